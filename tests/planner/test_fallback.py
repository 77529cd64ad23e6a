"""The fallback: braking along the best path known, and never braking into a vehicle coming from behind.

The policy ranks violations by kind and by whose they are (a hit by a follower, one by anything
else, a broken limit), never by their text.
"""

from __future__ import annotations

import numpy as np
import pytest
from traffic import LANE, ROAD, car, violations

from planner.ego import start_state
from planner.fallback import fallback, severity
from planner.pipeline import plan
from planner.problem import Ego, Options, PlanningProblem, PolygonObstacle, Vehicle
from planner.reference import build_reference
from planner.speed import ProfileKind
from planner.st_bounds import static_shapes
from planner.timing import STAGES, TOTAL
from planner.trajectory import polyline_path
from planner.validation import Violation, ViolationKind

KIND = ViolationKind


def _hit(kind: ViolationKind, obstacle_id: str) -> Violation:
    return Violation(kind, obstacle_id=obstacle_id, t=1.0)


def test_a_hit_from_behind_ranks_below_any_other_hit_and_above_a_broken_limit() -> None:
    rear = {"behind"}
    from_behind = [_hit(KIND.HITS_MOVING_OBSTACLE, "behind")]
    leader = [_hit(KIND.HITS_MOVING_OBSTACLE, "leader")]
    wall = [_hit(KIND.HITS_OBSTACLE, "wall")]
    lane = [Violation(KIND.LANE, t=1.0)]
    assert severity(from_behind, rear) == (0, 1, 0)
    assert severity(leader, rear) == severity(wall, rear) == (1, 0, 0)  # only a follower is "behind"
    assert severity(lane, rear) < severity(from_behind, rear) < severity(wall, rear)
    # a static obstacle with a follower's id is not hit from behind
    assert severity([_hit(KIND.HITS_OBSTACLE, "behind")], rear) == (1, 0, 0)
    assert severity([*from_behind, *lane, *wall], rear) == (1, 1, 1)


def _hit_from_behind_when_braking() -> PlanningProblem:
    # a leader 14 m ahead and a car 9 m behind, all at 15 m/s: the headway to the leader asks for braking,
    # which the car behind (recorded, it does not react) would drive into; keeping the speed hits nothing
    obstacles = (car("leader", 44.0, 15.0), car("behind", 21.0, 15.0))
    return PlanningProblem(
        ROAD, LANE, Ego(30.0, 0.0, 0.0, 15.0), obstacles, Vehicle(), Options(target_speed=15.0)
    )


def test_when_braking_is_hit_from_behind_the_fallback_keeps_the_speed() -> None:
    problem = _hit_from_behind_when_braking()
    result = plan(problem)
    assert result.status == "fallback"
    assert "hit from behind" in result.message and "keeping the speed" in result.message
    assert result.violations == ()
    assert violations(problem, result.trajectory) == []
    assert np.allclose(result.trajectory.v, 15.0, atol=1e-6)
    assert result.diagnostics.speed_profile is ProfileKind.KEEP_SPEED
    assert list(result.diagnostics.timing_ms) == [*STAGES, TOTAL]  # the fallback's work is timed


def test_the_choice_does_not_read_the_messages(monkeypatch: pytest.MonkeyPatch) -> None:
    """Rewording every violation changes the message of the answer, not the trajectory it returns."""
    problem = _hit_from_behind_when_braking()
    worded = plan(problem)
    monkeypatch.setattr(Violation, "message", property(lambda self: f"reworded {self.kind.value}"))
    reworded = plan(problem)
    assert reworded.message != worded.message and "reworded hits_moving_obstacle" in reworded.message
    assert reworded.diagnostics.speed_profile is worded.diagnostics.speed_profile is ProfileKind.KEEP_SPEED
    assert np.array_equal(reworded.trajectory.x, worded.trajectory.x)
    assert np.array_equal(reworded.trajectory.v, worded.trajectory.v)


def test_the_target_speed_stays_a_cap_with_a_faster_car_behind() -> None:
    # target 8 and a car behind at 14 m/s: keeping ahead would need 14 m/s; the plan does not speed
    # up past the target, so the answer is a fallback that says who hits it, and it does not brake hard
    problem = PlanningProblem(
        ROAD,
        LANE,
        Ego(30.0, 0.0, 0.0, 10.0),
        (car("behind", 15.0, 14.0),),
        Vehicle(),
        Options(target_speed=8.0),
    )
    result = plan(problem)
    assert result.status == "fallback"
    assert "hit from behind" in result.message
    assert np.max(result.trajectory.v) <= 10.0 + 1e-6
    assert np.min(result.trajectory.v) >= 8.0 - 0.1  # never braking below the target into it
    assert {(v.kind, v.obstacle_id) for v in result.violations} <= {(KIND.HITS_MOVING_OBSTACLE, "behind")}


def test_a_block_ahead_wins_over_a_car_behind() -> None:
    # a wall across the road 50 m ahead and a car close behind: stopping before the wall comes first, and
    # what the answer still breaks is the car behind driving into it
    wall = PolygonObstacle("wall", np.array([[80.0, -4.0], [82.0, -4.0], [82.0, 4.0], [80.0, 4.0]]))
    problem = PlanningProblem(
        ROAD,
        LANE,
        Ego(30.0, 0.0, 0.0, 8.0),
        (wall, car("behind", 20.0, 8.0)),
        Vehicle(),
        Options(target_speed=8.0),
    )
    result = plan(problem)
    assert result.status == "fallback"
    hits = [(v.kind, v.obstacle_id) for v in violations(problem, result.trajectory)]
    assert (KIND.HITS_OBSTACLE, "wall") not in hits
    assert [(v.kind, v.obstacle_id) for v in result.violations] == [(KIND.HITS_MOVING_OBSTACLE, "behind")]
    assert np.all(result.trajectory.x + 0.5 * Vehicle().length < 80.0)
    assert result.trajectory.v[-1] < 1e-3


@pytest.mark.parametrize("bad_paths", [1, 2])
def test_the_fallback_brakes_along_the_first_path_that_passes_every_check(bad_paths: int) -> None:
    """The best path known, then the candidate, then straight on at the ego's offset: the first whose
    braking trajectory passes every check (here a swerve breaks the curvature limit)."""
    problem = PlanningProblem(ROAD, LANE, Ego(30.0, 0.3, 0.0, 6.0), (), Vehicle())
    ref = build_reference(ROAD)
    start = start_state(ref, problem)
    s = np.linspace(start.s, 80.0, 101)
    swerve = polyline_path(ref, s, np.clip(0.3 + 2.0 * (s - start.s), 0.3, 3.0))
    gentle = polyline_path(ref, s, 0.3 - 0.5 * np.clip((s - start.s) / 50.0, 0.0, 1.0))
    path, candidate = (swerve, gentle) if bad_paths == 1 else (swerve, swerve)
    out = fallback("a reason", path, candidate, ref, problem, start, [])
    assert (out.message, out.violations, out.profile) == ("a reason", (), ProfileKind.BRAKING)
    traj = out.trajectory
    assert traj.v[-1] == pytest.approx(0.0, abs=1e-9) and np.all(np.diff(traj.v) <= 1e-9)
    if bad_paths == 1:  # along the candidate, which bends away from the ego's offset
        assert traj.d[-1] < 0.3 - 1e-3
    else:  # straight on at the ego's offset
        np.testing.assert_allclose(traj.d, 0.3, atol=1e-9)


def test_a_fallback_that_cannot_pass_says_what_its_braking_trajectory_still_breaks() -> None:
    wall = PolygonObstacle("wall", np.array([[36.0, -4.0], [38.0, -4.0], [38.0, 4.0], [36.0, 4.0]]))
    problem = PlanningProblem(ROAD, LANE, Ego(30.0, 0.0, 0.0, 15.0), (wall,), Vehicle())
    ref = build_reference(ROAD)
    start = start_state(ref, problem)
    s = np.linspace(start.s, 80.0, 101)
    straight_on = polyline_path(ref, s, 0.0 * s)
    out = fallback("a reason", straight_on, straight_on, ref, problem, start, static_shapes(problem))
    assert [(v.kind, v.obstacle_id) for v in out.violations] == [(KIND.HITS_OBSTACLE, "wall")]
    assert out.message == "a reason; the braking trajectory still breaks: footprint hits obstacle wall"
    assert out.profile is ProfileKind.BRAKING
