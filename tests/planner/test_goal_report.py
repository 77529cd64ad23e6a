"""What a plan says of its goal: every reason a goal is unreachable, through whole plans; and for any goal,
``reached`` at ``t`` exactly when an independent judge finds the trajectory meets it first at ``t``."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, note, settings
from hypothesis import strategies as st

from planner.goal import Goal, GoalCircle, GoalReason, GoalStatus
from planner.pipeline import plan
from planner.problem import PlanningProblem, PolygonObstacle, Vehicle
from tests.planner.goal_cases import EGO_X, box, meets, straight_problem
from tests.planner.test_scenarios import trajectory_problems

LANE = (-1.75, 1.75)


def _judged(problem: PlanningProblem) -> tuple[GoalStatus, GoalReason | None, str]:
    result = plan(problem)
    report = result.diagnostics.goal
    assert report is not None
    assert problem.goal is not None
    held = meets(problem.goal, result.trajectory)
    assert (report.status is GoalStatus.REACHED) == bool(held.any()), report
    return report.status, report.reason, report.message


@pytest.mark.parametrize(
    ("problem", "reason"),
    [
        pytest.param(straight_problem(Goal(time=(-3.0, -1.0))), GoalReason.WINDOW_ENDED, id="window ended"),
        pytest.param(straight_problem(Goal(box(-20.0, -10.0, *LANE))), GoalReason.BEHIND, id="behind"),
        pytest.param(
            straight_problem(Goal(box(60.0, 70.0, 10.0, 15.0))), GoalReason.OFF_ROAD, id="off the road"
        ),
        pytest.param(
            straight_problem(Goal(box(500.0, 510.0, *LANE))), GoalReason.OFF_ROAD, id="past the end"
        ),
        pytest.param(
            straight_problem(Goal(box(EGO_X + 95.0, EGO_X + 115.0, *LANE), time=(6.0, 8.0))),
            GoalReason.TOO_FAR,
            id="too far at the target",
        ),
        pytest.param(
            straight_problem(
                Goal(box(EGO_X + 150.0, EGO_X + 160.0, *LANE), time=(0.0, 8.0)), speed_limit=16.0
            ),
            GoalReason.TOO_FAR,
            id="too far at the limit",
        ),
        pytest.param(
            straight_problem(Goal(speed=(25.0, 30.0)), speed_limit=20.0),
            GoalReason.SPEED_RANGE,
            id="too fast",
        ),
        pytest.param(
            replace(
                straight_problem(Goal(box(EGO_X + 50.0, EGO_X + 60.0, *LANE))),
                obstacles=(
                    PolygonObstacle("wall", np.array([[35.0, -4.0], [36.0, -4.0], [36.0, 4.0], [35.0, 4.0]])),
                ),
            ),
            GoalReason.BLOCKED,
            id="blocked",
        ),
        pytest.param(
            straight_problem(Goal(box(EGO_X + 2.0, EGO_X + 6.0, *LANE), time=(6.0, 8.0))),
            GoalReason.TOO_EARLY,
            id="too early",
        ),
        pytest.param(
            straight_problem(Goal(box(EGO_X + 4.0, EGO_X + 7.0, *LANE), speed=(0.5, 1.0))),
            GoalReason.SPEED_RANGE,
            id="cannot slow into the range",
        ),
        pytest.param(
            straight_problem(Goal(box(EGO_X + 30.0, EGO_X + 40.0, *LANE)), time_budget_ms=1e-3),
            GoalReason.FALLBACK,
            id="fallback",
        ),
    ],
)
def test_an_unreachable_goal_says_why(problem: PlanningProblem, reason: GoalReason) -> None:
    status, got, message = _judged(problem)
    assert (status, got) == (GoalStatus.UNREACHABLE, reason), message
    assert message


def _walled(wall_x: float, goal: Goal, model: str = "point") -> PlanningProblem:
    """:func:`straight_problem` with ``goal`` and a wall across the road from ``wall_x`` [m]."""
    wall = np.array([[wall_x, -4.0], [wall_x + 1.0, -4.0], [wall_x + 1.0, 4.0], [wall_x, 4.0]])
    return replace(straight_problem(goal, model=model), obstacles=(PolygonObstacle("wall", wall),))


@pytest.mark.parametrize("model", ["point", "car"])
def test_a_block_beyond_the_regions_entry_leaves_the_goal_on_the_way(model: str) -> None:
    # The plan stops before a wall 100 m ahead; the region begins 5 m before the wall, so the centre gets
    # inside before the stop: out of the horizon's reach it is on the way, not blocked.
    problem = _walled(EGO_X + 100.0, Goal(box(EGO_X + 95.0, EGO_X + 105.0, *LANE)), model)
    result = plan(problem)
    assert result.status == "stopped", result.message
    status, reason, message = _judged(problem)
    assert (status, reason) == (GoalStatus.ON_THE_WAY, None), message
    # the same wall before the region's entry blocks it, and the message measures from the stop
    blocked = _walled(EGO_X + 80.0, Goal(box(EGO_X + 95.0, EGO_X + 105.0, *LANE)), model)
    status, reason, message = _judged(blocked)
    assert (status, reason) == (GoalStatus.UNREACHABLE, GoalReason.BLOCKED), message
    gap = float(message.rsplit(", ", 1)[1].split(" m ")[0])  # the region's entry less the stop
    assert 15.0 + 0.5 * Vehicle().length < gap < 15.0 + 0.5 * Vehicle().length + 4.0, message


def test_a_goal_out_of_the_horizon_is_on_the_way() -> None:
    assert _judged(straight_problem(Goal(box(300.0, 320.0, *LANE))))[0] is GoalStatus.ON_THE_WAY
    later = straight_problem(Goal(time=(20.0, 30.0), speed=(5.0, 6.0)))
    assert _judged(later)[0] is GoalStatus.ON_THE_WAY
    waiting = straight_problem(
        Goal(box(EGO_X + 20.0, EGO_X + 40.0, *LANE), time=(12.0, 15.0), speed=(0.0, 0.0))
    )
    status, _, message = _judged(waiting)
    assert status is GoalStatus.ON_THE_WAY, message  # stopped inside before the window opens: waits


def test_a_goal_met_now_is_reached_at_zero() -> None:
    problem = straight_problem(Goal(GoalCircle(np.array([EGO_X, 0.0]), 1.0), speed=(9.0, 11.0)))
    result = plan(problem)
    assert result.diagnostics.goal is not None and result.diagnostics.goal.t == 0.0


# -- any goal ----------------------------------------------------------------------------------

goals = st.builds(
    lambda x0, length, y0, height, window, speed, kind: Goal(
        position=box(x0, x0 + length, y0, y0 + height) if kind != "none" else None,
        time=window,
        speed=speed,
    ),
    x0=st.floats(EGO_X - 20.0, EGO_X + 140.0),
    length=st.floats(1.0, 40.0),
    y0=st.floats(-4.0, 3.0),
    height=st.floats(0.5, 6.0),
    window=st.none()
    | st.tuples(st.floats(-2.0, 12.0), st.floats(0.0, 6.0)).map(lambda p: (p[0], p[0] + p[1])),
    speed=st.none()
    | st.tuples(st.sampled_from([0.0, 0.0, 2.0, 8.0]), st.floats(0.0, 12.0)).map(
        lambda p: (p[0], p[0] + p[1])
    ),
    kind=st.sampled_from(["box", "box", "box", "none"]),
)


@settings(max_examples=50, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(goal=goals, speed_limit=st.none() | st.floats(10.0, 18.0), model=st.sampled_from(["point", "car"]))
def test_reached_is_said_exactly_when_the_trajectory_meets_the_goal_first_then(
    goal: Goal, speed_limit: float | None, model: str
) -> None:
    problem = straight_problem(goal, model=model, speed_limit=speed_limit)
    result = plan(problem)
    note(f"{result.status}: {result.message}; {result.diagnostics.goal}")
    report = result.diagnostics.goal
    assert report is not None
    # a sample within a micrometre of the region's edge may be judged either way
    t = result.trajectory.t
    loose, strict = meets(goal, result.trajectory, 1e-6), meets(goal, result.trajectory, -1e-6)
    if report.status is GoalStatus.REACHED:
        assert report.t is not None and report.reason is None
        at = int(np.flatnonzero(np.isclose(t, report.t))[0])
        assert loose[at], f"the goal is not met at t = {report.t}"
        assert not strict[:at].any(), f"the goal is met before, at t = {t[np.argmax(strict)]}"
    else:
        assert not strict.any(), f"the trajectory meets the goal at t = {t[np.argmax(strict)]}"
        assert report.t is None and (report.reason is None) == (report.status is GoalStatus.ON_THE_WAY)
    # whatever the goal asks, the answer keeps every check (the independent checker)
    assert trajectory_problems(problem, result.trajectory) == []
    assert result.trajectory.v.max() <= max(problem.vehicle.max_speed, 10.0) + 1e-3
    cap = 10.0 if speed_limit is None else speed_limit
    assert result.trajectory.v.max() <= cap + 1e-3  # never above the speed limit


def test_a_car_is_judged_at_its_centre_not_its_rear_axle() -> None:
    car = Vehicle(wheelbase=2.7, rear_axle_offset=1.35)
    # a 1 m deep region at the stop's centre: the rear axle stands 1.35 m behind it, outside
    goal = Goal(box(EGO_X + 40.0, EGO_X + 41.0, *LANE), speed=(0.0, 0.0))
    result = plan(replace(straight_problem(goal), vehicle=car))
    report = result.diagnostics.goal
    assert report is not None and report.status is GoalStatus.REACHED, report
    rear_x = result.trajectory.x - 1.35 * np.cos(result.trajectory.heading)
    assert not (rear_x[-1] >= EGO_X + 40.0 and rear_x[-1] <= EGO_X + 41.0)
    assert EGO_X + 40.0 <= result.trajectory.x[-1] <= EGO_X + 41.0


def test_beside_the_region_when_the_window_closes_is_missed_not_too_far() -> None:
    # the region's left half of the lane, 40–70 m ahead, filled by a parked car: the vehicle drives past it
    # in the window (at 10 m/s it is 40–50 m on at 4–5 s) but cannot get in: missed, not too far
    region = box(EGO_X + 40.0, EGO_X + 70.0, 1.2, 3.5)
    car = PolygonObstacle("parked", np.array([[45.0, 1.0], [85.0, 1.0], [85.0, 3.4], [45.0, 3.4]]))
    problem = replace(straight_problem(Goal(region, time=(4.0, 5.0))), obstacles=(car,))
    result = plan(problem)
    assert result.status == "ok", result.message
    assert not meets(problem.goal, result.trajectory).any()  # type: ignore[arg-type]
    report = result.diagnostics.goal
    assert report is not None and report.status is GoalStatus.UNREACHABLE
    assert report.reason == "missed", report.message
