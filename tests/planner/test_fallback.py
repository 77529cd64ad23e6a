"""The fallback: braking along the best path known, and never braking into a vehicle coming from behind.

The policy ranks violations by kind and by whose they are (a hit by a follower, one by anything
else, a broken limit), never by their text.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, event, given, note, settings
from hypothesis import strategies as st
from scenario_roads import Road, arc_piece, follow_prediction, straight_piece
from traffic import LANE, ROAD, T, car, violations

from planner.config import DEFAULT_CONFIG
from planner.ego import start_state
from planner.fallback import fallback, severity, straight_on
from planner.pipeline import plan
from planner.problem import DynamicObstacle, Ego, Lane, Options, PlanningProblem, PolygonObstacle, Vehicle
from planner.reference import build_reference
from planner.roads import straight, u_turn
from planner.speed import Profile, ProfileKind, braking, profile_grid
from planner.st_bounds import static_shapes
from planner.timing import STAGES, TOTAL
from planner.trajectory import polyline_path
from planner.validation import LIMITS, Violation, ViolationKind
from tests.regression.checks import limit_problems

KIND = ViolationKind


def _hit(kind: ViolationKind, obstacle_id: str) -> Violation:
    return Violation(kind, obstacle_id=obstacle_id, t=1.0)


def test_wrong_numbers_rank_first_then_a_broken_limit_a_hit_ahead_one_from_behind_and_the_rest() -> None:
    rear = {"behind"}
    from_behind = [_hit(KIND.HITS_MOVING_OBSTACLE, "behind")]
    leader = [_hit(KIND.HITS_MOVING_OBSTACLE, "leader")]
    wall = [_hit(KIND.HITS_OBSTACLE, "wall")]
    lane = [Violation(KIND.LANE, t=1.0)]
    lateral = [Violation(KIND.LATERAL_ACCELERATION, t=1.0, value=7.0)]
    step = [Violation(KIND.STEP, t=1.0)]
    assert severity(from_behind, rear) == (0, 0, 0, 0, 1, 0)
    assert severity(leader, rear) == severity(wall, rear) == (0, 0, 0, 1, 0, 0)  # only a follower is "behind"
    assert severity(lane, rear) < severity(from_behind, rear) < severity(wall, rear) < severity(lateral, rear)
    assert severity(lateral, rear) < severity(step, rear)
    # a static obstacle with a follower's id is not hit from behind
    assert severity([_hit(KIND.HITS_OBSTACLE, "behind")], rear) == (0, 0, 0, 1, 0, 0)
    assert severity([*from_behind, *lane, *wall, *lateral, *step], rear) == (0, 1, 1, 1, 1, 1)
    for kind in (KIND.CURVATURE, KIND.ACCELERATION, KIND.SPEED, KIND.STEERING_ANGLE, KIND.STEERING_RATE):
        assert severity([Violation(kind, t=0.0, value=1.0)], rear) == (0, 0, 1, 0, 0, 0)
    for kind in (KIND.FRENET, KIND.HEADING, KIND.TURN, KIND.REAR_AXLE_SLIPS, KIND.S_DECREASES, KIND.KAPPA_D):
        assert severity([Violation(kind, t=0.0)], rear) == (0, 1, 0, 0, 0, 0)
    # one that does not start at the ego is not the ego's motion: worse than any other disagreement
    elsewhere = [Violation(KIND.START, t=0.0)]
    assert severity(elsewhere, rear) == (1, 1, 0, 0, 0, 0)
    assert severity([Violation(KIND.S_DECREASES, t=0.0), *lateral, *wall], rear) < severity(elsewhere, rear)


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


def test_when_braking_stands_in_crossing_traffic_the_fallback_drives_on() -> None:
    """A car crossing the road where full braking would leave the ego standing (a hit by anything
    moving, not only from behind): keeping the speed is weighed and taken, as it passes before."""
    problem = PlanningProblem(ROAD, LANE, Ego(30.0, 0.0, 0.0, 10.0), (), Vehicle())
    ref = build_reference(ROAD)
    start = start_state(ref, problem)
    s = np.linspace(start.s, 120.0, 181)
    straight_on = polyline_path(ref, s, 0.0 * s)
    stands = fallback("a reason", straight_on, straight_on, ref, problem, start, [])
    assert stands.profile is ProfileKind.BRAKING and stands.violations == ()
    x_stop = float(stands.trajectory.x[-1])
    # crossing at the stopped ego's front from the right, there at t = 4 s (the ego passed at ~1 s)
    y = -40.0 + 10.0 * T
    crossing = DynamicObstacle(
        "crossing", 4.5, 1.8, np.column_stack((T, 0 * T + x_stop + 2.0, y, 0 * T + np.pi / 2))
    )
    problem = PlanningProblem(ROAD, LANE, problem.ego, (crossing,), Vehicle())
    assert [(v.kind, v.obstacle_id) for v in violations(problem, stands.trajectory)] == [
        (KIND.HITS_MOVING_OBSTACLE, "crossing")
    ]
    out = fallback("a reason", straight_on, straight_on, ref, problem, start, [])
    assert out.profile is ProfileKind.KEEP_SPEED and out.violations == ()
    assert "braking is hit by moving traffic" in out.message and "keeping the speed instead" in out.message
    assert violations(problem, out.trajectory) == []
    assert out.follower is None


def test_braking_stays_when_driving_on_hits_a_leader_sooner() -> None:
    """A leader braking hard ahead: every profile hits it, braking latest; the fallback brakes."""
    leader = DynamicObstacle("leader", 4.5, 1.8, np.column_stack((T, 40.0 + 0 * T, 0 * T, 0 * T)))
    problem = PlanningProblem(ROAD, LANE, Ego(30.0, 0.0, 0.0, 12.0), (leader,), Vehicle())
    ref = build_reference(ROAD)
    start = start_state(ref, problem)
    s = np.linspace(start.s, 120.0, 181)
    straight_on = polyline_path(ref, s, 0.0 * s)
    out = fallback("a reason", straight_on, straight_on, ref, problem, start, [])
    assert out.profile is ProfileKind.BRAKING
    assert [(v.kind, v.obstacle_id) for v in out.violations] == [(KIND.HITS_MOVING_OBSTACLE, "leader")]


def _curve_ahead(ego_speed: float, follower: DynamicObstacle | None = None) -> tuple[PlanningProblem, Road]:
    """A 25 m curve 40 m ahead of the ego (about 8 m/s within 3 m/s² of lateral acceleration)."""
    road = Road([straight_piece(80.0), arc_piece(25.0, np.pi / 2), straight_piece(80.0)])
    x, y, heading = road.pose(40.0)
    obstacles = () if follower is None else (follower,)
    ego = Ego(x, y, heading, ego_speed)
    options = Options(target_speed=ego_speed)
    return PlanningProblem(road.polyline(1.0), Lane(3.5, 3.5), ego, obstacles, Vehicle(), options), road


def test_keeping_the_speed_to_escape_a_car_behind_still_slows_for_a_curve() -> None:
    """At 14 m/s towards the curve with a car 12 m behind at 14 m/s that does not slow: braking is hit
    from behind, and keeping 14 m/s through the curve would need 7.8 m/s² of lateral acceleration
    (3 allowed). Whatever the fallback chooses is within the vehicle's limits (the independent checks)."""
    road = Road([straight_piece(80.0), arc_piece(25.0, np.pi / 2), straight_piece(80.0)])
    behind = DynamicObstacle("behind", 4.5, 1.8, follow_prediction(road, 40.0 - 16.5, 14.0, 8.0))
    problem, _ = _curve_ahead(14.0, behind)
    ref = build_reference(problem.reference_line)
    start = start_state(ref, problem)
    s = np.linspace(start.s, start.s + 150.0, 301)
    path = polyline_path(ref, s, 0.0 * s)
    out = fallback("a reason", path, path, ref, problem, start, [])
    assert "braking is hit from behind" in out.message
    assert limit_problems(problem, out.trajectory) == []
    assert out.profile is not ProfileKind.BRAKING
    # what keeping 14 m/s would have been: far outside the limit
    t = np.arange(81) * 0.1
    zero = np.zeros(81)
    kept = Profile(ProfileKind.KEEP_SPEED, t, 14.0 * t, zero + 14.0, zero, zero[1:])
    broken = limit_problems(problem, kept.sample(path, 0.1, ref, problem.vehicle))
    assert any("lateral acceleration" in p for p in broken)


_SPEEDS = st.floats(0.0, 20.0)


@settings(max_examples=40, deadline=None)
@given(
    radius=st.floats(15.0, 80.0),
    turn=st.sampled_from([-1.0, 1.0]),
    straight=st.floats(40.0, 120.0),
    v0=_SPEEDS,
    a0=st.floats(-2.0, 1.0),
    gap=st.floats(2.0, 20.0),
    closing=st.floats(0.0, 10.0),
    leader=st.none() | st.tuples(st.floats(8.0, 40.0), _SPEEDS),
    target=st.floats(3.0, 20.0),
    above=st.none() | st.floats(0.0, 10.0),
    car_model=st.booleans(),
)
def test_every_answer_in_a_scene_that_allows_it_is_within_the_vehicles_limits(
    radius: float,
    turn: float,
    straight: float,
    v0: float,
    a0: float,
    gap: float,
    closing: float,
    leader: tuple[float, float] | None,
    target: float,
    above: float | None,
    car_model: bool,
) -> None:
    """A curve ahead, a car behind that does not react (faster or as fast) and maybe a leader: whenever
    braking at once keeps the lateral limit up to the curve, every answer — fallbacks hit from behind
    included — keeps the curvature, steering, lateral and longitudinal limits (the independent checks
    of tests/regression/checks.py)."""
    vehicle = Vehicle(wheelbase=2.7, rear_axle_offset=1.35) if car_model else Vehicle()
    a_lat, decel = vehicle.max_lateral_acceleration, vehicle.max_deceleration
    ego_s = 20.0
    room = straight - ego_s - vehicle.length
    # the curve can be taken: at the speed after braking at half the deceleration up to it
    assume(v0**2 - decel * max(room - v0 * 0.5, 0.0) <= 0.8 * a_lat * radius)
    road = Road([straight_piece(straight), arc_piece(radius, turn * np.pi / 2), straight_piece(100.0)])
    x, y, heading = road.pose(ego_s)
    others = [
        DynamicObstacle(
            "behind", 4.5, 1.8, follow_prediction(road, ego_s - vehicle.length - gap, v0 + closing, 8.0)
        )
    ]
    if leader is not None:
        ahead, speed = leader
        others.append(
            DynamicObstacle("leader", 4.5, 1.8, follow_prediction(road, ego_s + 4.5 + ahead, speed, 8.0))
        )
    options = Options(target_speed=target, speed_limit=None if above is None else target + above)
    ego = Ego(x, y, heading, v0, acceleration=a0)
    problem = PlanningProblem(road.polyline(1.0), Lane(3.5, 3.5), ego, tuple(others), vehicle, options)
    result = plan(problem)
    event(result.status)
    note(f"{result.status}: {result.message}")
    assert limit_problems(problem, result.trajectory) == []


@pytest.mark.parametrize("car_model", [False, True])
def test_a_start_too_fast_for_every_bend_ahead_brakes_straight_on_within_the_limits(car_model: bool) -> None:
    """At 60 m/s on a bend of 10 m radius every path along the road breaks the lateral limit (36 g):
    the fallback brakes straight on along the ego's heading instead (no curvature), which keeps every
    limit of the vehicle whatever else it breaks (here: it leaves the lane)."""
    road = Road([arc_piece(10.0, np.pi), straight_piece(80.0)])
    vehicle = Vehicle(wheelbase=2.7, rear_axle_offset=1.35) if car_model else Vehicle()
    x, y, heading = road.pose(2.0)
    problem = PlanningProblem(road.polyline(0.5), Lane(3.5, 3.5), Ego(x, y, heading, 60.0), (), vehicle)
    result = plan(problem)
    assert result.status == "fallback"
    assert limit_problems(problem, result.trajectory) == []
    traj = result.trajectory
    np.testing.assert_allclose(traj.curvature, 0.0, atol=1e-9)
    np.testing.assert_allclose(np.unwrap(traj.heading), heading, atol=1e-9)
    assert traj.v[-1] < traj.v[0]
    assert KIND.LANE in {v.kind for v in result.violations}


def test_a_car_braking_straight_on_first_steers_back_to_straight_within_its_steering_rate() -> None:
    """A car at 12 m/s on a bend of 10 m radius (14 m/s² along it) measured steering into it at 0.015 1/m
    (2.2 m/s², its limit 3): every path along the road breaks the lateral limit and the fallback brakes
    straight on. It starts at the measured steering angle and unwinds it within the steering rate, then
    drives straight; before, it started straight at once, 0.04 rad off the angle it was steering at."""
    road = Road([arc_piece(10.0, np.pi), straight_piece(80.0)])
    vehicle = Vehicle(wheelbase=2.7, rear_axle_offset=1.35, max_steering_rate=0.4)
    x, y, heading = road.pose(2.0)
    ego = Ego(x, y, heading, 12.0, curvature=0.015)
    problem = PlanningProblem(road.polyline(0.5), Lane(3.5, 3.5), ego, (), vehicle)
    result = plan(problem)
    assert result.status == "fallback"
    traj = result.trajectory
    assert traj.curvature[0] == pytest.approx(0.015, abs=1e-5)
    assert limit_problems(problem, traj) == []
    assert np.all(np.diff(traj.curvature) <= 1e-12) and traj.curvature[-1] == 0.0  # unwinding, then straight
    assert not {v.kind for v in result.violations} & {ViolationKind.START, *LIMITS}


@pytest.mark.parametrize("curvature", [-0.2, -0.01, 0.003, 0.15])
@pytest.mark.parametrize("speed", [0.3, 4.0, 25.0])
def test_the_straight_on_path_unwinds_the_measured_curvature_at_the_steering_rate(
    curvature: float, speed: float
) -> None:
    """The path's heading is its curvature's integral and its points follow the heading; driven at any
    speed up to the start's, the steering rate stays within its share of the limit; past the unwinding,
    the curvature is 0."""
    vehicle = Vehicle(wheelbase=2.7, rear_axle_offset=1.35, max_steering_rate=0.4)
    problem = PlanningProblem(
        straight(100.0, step=1.0),
        Lane(3.5, 3.5),
        Ego(10.0, 0.5, 0.2, speed, curvature=curvature),
        (),
        vehicle,
    )
    ref = build_reference(problem.reference_line)
    path = straight_on(ref, problem)
    assert path.curvature[0] == pytest.approx(curvature) and path.heading[0] == pytest.approx(0.2)
    # the curvature is monotone between knots: the heading turns by between its ends' times the step
    turned, step = np.diff(path.heading), np.diff(path.sigma)
    low = np.minimum(path.curvature[1:], path.curvature[:-1]) * step
    high = np.maximum(path.curvature[1:], path.curvature[:-1]) * step
    assert np.all((turned >= low - 1e-12) & (turned <= high + 1e-12))
    # the heading is monotone between knots: each chord's direction lies between its ends' headings
    chord = np.arctan2(np.diff(path.y), np.diff(path.x))
    along = np.angle(np.exp(1j * (chord - path.heading[:-1])))  # from the heading at the start of the step
    assert np.all((along >= np.minimum(turned, 0.0) - 1e-6) & (along <= np.maximum(turned, 0.0) + 1e-6))
    steering = np.arctan(vehicle.wheelbase * path.curvature)
    rate = speed * np.abs(np.diff(steering)) / np.diff(path.sigma)  # at the start's speed, the fastest
    assert rate.max() <= 0.9 * 0.4 + 1e-9
    unwound_at = abs(curvature) * vehicle.wheelbase * speed / (0.9 * 0.4)
    assert np.all(path.curvature[path.sigma >= unwound_at] == 0.0)
    # the planned point is the rear axle, 1.35 m behind the centre along the yaw
    assert (path.x[0], path.y[0]) == pytest.approx((10.0 - 1.35 * np.cos(0.2), 0.5 - 1.35 * np.sin(0.2)))


@pytest.mark.parametrize("acceleration", [-4.0, 0.0, 6.0])
@pytest.mark.parametrize("speed", [0.6, 1.0, 2.0])
def test_braking_straight_on_keeps_the_steering_rate_whatever_the_measured_acceleration(
    speed: float, acceleration: float
) -> None:
    """Braking straight on from a car measured steering (0.05 1/m), sampled as the answer is: the steering
    rate stays within its limit, also where braking first releases a positive acceleration (6 m/s² at the
    emergency jerk: 0.6 m/s faster than measured). Unwound for the measured speed alone, it reached
    0.56 rad/s for a limit of 0.4."""
    vehicle = Vehicle(wheelbase=2.7, rear_axle_offset=1.35, max_steering_rate=0.4, max_acceleration=6.0)
    ego = Ego(10.0, 0.5, 0.2, speed, acceleration=acceleration, curvature=0.05)
    problem = PlanningProblem(straight(100.0, step=1.0), Lane(3.5, 3.5), ego, (), vehicle)
    ref = build_reference(problem.reference_line)
    path = straight_on(ref, problem)
    steps, dt = profile_grid(problem.options, DEFAULT_CONFIG.speed)
    profile = braking(path, problem, steps, dt, DEFAULT_CONFIG.speed)
    traj = profile.sample(path, problem.options.dt, ref, vehicle)
    assert traj.curvature[0] == pytest.approx(0.05, abs=1e-6)
    steering = np.arctan(vehicle.wheelbase * traj.curvature)
    assert np.max(np.abs(np.diff(steering)) / np.diff(traj.t)) <= 0.4


def test_a_car_yawed_far_off_a_tight_u_turns_leg_brakes_along_its_own_heading_from_where_it_is() -> None:
    """A car 49° off the straight leg of a 3.2 m U-turn at 7 m/s, its lane too narrow for any path: the
    QP holds its rear axle's offset along the reference, whose body (yawed with the reference) stands
    1.4 m from the ego; braking straight on along its own yaw starts at the ego, its only fault that its
    projection runs back where it nears the other leg. Ranked by the count of disagreements alone, the
    held path came first and the answer did not start at the ego."""
    vehicle = Vehicle(
        length=5.1, width=1.9, max_curvature=0.18, max_deceleration=8.5, wheelbase=3.0, rear_axle_offset=1.7
    )
    problem = PlanningProblem(
        u_turn(radius=3.2, leg=45.0, step=0.5), Lane(2.0, 1.0), Ego(-20.0, 0.4, 0.86, 7.0), (), vehicle
    )
    result = plan(problem)
    assert result.status == "fallback" and result.trajectory is not None
    assert result.trajectory.x[0] == pytest.approx(-20.0) and result.trajectory.y[0] == pytest.approx(0.4)
    assert ViolationKind.START not in {v.kind for v in result.violations}
    np.testing.assert_allclose(result.trajectory.heading, 0.86)  # straight on, no steering
