"""The start state: the ego in the Frenet frame, its assumed curvature clipped to what it can drive at its
speed, and refused when it is not on the road (by the plan and by the candidates alike)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest

from planner.candidates import generate_candidates
from planner.config import DEFAULT_CONFIG
from planner.ego import ego_frenet, start_state
from planner.errors import InvalidInputError
from planner.pipeline import plan
from planner.problem import Ego, Lane, Options, PlanningProblem, Vehicle
from planner.reference import build_reference
from planner.roads import arc, straight

ROAD = straight(100.0)


def _by_start_state(ego: Ego) -> None:
    problem = PlanningProblem(ROAD, Lane(3.0, 3.0), ego)
    start_state(build_reference(ROAD), problem)


def _by_candidates(ego: Ego) -> None:
    generate_candidates(build_reference(ROAD), Lane(3.0, 3.0), ego, Vehicle(), Options())


REFUSERS: list[Callable[[Ego], None]] = [_by_start_state, _by_candidates]


@pytest.mark.parametrize("refuse", REFUSERS)
def test_ego_facing_backwards_is_rejected_with_its_field(refuse: Callable[[Ego], None]) -> None:
    with pytest.raises(InvalidInputError) as err:
        refuse(Ego(x=10, y=0, heading=np.pi))
    assert err.value.field == "ego.heading"


@pytest.mark.parametrize("refuse", REFUSERS)
@pytest.mark.parametrize("x, y", [(50.0, 20.0), (50.0, -25.0), (-30.0, 0.0)])
def test_ego_far_from_the_road_is_rejected(refuse: Callable[[Ego], None], x: float, y: float) -> None:
    with pytest.raises(InvalidInputError) as err:
        refuse(Ego(x=x, y=y, heading=0.0))
    assert err.value.field == "ego"


@pytest.mark.parametrize("refuse", REFUSERS)
@pytest.mark.parametrize("heading", [0.0, np.pi])
def test_an_ego_far_away_is_refused_for_its_position_whatever_its_heading(
    refuse: Callable[[Ego], None], heading: float
) -> None:
    """Far from the road the nearest point's direction means nothing: the position is the problem."""
    with pytest.raises(InvalidInputError, match="outside the lane") as err:
        refuse(Ego(x=50.0, y=1e5, heading=heading))
    assert err.value.field == "ego"


def _on_a_bend(speed: float, curvature: float | None = None) -> PlanningProblem:
    """The ego on a 10 m radius bend (κ = 0.1 1/m), along it."""
    road = arc(10.0, 2.0, step=0.25)
    ego = Ego(x=float(road[20, 0]), y=float(road[20, 1]), heading=0.5, speed=speed, curvature=curvature)
    return PlanningProblem(road, Lane(3.0, 3.0), ego, vehicle=Vehicle(max_curvature=0.5))


@pytest.mark.parametrize("speed", [0.0, 3.0, 12.0])
def test_the_assumed_curvature_is_the_roads_within_what_the_ego_can_drive_at_its_speed(speed: float) -> None:
    problem = _on_a_bend(speed)
    ref = build_reference(problem.reference_line)
    v = problem.vehicle
    reachable = min(v.max_curvature, v.max_lateral_acceleration / max(speed, 0.1) ** 2)
    clip = DEFAULT_CONFIG.limit_margin * reachable
    start = start_state(ref, problem)
    assert start == ego_frenet(ref, problem.ego, max_curvature=clip)
    # 3 m/s² at 12 m/s allows 0.021 1/m, less than the road's 0.1: clipped; slower, the road's
    unclipped = ego_frenet(ref, problem.ego)
    assert (start == unclipped) is (clip >= 0.1)


def test_a_given_curvature_is_the_egos_own() -> None:
    problem = _on_a_bend(12.0, curvature=0.1)
    ref = build_reference(problem.reference_line)
    assert start_state(ref, problem) == ego_frenet(ref, problem.ego)


def test_the_plans_candidates_start_from_the_start_state() -> None:
    base = _on_a_bend(12.0)
    problem = replace(base, options=replace(base.options, return_candidates=True))
    result = plan(problem)
    ref = build_reference(problem.reference_line)
    start = start_state(ref, problem)
    expected = generate_candidates(
        ref, problem.lane, problem.ego, problem.vehicle, problem.options, start=start
    )
    assert result.candidates is not None
    np.testing.assert_array_equal(result.candidates.d, expected.d)
    unclipped = generate_candidates(ref, problem.lane, problem.ego, problem.vehicle, problem.options)
    assert not np.array_equal(result.candidates.d, unclipped.d)  # the clip matters here
