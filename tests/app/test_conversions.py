"""app.conversions: a problem survives the round trip through a request; the answer writers refuse what
would be a wrong answer."""

from __future__ import annotations

import dataclasses

import numpy as np
import pydantic_core
import pytest

from app.conversions import demo_request, from_problem, plan_data, to_problem
from app.models.plan import STAGES, PlanResponse
from planner.pipeline import plan
from planner.result import PlanResult
from planner.roads import demo_problem


@pytest.fixture(scope="module")
def demo_plan() -> PlanResult:
    return plan(to_problem(demo_request()))


def test_problem_round_trip() -> None:
    problem = demo_problem()
    again = to_problem(from_problem(problem))
    assert np.array_equal(again.reference_line, problem.reference_line)
    assert again.lane == problem.lane
    assert again.ego == problem.ego
    assert again.vehicle == problem.vehicle
    assert again.options == problem.options
    assert len(again.obstacles) == len(problem.obstacles)
    for a, b in zip(again.obstacles, problem.obstacles, strict=True):
        assert type(a) is type(b) and a.id == b.id


#: a request's budget and what it spent [ms]
SPENT = {"budget_ms": 1000.0, "waited_ms": 2.5, "ran_ms": 30.0}


def test_plan_data_is_the_response_model_json(demo_plan: PlanResult) -> None:
    data = plan_data(demo_plan, SPENT)
    model = PlanResponse.model_validate_json(pydantic_core.to_json(data), strict=True)
    assert model.model_dump(mode="json", exclude_none=True) == data
    assert list(data["diagnostics"]["timing_ms"]) == list(STAGES)
    assert data["diagnostics"]["request"] == SPENT
    assert len(data["trajectory"]) == demo_plan.trajectory.t.size
    assert data["trajectory"][-1]["v"] == pytest.approx(float(demo_plan.trajectory.v[-1]))


def test_plan_data_refuses_what_would_be_a_wrong_answer(demo_plan: PlanResult) -> None:
    v = demo_plan.trajectory.v.copy()
    v[2] = np.inf
    broken = dataclasses.replace(demo_plan, trajectory=dataclasses.replace(demo_plan.trajectory, v=v))
    with pytest.raises(ValueError, match="the trajectory holds a non-finite number"):
        plan_data(broken, SPENT)
    with pytest.raises(ValueError, match="unknown plan status 'maybe'"):
        plan_data(dataclasses.replace(demo_plan, status="maybe"), SPENT)  # type: ignore[arg-type]
    timing = {**demo_plan.diagnostics.timing_ms, "speed": float("nan")}
    diagnostics = dataclasses.replace(demo_plan.diagnostics, timing_ms=timing)
    with pytest.raises(ValueError, match="the diagnostics hold"):
        plan_data(dataclasses.replace(demo_plan, diagnostics=diagnostics), SPENT)
