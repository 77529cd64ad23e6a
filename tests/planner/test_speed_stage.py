"""The speed stage: its grid and limit, the analytic profiles, and diagnostics that say which profile
the trajectory samples while keeping the SQP's own account of its solve."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest
from scenario_roads import Road, arc_piece, follow_prediction, straight_piece
from spies import counted_calls, started_work
from traffic import car, violations

from planner import drive
from planner.candidates import path_length
from planner.config import DEFAULT_CONFIG
from planner.pipeline import plan
from planner.problem import (
    DynamicObstacle,
    Ego,
    Lane,
    Options,
    PlanningProblem,
    PolygonObstacle,
    Vehicle,
    speed_cap,
    target_speed,
)
from planner.reference import build_reference
from planner.roads import hairpin, straight, two_lane_problem
from planner.speed import (
    ProfileKind,
    SpeedPlan,
    braking,
    escape,
    initial_acceleration,
    keep_speed,
    profile_grid,
    reach_speed,
    speed_limit,
    speed_stage,
)
from planner.thread_solvers import Spare
from planner.timing import StageTimer
from planner.trajectory import frenet_path
from planner.validation import Violation, ViolationKind
from solvers.speed_sqp import SpeedSolver

ROAD = straight(300.0, step=5.0)


def _wall(x: float) -> PolygonObstacle:
    return PolygonObstacle("wall", np.array([[x, -4.0], [x + 2.0, -4.0], [x + 2.0, 4.0], [x, 4.0]]))


def _towards_a_wall(speed: float, gap: float) -> PlanningProblem:
    """The ego at ``speed`` [m/s], its front ``gap`` [m] before a wall across the road (at
    ``_wall_x(gap)``)."""
    ego = Ego(10.0, 0.0, 0.0, speed)
    wall = _wall(_wall_x(gap))
    return PlanningProblem(ROAD, Lane(3.5, 3.5), ego, (wall,), Vehicle(), Options(target_speed=speed))


def _wall_x(gap: float) -> float:
    return 10.0 + 0.5 * Vehicle().length + gap


@pytest.mark.parametrize(
    ("horizon", "dt", "steps"), [(8.0, 0.1, 80), (8.0, 0.05, 80), (2.0, 0.5, 4), (0.1, 1.0, 1)]
)
def test_the_profile_grid_covers_the_horizon_in_at_most_the_configured_steps(
    horizon: float, dt: float, steps: int
) -> None:
    n, step = profile_grid(Options(horizon_time=horizon, dt=dt))
    assert n == steps
    assert n * step == pytest.approx(horizon)


def test_the_speed_limit_is_the_target_within_the_curvature_limit_and_reaches_either_side() -> None:
    problem = PlanningProblem(
        ROAD, Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, 5.0), options=Options(target_speed=12.0)
    )
    ref = build_reference(ROAD)
    s = np.linspace(0.0, 100.0, 201)
    bend = np.where((s > 50.0) & (s < 51.0), 0.1, 0.0)  # on a straight reference d″ is the curvature
    path = frenet_path(ref, s, 0.0 * s, 0.0 * s, bend)
    limit = speed_limit(path, problem)
    assert target_speed(problem) == 12.0
    assert limit[0] == pytest.approx(12.0) and limit[-1] == pytest.approx(12.0)
    curved = np.abs(path.curvature) > 1e-6
    lateral = np.sqrt(0.9 * problem.vehicle.max_lateral_acceleration / np.abs(path.curvature[curved]))
    assert np.all(limit[curved] <= lateral + 1e-9)
    assert limit.min() == pytest.approx(lateral.min()) and lateral.min() < 12.0
    # each knot's limit also holds limit_reach (2 m) either side of it
    for sigma, v in zip(path.sigma[curved], lateral, strict=True):
        assert np.all(limit[np.abs(path.sigma - sigma) <= 2.0 - 1e-9] <= v + 1e-9)


ANALYTIC = {ProfileKind.BRAKING: braking, ProfileKind.KEEP_SPEED: keep_speed, ProfileKind.ESCAPE: escape}


@pytest.mark.parametrize("kind", list(ANALYTIC))
def test_the_analytic_profiles_say_what_they_are(kind: ProfileKind) -> None:
    problem = PlanningProblem(ROAD, Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, 12.0, acceleration=1.0))
    ref = build_reference(ROAD)
    s = np.linspace(10.0, 290.0, 100)
    path = frenet_path(ref, s, 0.0 * s, 0.0 * s, 0.0 * s)
    profile = ANALYTIC[kind](path, problem, 80, 0.1)
    assert profile.kind is kind
    assert profile.t[-1] == pytest.approx(8.0) and profile.s[0] == 0.0 and profile.v[0] == 12.0
    assert np.all(np.abs(np.diff(profile.a)) <= 30.0 * 0.1 + 1e-9)  # the emergency jerk
    if kind is ProfileKind.KEEP_SPEED:  # the acceleration released, then the speed kept
        assert profile.a[-1] == pytest.approx(0.0) and profile.v[-1] > 12.0
    elif kind is ProfileKind.BRAKING:
        assert profile.v[-1] == pytest.approx(0.0, abs=1e-9)
    else:  # up to the vehicle's max speed (no target, no speed limit), at its acceleration
        assert profile.v[-1] == pytest.approx(problem.vehicle.max_speed, abs=0.05)
        assert np.all(profile.a <= problem.vehicle.max_acceleration + 1e-9)


def test_a_plan_that_passes_its_checks_uses_the_optimised_profile() -> None:
    result = plan(
        PlanningProblem(ROAD, Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, 8.0), options=Options(target_speed=10.0))
    )
    assert result.status == "ok"
    assert result.diagnostics.speed_profile is ProfileKind.OPTIMISED
    assert result.diagnostics.speed.converged and result.diagnostics.speed.iterations > 0


def test_a_stop_the_optimised_profile_overshoots_is_braked_for_and_says_so() -> None:
    """Too close to a wall for the comfortable profile: the SQP's (soft) stop is overshot, full braking is
    the answer, and the diagnostics keep the SQP's own solve (it ran: iterations, time) beside the
    profile actually used."""
    for speed, gap in ((10.0, 10.0), (15.0, 22.0)):
        result = plan(_towards_a_wall(speed, gap))
        diag = result.diagnostics
        assert result.status == "stopped", result.message
        assert diag.speed_profile is ProfileKind.BRAKING
        assert diag.speed.usable
        assert diag.speed.iterations > 0 and diag.speed.solve_time_ms > 0.0
        assert "braking profile" not in diag.speed.message
        assert np.all(np.diff(result.trajectory.v) <= 1e-9)  # braking all the way
        assert (
            result.trajectory.x.max() + 0.5 * Vehicle().length < _wall(0.0).polygon[0][0] + 10.0 + 2.25 + 30
        )


def test_a_fallback_that_brakes_keeps_the_sqps_own_solve_info() -> None:
    result = plan(_towards_a_wall(15.0, 10.0))  # braking distance ≈ 19 m: the wall cannot be avoided
    assert result.status == "fallback", result.message
    assert result.diagnostics.speed_profile is ProfileKind.BRAKING
    assert result.diagnostics.speed.iterations > 0  # the SQP ran; its info is not a braking profile's
    assert "braking profile" not in result.diagnostics.speed.message


@pytest.mark.parametrize(
    ("target", "limit", "cruise", "cap"),
    [
        (None, None, 20.0, 20.0),
        (8.0, None, 8.0, 8.0),
        (8.0, 14.0, 8.0, 14.0),
        (None, 14.0, 14.0, 14.0),
        (8.0, 30.0, 8.0, 20.0),
        (25.0, 30.0, 20.0, 20.0),
    ],
)
def test_the_profile_cruises_at_the_target_and_may_drive_up_to_the_speed_limit(
    target: float | None, limit: float | None, cruise: float, cap: float
) -> None:
    """Without a speed limit the target is the cap (today's behaviour); with one, the cap is the speed
    limit; both within the vehicle's max speed (20 m/s)."""
    options = Options(target_speed=target, speed_limit=limit)
    problem = PlanningProblem(ROAD, Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, 5.0), options=options)
    assert (target_speed(problem), speed_cap(problem)) == (cruise, cap)
    ref = build_reference(ROAD)
    s = np.linspace(10.0, 100.0, 181)
    path = frenet_path(ref, s, 0.0 * s, 0.0 * s, 0.0 * s)
    np.testing.assert_allclose(speed_limit(path, problem), cap)


def test_keeping_the_speed_slows_for_a_curve_ahead_and_speeds_up_after_it() -> None:
    """At 14 m/s towards a 2 m stretch bent to 0.1 1/m (about 5 m/s at 3 m/s²): keeping the speed
    slows before it, within the path's limit, and comes back to the speed after it."""
    problem = PlanningProblem(
        ROAD, Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, 14.0), options=Options(target_speed=14.0)
    )
    ref = build_reference(ROAD)
    s = np.linspace(10.0, 250.0, 481)
    bend = np.where((s > 60.0) & (s < 62.0), 0.1, 0.0)
    path = frenet_path(ref, s, 0.0 * s, 0.0 * s, bend)
    profile = keep_speed(path, problem, 160, 0.1)
    limit = np.interp(profile.s, path.sigma, speed_limit(path, problem, cap=np.inf))
    assert np.all(profile.v <= limit + 1e-6)
    assert profile.v.min() < 6.0 and profile.v[-1] == pytest.approx(14.0, abs=1e-3)
    straight_on = keep_speed(frenet_path(ref, s, 0.0 * s, 0.0 * s, 0.0 * s), problem, 160, 0.1)
    np.testing.assert_allclose(straight_on.v, 14.0)  # nothing to slow for: the speed kept


def test_keeping_the_speed_above_the_max_speed_settles_at_it() -> None:
    """An ego 0.03 m/s above the vehicle's max speed (20 m/s), measured speeding up: keeping the speed
    drives at the max speed, the acceleration settled, instead of steering towards its own speed past the
    limit and braking back every few steps (±3 m/s² for the whole horizon)."""
    problem = PlanningProblem(ROAD, Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, 20.03, acceleration=0.5))
    ref = build_reference(ROAD)
    s = np.linspace(10.0, 250.0, 481)
    profile = keep_speed(frenet_path(ref, s, 0.0 * s, 0.0 * s, 0.0 * s), problem, 80, 0.1)
    assert np.all(profile.v <= 20.03 + 0.5**2 / (2 * DEFAULT_CONFIG.speed.emergency_jerk) + 1e-9)
    np.testing.assert_allclose(profile.v[20:], 20.0, atol=1e-6)
    np.testing.assert_allclose(profile.a[20:], 0.0, atol=1e-6)


def test_the_paths_reach_the_speed_limit_only_with_a_vehicle_behind() -> None:
    """Above the target the profile speeds up only to keep ahead of a vehicle from behind: only then must
    the candidates' paths be long enough for the speed limit (longer paths spread their points thinner)."""
    ref = build_reference(ROAD)
    ego = Ego(30.0, 0.0, 0.0, 8.0)
    limited = Options(target_speed=8.0, speed_limit=16.0)
    alone = PlanningProblem(ROAD, Lane(3.5, 3.5), ego, options=limited)
    behind = PlanningProblem(ROAD, Lane(3.5, 3.5), ego, (car("behind", 10.0, 14.0),), options=limited)
    ahead = PlanningProblem(ROAD, Lane(3.5, 3.5), ego, (car("ahead", 60.0, 14.0),), options=limited)
    capped = PlanningProblem(ROAD, Lane(3.5, 3.5), ego, behind.obstacles, options=Options(target_speed=8.0))
    start = 30.0
    assert reach_speed(ref, alone, start) is None and reach_speed(ref, ahead, start) is None
    assert reach_speed(ref, capped, start) is None  # no speed limit: the target is the cap
    assert reach_speed(ref, behind, start) == 16.0
    vehicle, options = Vehicle(), limited
    assert path_length(ego, vehicle, options, 16.0) > path_length(ego, vehicle, options) + 8.0 * (16.0 - 8.0)


def test_behind_a_follower_bound_the_profile_brakes_later_with_the_emergency_jerk(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """At 10 m/s, 15 m before a 25 m curve (about 8 m/s at 3 m/s²), a car 8 m behind at 10 m/s: the
    comfortable jerk starts braking at once and the car behind closes in; braking later and harder (the
    emergency jerk) keeps further ahead of it, within the same limits."""
    road = Road([straight_piece(100.0), arc_piece(25.0, np.pi / 2), straight_piece(80.0)])
    x, y, heading = road.pose(85.0)
    behind = DynamicObstacle("behind", 4.5, 1.8, follow_prediction(road, 85.0 - 4.5 - 8.0, 10.0, 8.0))
    ego = Ego(x, y, heading, 10.0)
    problem = PlanningProblem(
        road.polyline(1.0), Lane(3.5, 3.5), ego, (behind,), Vehicle(), Options(target_speed=10.0)
    )
    comfortable = replace(DEFAULT_CONFIG, speed=replace(DEFAULT_CONFIG.speed, emergency_jerk=8.0 + 1e-9))
    stages: list[SpeedPlan] = []

    def kept(*args: Any, **kwargs: Any) -> SpeedPlan:
        stages.append(speed_stage(*args, **kwargs))
        return stages[-1]

    monkeypatch.setattr(drive, "speed_stage", kept)
    harder, soft = plan(problem), plan(problem, comfortable)
    assert len(stages) == 2
    later, early = stages[0].solved, stages[1].solved
    assert later.follower_violation < early.follower_violation - 0.05
    assert later.speed_violation <= max(early.speed_violation, 0.05)
    assert harder.trajectory.v[10] > soft.trajectory.v[10]  # it keeps its speed longer


def _crossing(y0: float) -> DynamicObstacle:
    """A 4.5 m × 1.8 m car crossing the straight road at x = 80 m from ``y0`` [m] at 10 m/s along y."""
    t = np.arange(0.0, 8.01, 0.5)
    return DynamicObstacle(
        "crossing", 4.5, 1.8, np.column_stack((t, 80.0 + 0 * t, y0 + 10.0 * t, 0.5 * np.pi + 0 * t))
    )


@pytest.mark.parametrize(("y0", "first"), [(-70.0, True), (-30.0, False)])
def test_crossing_traffic_is_passed_in_front_of_where_the_limits_allow_it_else_yielded_to(
    monkeypatch: pytest.MonkeyPatch, y0: float, first: bool
) -> None:
    """At 10 m/s (target 14) 50 m before a car that crosses the road 7 s from now: the profile passes in
    front of it with a headway to spare (it would have had to stop for it 1 s after it left); one that
    crosses 3 s from now cannot be passed so within the vehicle's limits: it is yielded to, as before."""
    crossing = _crossing(y0)
    problem = PlanningProblem(
        ROAD, Lane(3.5, 3.5), Ego(30.0, 0.0, 0.0, 10.0), (crossing,), Vehicle(), Options(target_speed=14.0)
    )
    stages: list[SpeedPlan] = []

    def kept(*args: Any, **kwargs: Any) -> SpeedPlan:
        stages.append(speed_stage(*args, **kwargs))
        return stages[-1]

    monkeypatch.setattr(drive, "speed_stage", kept)
    result = plan(problem)
    assert result.status == "ok", result.message
    assert violations(problem, result.trajectory) == []
    assert stages[-1].first == (("crossing",) if first else ())
    traj = result.trajectory
    on_lane = (-y0 - 5.0) / 10.0  # when its front reaches the lane's far half [s]
    x_then = float(np.interp(on_lane, traj.t, traj.x))
    if first:  # our rear past its far side
        assert x_then - 2.25 > 80.0 + 0.9
    else:  # our front short of its near side, braking for it
        assert x_then + 2.25 < 80.0 - 0.9
    assert np.max(traj.v) <= 14.0 + 1e-6 and np.max(traj.a) <= problem.vehicle.max_acceleration + 1e-6


def test_passing_in_front_that_breaks_a_check_yields_instead(monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the profile passing in front of crossing traffic breaks a final check, the speed stage runs
    again yielding to it, and that answer (which passes them) is the plan's."""
    problem = PlanningProblem(
        ROAD,
        Lane(3.5, 3.5),
        Ego(30.0, 0.0, 0.0, 10.0),
        (_crossing(-70.0),),
        Vehicle(),
        Options(target_speed=14.0),
    )
    stages: list[SpeedPlan] = []
    checked = drive._trajectory

    def kept(*args: Any, **kwargs: Any) -> SpeedPlan:
        stages.append(speed_stage(*args, **kwargs))
        return stages[-1]

    def refused(*args: Any) -> Any:
        profile, traj, bad, note = checked(*args)
        if args[3].first:  # the speed plan passes in front: say it hits the crossing car
            bad = [Violation(ViolationKind.HITS_MOVING_OBSTACLE, "crossing", 5.0)]
        return profile, traj, bad, note

    monkeypatch.setattr(drive, "speed_stage", kept)
    monkeypatch.setattr(drive, "_trajectory", refused)
    result = plan(problem)
    assert [stage.first for stage in stages] == [("crossing",), ()]
    assert result.status == "ok", result.message
    assert violations(problem, result.trajectory) == []
    x_then = float(np.interp(6.5, result.trajectory.t, result.trajectory.x))
    assert x_then + 2.25 < 80.0 - 0.9  # short of it as it crosses


def test_past_its_budget_the_speed_stage_does_not_solve_again_with_the_emergency_jerk(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """18 m/s into a hairpin of radius 15 m: the comfortable jerk cannot slow down in time, and the
    profile is solved again with the emergency jerk — only while the budget leaves what the first solve
    took (past it, the plan falls back anyway). Without a budget both solves run."""
    problem = two_lane_problem(hairpin(15.0, leg=30.0), speed=18.0, road=False)
    solves = counted_calls(monkeypatch, SpeedSolver, "solve")
    plan(problem)
    assert len(solves) == 2
    solves.clear()
    monkeypatch.setattr(StageTimer, "remaining_s", lambda self: 1e-9)  # nothing left, whatever the budget
    plan(problem)
    assert len(solves) == 1


def test_behind_a_slow_leader_too_close_for_the_comfortable_jerk_the_second_profile_starts_on_the_spare(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """15 m/s with a leader at 8 m/s 10 m ahead: braking with the comfortable jerk cannot keep the
    headway, so the profile with the emergency jerk is solved next; it starts on the spare thread beside
    the first, and the answer is the one planned without a spare thread. Without a leader nothing starts."""
    ego, options = Ego(30.0, 0.0, 0.0, 15.0), Options(target_speed=15.0)
    leader = car("leader", 30.0 + 4.5 + 10.0, 8.0)
    problem = PlanningProblem(straight(), Lane(1.75, 1.75), ego, (leader,), Vehicle(), options)
    started = counted_calls(monkeypatch, Spare, "submit")
    solves = counted_calls(monkeypatch, SpeedSolver, "solve")
    alone = plan(problem, replace(DEFAULT_CONFIG, speculate=False))
    assert (len(started), len(solves)) == (0, 2)
    beside = plan(problem)
    assert (len(started), len(solves)) == (1, 4)  # the emergency profile's solve on the spare thread
    assert (beside.status, beside.message) == (alone.status, alone.message) == ("ok", "planned")
    np.testing.assert_array_equal(beside.trajectory.v, alone.trajectory.v)
    np.testing.assert_array_equal(beside.trajectory.y, alone.trajectory.y)
    started.clear()
    free = plan(PlanningProblem(straight(), Lane(1.75, 1.75), ego, (), Vehicle(), options))
    assert free.status == "ok" and started == []


def test_into_a_bend_too_fast_for_the_comfortable_jerk_the_second_profile_starts_on_the_spare(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """18 m/s into a hairpin of radius 15 m (no traffic): braking with the comfortable jerk cannot get
    under the bend's limit in time, so the emergency jerk's profile starts on the spare thread beside the
    first; the answer is the one planned without a spare thread. At 8 m/s nothing starts."""
    problem = two_lane_problem(hairpin(15.0, leg=30.0), speed=18.0, road=False)
    started = started_work(monkeypatch)
    alone = plan(problem, replace(DEFAULT_CONFIG, speculate=False))
    assert started == []
    beside = plan(problem)
    # (the lateral QP's elastic problems start there too: its corridor is tight at this speed)
    assert started.count("emergency") == 1
    assert (beside.status, beside.message) == (alone.status, alone.message)
    np.testing.assert_array_equal(beside.trajectory.v, alone.trajectory.v)
    np.testing.assert_array_equal(beside.trajectory.x, alone.trajectory.x)
    started.clear()
    slow = plan(two_lane_problem(hairpin(15.0, leg=30.0), speed=8.0, road=False))
    assert slow.status == "ok" and "emergency" not in started


@pytest.mark.parametrize("speed", [0.0, 0.3])
@pytest.mark.parametrize("measured", [-5.0, -8.0])
def test_a_vehicle_measured_braking_as_it_stops_is_planned_standing_or_stopping_not_rolling_back(
    speed: float, measured: float
) -> None:
    """Standing (or nearly) and measured braking hard: the brakes hold a standing vehicle, so the profiles
    start from no harder braking than releasing it at the emergency jerk stops exactly (−√(2·jerk·v₀)).
    From the measured value the release took the profile backwards (σ falling, positions against v·dt):
    the plan was a fallback; now it is ``ok``, every check passed, its speed never negative."""
    jerk = DEFAULT_CONFIG.speed.emergency_jerk
    vehicle = Vehicle(max_deceleration=8.0)
    problem = PlanningProblem(
        ROAD, Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, speed, acceleration=measured), (), vehicle, Options()
    )
    assert initial_acceleration(problem) == pytest.approx(max(measured, -np.sqrt(2.0 * jerk * speed)))
    result = plan(problem)
    assert result.status == "ok", result.message
    assert result.trajectory is not None and np.all(result.trajectory.v >= 0.0)
    assert np.all(np.diff(result.trajectory.s) >= -1e-9)
    # not standing: the measured braking is kept wherever the release ends at or above a standstill
    moving = replace(problem, ego=replace(problem.ego, speed=5.0))
    assert initial_acceleration(moving) == measured
