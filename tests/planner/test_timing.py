"""Stage names and the plan's timing: every stage that ran, and ``total`` as the plan's wall time."""

from __future__ import annotations

import gc
import time
from dataclasses import replace

import numpy as np
import pytest

from planner.pipeline import plan
from planner.problem import DynamicObstacle, Ego, Lane, Options, PlanningProblem, Vehicle
from planner.roads import demo_problem, straight
from planner.timing import STAGES, TOTAL, StageTimer

#: a plan's call overhead outside its own first and last line may take this long [ms]
CALL_OVERHEAD_MS = 5.0


def test_the_stages_are_named_once_in_the_order_they_run() -> None:
    assert STAGES == ("reference", "candidates", "lateral", "decision", "speed", "trajectory", "fallback")
    assert TOTAL not in STAGES


def test_the_timer_adds_up_a_repeated_stage_and_counts_the_time_between_stages_in_total() -> None:
    timer = StageTimer()
    with timer.stage("lateral"):
        time.sleep(0.01)
    with timer.stage("reference"):
        time.sleep(0.01)
    with timer.stage("lateral"):
        time.sleep(0.01)
    time.sleep(0.02)  # outside any stage
    timing = timer.timing_ms()
    assert list(timing) == ["reference", "lateral", TOTAL]  # in the order of STAGES, total last
    assert timing["lateral"] >= 20.0
    assert timing[TOTAL] >= timing["reference"] + timing["lateral"] + 20.0


def test_the_budget_says_which_stage_overran() -> None:
    assert StageTimer().overrun("speed") is None
    assert StageTimer().remaining_s() is None
    spent = StageTimer(budget_ms=0.0)
    time.sleep(0.002)
    assert spent.overrun("candidates") is not None
    assert "spent after the candidates stage" in str(spent.overrun("candidates"))
    assert spent.remaining_s() == pytest.approx(1e-3)  # never less than a millisecond
    assert StageTimer(budget_ms=1e6).overrun("lateral") is None


def _timed(problem: PlanningProblem) -> tuple[dict[str, float], float, str]:
    gc.collect()  # no collection of the whole suite's garbage between the clock and plan()'s first line
    t0 = time.perf_counter()
    result = plan(problem)
    wall = 1e3 * (time.perf_counter() - t0)
    return result.diagnostics.timing_ms, wall, result.status


def test_an_ok_plan_times_every_stage_it_ran_and_its_total_is_its_wall_time() -> None:
    timing, wall, status = _timed(demo_problem())
    assert status == "ok"
    assert list(timing) == ["reference", "candidates", "lateral", "decision", "speed", "trajectory", TOTAL]
    assert timing[TOTAL] >= sum(v for k, v in timing.items() if k != TOTAL)
    assert wall - CALL_OVERHEAD_MS <= timing[TOTAL] <= wall


def test_a_fallback_after_the_candidates_times_the_fallback_and_no_later_stage() -> None:
    base = demo_problem()
    timing, wall, status = _timed(replace(base, options=replace(base.options, time_budget_ms=1.0)))
    assert status == "fallback"
    assert list(timing) == ["reference", "candidates", "fallback", TOTAL]
    assert timing["fallback"] > 0.0
    assert timing[TOTAL] >= sum(v for k, v in timing.items() if k != TOTAL)
    assert wall - CALL_OVERHEAD_MS <= timing[TOTAL] <= wall


def test_a_fallback_after_the_checks_times_every_stage() -> None:
    # braking for the leader's headway is hit by the car behind: the fallback keeps the speed
    t = np.arange(0.0, 8.01, 0.5)
    cars = tuple(
        DynamicObstacle(name, 4.5, 1.8, np.column_stack((t, x0 + 15.0 * t, 0 * t, 0 * t)))
        for name, x0 in (("leader", 44.0), ("behind", 21.0))
    )
    problem = PlanningProblem(
        straight(300.0, step=5.0),
        Lane(3.5, 3.5),
        Ego(30.0, 0.0, 0.0, 15.0),
        cars,
        Vehicle(),
        Options(target_speed=15.0),
    )
    timing, wall, status = _timed(problem)
    assert status == "fallback"
    assert list(timing) == [*STAGES, TOTAL]
    assert wall - CALL_OVERHEAD_MS <= timing[TOTAL] <= wall


def test_the_stages_stop_short_of_the_budget_by_the_fallbacks_reserve() -> None:
    timer = StageTimer(budget_ms=40.0, reserve_share=0.5)  # the stages have 20 ms
    time.sleep(0.025)
    reason = timer.overrun("speed")
    assert reason is not None and "the rest kept for the fallback" in reason
    assert timer.remaining_s() == pytest.approx(1e-3)
    assert StageTimer(budget_ms=40.0, reserve_share=0.5).overrun("speed") is None


def test_a_plan_that_overruns_in_its_last_stage_is_a_braking_fallback(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The trajectory stage runs after the speed stage's check: an overrun there is caught too (the
    answer is a braking fallback, not an ``ok`` past the budget)."""
    import planner.drive as drive

    budget_ms = 400.0
    slow = drive._trajectory

    def slow_trajectory(*args: object, **kwargs: object) -> object:
        time.sleep(0.4)
        return slow(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(drive, "_trajectory", slow_trajectory)
    base = demo_problem()
    problem = replace(base, options=replace(base.options, time_budget_ms=budget_ms))
    result = plan(problem)
    assert result.status == "fallback"
    assert "spent after the trajectory stage" in result.message
    assert "fallback" in result.diagnostics.timing_ms
    assert np.all(np.diff(result.trajectory.v) <= 1e-9)  # it brakes
