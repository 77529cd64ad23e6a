"""The trajectory checks as typed violations: each kind from a trajectory that breaks exactly that check,
with the first time it happens and the message answers report."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planner.collision import box_corners
from planner.frenet import to_cartesian, to_frenet
from planner.problem import (
    DynamicObstacle,
    Ego,
    Lane,
    Obstacle,
    PlanningProblem,
    PolygonObstacle,
    Road,
    Vehicle,
)
from planner.reference import ReferenceLine, build_reference
from planner.roads import arc, straight
from planner.st_bounds import static_shapes
from planner.trajectory import Trajectory, body_trajectory, frenet_path, sample
from planner.validation import (
    EMERGENCY_JERK,
    HITS,
    Violation,
    ViolationKind,
    consistency_violations,
    fastest_braking,
    lane_overshoot,
    leaves_lane,
    return_length,
    speed_violations,
    start_allowance,
    still_out,
    trajectory_violations,
)
from solvers.speed_problem import integrate_jerk

DT, SPEED = 0.1, 5.0
STRAIGHT = build_reference(straight(200.0, step=1.0))
BEND = build_reference(arc(30.0, 2.0, step=0.5))  # radius 30 m: κ = 1/30 1/m


def _along(ref: ReferenceLine, speed: float = SPEED, steps: int = 50) -> Trajectory:
    """A clean trajectory along the reference from ``s = 10 m`` at a constant ``speed`` [m/s]."""
    s = np.linspace(10.0, 10.0 + speed * steps * DT + 5.0, 200)
    path = frenet_path(ref, s, 0.0 * s, 0.0 * s, 0.0 * s)
    t = np.arange(steps + 1) * DT
    v, zeros = np.full(steps + 1, speed), np.zeros(steps + 1)
    return sample(path, t, speed * t, v, zeros, zeros[:-1], DT, ref)


def _problem(ref: ReferenceLine, traj: Trajectory, *obstacles: Obstacle, **vehicle: float) -> PlanningProblem:
    """The problem whose ego is the trajectory's first point (a car's: the first point is its centre,
    ``heading`` its yaw)."""
    ego = Ego(x=float(traj.x[0]), y=float(traj.y[0]), heading=float(traj.heading[0]), speed=float(traj.v[0]))
    return PlanningProblem(ref.points, Lane(3.5, 3.5), ego, obstacles, Vehicle(**vehicle))


def _violations(problem: PlanningProblem, traj: Trajectory) -> list[Violation]:
    """The violations of ``traj``; with a road, as a plan that borrows it (in the road, not the lane)."""
    ref = build_reference(problem.reference_line)
    return trajectory_violations(
        ref, problem, traj, static_shapes(problem), borrowing=problem.road is not None
    )


def _set(values: np.ndarray, i: int, value: float) -> np.ndarray:
    out = values.copy()
    out[i] = value
    return out


def _from_frenet(ref: ReferenceLine, s: np.ndarray, d: np.ndarray) -> Trajectory:
    """A trajectory through the points ``(s, d)`` taken at 0.1 s steps whose numbers agree with each
    other: positions by TransF-κ's inverse, heading and curvature from the positions, speed from the
    steps."""
    xy = to_cartesian(ref, s, d)
    sigma = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    heading = np.unwrap(np.arctan2(np.gradient(xy[:, 1], sigma), np.gradient(xy[:, 0], sigma)))
    t = np.arange(s.size) * DT
    v = np.gradient(sigma, t)
    a, curvature = np.zeros(s.size), np.gradient(heading, sigma)
    return Trajectory(t=t, x=xy[:, 0], y=xy[:, 1], heading=heading, curvature=curvature, v=v, a=a, s=s, d=d)


#: a reference turning 1.3 times around a circle of radius 10 m: its second lap runs on its first
LOOP = build_reference(arc(10.0, 2.6 * np.pi, step=0.5))
#: a short straight road: a trajectory along it runs past its end
SHORT = build_reference(straight(30.0, step=1.0))


def _drift(to: float = 4.0) -> Trajectory:
    """Straight on from the ego while drifting to ``d = to`` [m]: out of the lane."""
    s = CLEAN.s
    return _from_frenet(STRAIGHT, s, np.linspace(0.0, to, s.size))


def _crossing(t_in: float) -> DynamicObstacle:
    """A car crossing the road at x = 25 m, in the way of the clean trajectory from ``t_in`` [s] on."""
    t = np.array([0.0, t_in, t_in + 0.5, 10.0])
    y = np.array([-30.0, -1.2, 0.0, 0.0])
    return DynamicObstacle(
        "crossing", 4.5, 1.8, np.column_stack((t, np.full(4, 32.0), y, np.full(4, np.pi / 2)))
    )


def _box(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


CLEAN = _along(STRAIGHT)
#: a car (wheelbase, rear axle 1.35 m behind the centre)
CAR = {"wheelbase": 2.7, "rear_axle_offset": 1.35}


def _case(kind: ViolationKind) -> tuple[PlanningProblem, Trajectory]:
    """A problem and a trajectory that breaks exactly the check ``kind``."""
    if kind is ViolationKind.START:
        shifted = replace(CLEAN, x=CLEAN.x + 1.0, s=CLEAN.s + 1.0)  # along the x axis: s = x
        return _problem(STRAIGHT, CLEAN), shifted
    if kind is ViolationKind.KAPPA_D:
        # 0.5 m past the centre of curvature of the radius-30 bend, in a lane that reaches there
        s = np.linspace(10.0, 30.0, 40)
        beyond = _from_frenet(BEND, s, np.full(s.size, 30.5))
        problem = _problem(BEND, beyond, max_curvature=10.0, max_lateral_acceleration=1e4)
        return replace(problem, lane=Lane(40.0, 3.5)), beyond
    if kind is ViolationKind.CURVATURE:
        bend = _along(BEND)  # κ = 1/30 1/m
        return _problem(BEND, bend, max_curvature=0.02, max_lateral_acceleration=10.0), bend
    if kind is ViolationKind.LATERAL_ACCELERATION:
        bend = _along(BEND)  # 25 / 30 ≈ 0.83 m/s²
        return _problem(BEND, bend, max_lateral_acceleration=0.5), bend
    if kind is ViolationKind.ACCELERATION:
        return _problem(STRAIGHT, CLEAN), replace(CLEAN, a=_set(CLEAN.a, 20, 3.0))
    if kind is ViolationKind.STEP:
        return _problem(STRAIGHT, CLEAN), replace(CLEAN, v=_set(CLEAN.v, 20, SPEED + 2.0))
    if kind is ViolationKind.S_DECREASES:
        slow = _along(STRAIGHT, speed=0.6)  # steps of 6 cm: the repeated s is within its position's tolerance
        return _problem(STRAIGHT, slow), replace(slow, s=_set(slow.s, 20, slow.s[19]))
    if kind is ViolationKind.SELF_INTERSECTS:
        around = _along(LOOP, steps=130)  # 65 m along a circle of 63 m
        return _problem(LOOP, around), around
    if kind is ViolationKind.LANE:
        drift = _drift()
        return _problem(STRAIGHT, drift), drift
    if kind is ViolationKind.ROAD:  # borrowing a road 3.5 m to the left: the drift leaves it too
        drift = _drift()
        narrow = replace(_problem(STRAIGHT, drift), lane=Lane(1.75, 1.75), road=Road(3.5, 1.75))
        return narrow, drift
    if kind is ViolationKind.HITS_OBSTACLE:
        parked = PolygonObstacle("parked", _box(30.0, 34.0, 0.5, 2.0))
        return _problem(STRAIGHT, CLEAN, parked), CLEAN
    if kind is ViolationKind.HITS_MOVING_OBSTACLE:
        return _problem(STRAIGHT, CLEAN, _crossing(3.0)), CLEAN
    if kind is ViolationKind.REAR_AXLE_SLIPS:
        # straight on along x, the body yawed by 0.2 rad: its rear axle moves 0.2 rad off the yaw
        yawed = replace(CLEAN, heading=np.full(CLEAN.size, 0.2), steering_angle=np.zeros(CLEAN.size))
        return _problem(STRAIGHT, yawed, **CAR), yawed
    if kind is ViolationKind.STEERING_ANGLE:  # default limit atan(2.7 · 0.2) ≈ 0.495 rad
        steered = replace(CLEAN, steering_angle=_set(np.zeros(CLEAN.size), 20, 0.6))
        return _problem(STRAIGHT, CLEAN, **CAR), steered
    if kind is ViolationKind.STEERING_RATE:  # 0.2 rad in 0.1 s: 2 rad/s
        steered = replace(CLEAN, steering_angle=np.where(np.arange(CLEAN.size) > 20, 0.2, 0.0))
        return _problem(STRAIGHT, CLEAN, **CAR, max_steering_rate=1.0), steered
    if kind is ViolationKind.FRENET:
        return _problem(STRAIGHT, CLEAN), replace(CLEAN, d=_set(CLEAN.d, 20, 0.5))  # the position stays
    if kind is ViolationKind.HEADING:
        crabbing = replace(CLEAN, heading=CLEAN.heading + 0.3)  # the ego yawed so too
        return _problem(STRAIGHT, crabbing), crabbing
    if kind is ViolationKind.TURN:
        # curvature 0.15 1/m reported while the heading does not change (within the vehicle's limits)
        turning = replace(CLEAN, curvature=np.full(CLEAN.size, 0.15))
        return _problem(STRAIGHT, CLEAN, max_lateral_acceleration=10.0), turning
    if kind is ViolationKind.SPEED:
        return _problem(STRAIGHT, CLEAN, max_speed=4.0), CLEAN  # 5 m/s, not braking
    past = _along(SHORT)  # from s = 10 m to 35 m on a 30 m road
    return _problem(SHORT, past), past


def test_the_clean_trajectories_pass_every_check() -> None:
    for ref, traj in ((STRAIGHT, CLEAN), (BEND, _along(BEND))):
        assert _violations(_problem(ref, traj), traj) == []


def _car_along(ref: ReferenceLine, vehicle: Vehicle) -> Trajectory:
    """A car driving along the reference with its rear axle on it (at a constant speed): its centre
    ahead along the yaw, as :func:`planner.trajectory.body_trajectory` gives it."""
    return body_trajectory(ref, vehicle, _along(ref))


def test_a_car_driving_on_a_circle_passes_the_car_checks_and_its_centre_slips() -> None:
    vehicle = Vehicle(**CAR, max_steering_rate=0.5)
    car = _car_along(BEND, vehicle)
    assert car.steering_angle is not None
    np.testing.assert_allclose(car.steering_angle[1:-1], np.arctan(2.7 / 30.0), rtol=1e-3)
    assert _violations(_problem(BEND, car, **CAR, max_steering_rate=0.5), car) == []
    # a point model's trajectory on an 8 m circle read as a car's: its centre moves along the yaw, so
    # the point 2.25 m behind it (the car's rear axle) moves atan(2.25/8) off the yaw
    tight = build_reference(arc(8.0, 2.0, step=0.5))
    point = _along(tight)
    found = consistency_violations(tight, Vehicle(wheelbase=2.7, rear_axle_offset=2.25), point)
    (slipping,) = [v for v in found if v.kind is ViolationKind.REAR_AXLE_SLIPS]
    assert slipping.value == pytest.approx(np.arctan(2.25 / 8.0), rel=0.05)


def test_a_cars_lateral_acceleration_is_its_centres() -> None:
    # rear axle on a 30 m circle at 5 m/s: v²κ = 0.833 m/s², the centre's v²κ√(1 + (l_r κ)²) more
    vehicle = Vehicle(**CAR)
    car = _car_along(BEND, vehicle)
    limit = 25.0 / 30.0 * 1.0005  # above v²κ (and its tolerances), below the centre's
    offset = 2.25
    big = {"wheelbase": 2.7, "rear_axle_offset": offset}
    assert _violations(_problem(BEND, car, **CAR, max_lateral_acceleration=limit), car) == []
    wide = _car_along(BEND, Vehicle(**big))
    expected = 25.0 / 30.0 * np.sqrt(1.0 + (offset / 30.0) ** 2)
    (lateral,) = _violations(_problem(BEND, wide, **big, max_lateral_acceleration=limit), wide)
    assert lateral.kind is ViolationKind.LATERAL_ACCELERATION
    assert lateral.value == pytest.approx(expected, rel=2e-3)


@pytest.mark.parametrize("kind", list(ViolationKind), ids=lambda k: k.value)
def test_each_check_gives_its_own_kind(kind: ViolationKind) -> None:
    problem, traj = _case(kind)
    assert [v.kind for v in _violations(problem, traj)] == [kind]


#: the text of each kind in answers (their ``message`` embeds it: it must not change)
MESSAGES = {
    ViolationKind.START: "does not start at the ego",
    ViolationKind.KAPPA_D: "1 − κ·d ≤ 0 at some point",
    ViolationKind.CURVATURE: "curvature 0.033 1/m above max_curvature",
    ViolationKind.LATERAL_ACCELERATION: "lateral acceleration 0.83 m/s² above the limit",
    ViolationKind.ACCELERATION: "acceleration outside the limits",
    ViolationKind.STEP: "positions inconsistent with v·dt",
    ViolationKind.S_DECREASES: "s does not increase while moving",
    ViolationKind.SELF_INTERSECTS: "self-intersects",
    ViolationKind.LANE: "footprint leaves the lane",
    ViolationKind.ROAD: "footprint leaves the road",
    ViolationKind.HITS_OBSTACLE: "footprint hits obstacle parked",
    ViolationKind.HITS_MOVING_OBSTACLE: "footprint hits moving obstacle crossing",
    ViolationKind.FRENET: "positions inconsistent with the reported (s, d)",
    ViolationKind.HEADING: "heading off the direction of motion",
    ViolationKind.TURN: "curvature inconsistent with the heading's change",
    ViolationKind.SPEED: "speed 5.00 m/s above max_speed",
    ViolationKind.ROAD_END: "the front passes the end of the reference line",
    ViolationKind.REAR_AXLE_SLIPS: "the rear axle moves 0.200 rad off the body's yaw",
    ViolationKind.STEERING_ANGLE: "steering angle 0.600 rad above max_steering_angle",
    ViolationKind.STEERING_RATE: "steering rate 2.000 rad/s above max_steering_rate",
}


@pytest.mark.parametrize("kind", list(ViolationKind), ids=lambda k: k.value)
def test_messages_are_rendered_from_the_record_as_answers_word_them(kind: ViolationKind) -> None:
    problem, traj = _case(kind)
    (violation,) = _violations(problem, traj)
    assert violation.message == str(violation) == f"{violation}" == MESSAGES[kind]


def test_a_violation_says_when_it_first_happens_and_what_it_hit() -> None:
    problem, traj = _case(ViolationKind.ACCELERATION)
    assert _violations(problem, traj)[0].t == pytest.approx(traj.t[20])
    problem, traj = _case(ViolationKind.START)
    assert _violations(problem, traj)[0].t == 0.0
    problem, traj = _case(ViolationKind.SELF_INTERSECTS)
    assert _violations(problem, traj)[0].t is None  # a crossing has no one time
    problem, traj = _case(ViolationKind.HITS_OBSTACLE)
    (hit,) = _violations(problem, traj)
    # the footprint's front reaches the parked car's rear edge (x = 30 m) at 0.1 s steps
    assert hit.obstacle_id == "parked" and hit.t is not None
    assert traj.x[traj.t == hit.t][0] + 2.25 >= 30.0 > traj.x[traj.t < hit.t].max() + 2.25
    # the crossing car comes into the lane just before t_in, while the footprint spans its x from 3.8 s
    # to 5.0 s: the hit starts when it arrives
    problem, traj = _case(ViolationKind.HITS_MOVING_OBSTACLE)
    times = []
    for t_in in (4.2, 4.6):
        (hit,) = _violations(replace(problem, obstacles=(_crossing(t_in),)), traj)
        assert hit.obstacle_id == "crossing" and hit.t is not None
        assert t_in - 0.5 < hit.t <= t_in
        times.append(hit.t)
    assert times[0] < times[1]


def test_a_moving_obstacle_that_stays_put_is_checked_as_static() -> None:
    parked = DynamicObstacle("parked car", 4.0, 1.8, np.array([[0.0, 32.0, 1.0, 0.0], [8.0, 32.0, 1.0, 0.0]]))
    problem = _problem(STRAIGHT, CLEAN, parked)
    (hit,) = _violations(problem, CLEAN)
    assert (hit.kind, hit.obstacle_id) == (ViolationKind.HITS_OBSTACLE, "parked car")


def test_the_hit_kinds_are_the_collisions() -> None:
    assert {ViolationKind.HITS_OBSTACLE, ViolationKind.HITS_MOVING_OBSTACLE} == HITS
    assert all(Violation(kind).obstacle_id is None for kind in ViolationKind)


@pytest.mark.parametrize("ref", [STRAIGHT, BEND], ids=["straight", "bend"])
def test_the_lane_overshoot_is_positive_exactly_where_the_footprint_leaves_the_lane_on_its_side(
    ref: ReferenceLine,
) -> None:
    """Footprints (W = 2 m, in a lane 3.5 m either side) at offsets from −4 m to 4 m, turned by up to
    0.3 rad: the overshoot on a side is positive exactly where :func:`leaves_lane` says it leaves the lane,
    on the side it is off to, by how far its outermost corner reaches beyond the edge."""
    s = np.linspace(20.0, 40.0, 41)
    d = np.linspace(-4.0, 4.0, 41)
    turn = 0.3 * np.sin(np.arange(41.0))
    xy = to_cartesian(ref, s, d)
    heading = ref.heading_at(s) + turn
    ego = Ego(x=float(xy[0, 0]), y=float(xy[0, 1]), heading=float(heading[0]), speed=0.0)
    problem = PlanningProblem(ref.points, Lane(3.5, 3.5), ego, (), Vehicle(length=4.0, width=2.0))
    right, left = lane_overshoot(ref, problem, xy[:, 0], xy[:, 1], heading)
    out = leaves_lane(ref, problem, xy[:, 0], xy[:, 1], heading)
    np.testing.assert_array_equal((right > 0.0) | (left > 0.0), out)
    assert out.any() and not out.all()
    assert not np.any((right > 0.0) & (left > 0.0))
    # off to the right where right, to the left where left (beyond the start's allowance: it starts out)
    assert np.all(d[right > 0.0] < 0.0) and np.all(d[left > 0.0] > 0.0)
    # far out on the left (d = 4 m, straight): the outer corners reach d + W/2 = 5 m, 1.5 m beyond the edge
    if ref is STRAIGHT:
        reach = 4.0 + 1.0 * np.cos(turn[-1]) + 2.0 * abs(np.sin(turn[-1]))
        assert left[-1] == pytest.approx(reach - 3.5, abs=1e-6)


def test_a_side_cutting_the_inside_of_a_bend_between_its_corners_leaves_the_lane() -> None:
    """A 4.5 × 1.8 m footprint tangent to a left bend of radius 6 m, 0.95 m left of it: its corners lie
    4.72 m from the centre of curvature, inside the lane's left edge (radius 6 − 1.75 = 4.25 m), but the
    middle of its left side only 4.15 m from it, 0.10 m over the edge (the side's sagitta). The checks
    measure the sides, not the corners alone."""
    radius, half_lane, length, width, d = 6.0, 1.75, 4.5, 1.8, 0.95
    ref = build_reference(arc(radius, 1.5, step=0.25))
    assert ref.kappa_at(np.array([0.5 * ref.length]))[0] > 0.0  # a left bend: its inside is on the left
    # a pose on the reference first (the first pose is a measurement the checks allow for), then the one
    s = np.array([0.5 * ref.length - 0.5 * length, 0.5 * ref.length])
    xy = to_cartesian(ref, s, np.array([0.0, d]))
    heading = ref.heading_at(s)
    ego = Ego(x=float(xy[0, 0]), y=float(xy[0, 1]), heading=float(heading[0]), speed=0.0)
    vehicle = Vehicle(length=length, width=width)
    problem = PlanningProblem(ref.points, Lane(half_lane, half_lane), ego, (), vehicle)
    corners = box_corners(xy[1:, 0], xy[1:, 1], heading[1:], length, width).reshape(-1, 2)
    assert to_frenet(ref, corners).d.max() < half_lane - 0.3  # every corner well inside
    right, left = lane_overshoot(ref, problem, xy[:, 0], xy[:, 1], heading)
    assert left[1] == pytest.approx(radius - (radius - d - 0.5 * width) - half_lane, abs=2e-3)  # 0.10 m
    assert right.tolist() == [0.0, 0.0] and left[0] == 0.0
    assert leaves_lane(ref, problem, xy[:, 0], xy[:, 1], heading).tolist() == [False, True]


def _braking_from(v0: float, a0: float, jerk: float, decel: float, steps: int = 50) -> Trajectory:
    """Along the straight from ``s = 10 m`` at ``v0`` [m/s], the acceleration falling from ``a0`` at
    ``jerk`` [m/s³] to ``−decel`` [m/s²] and held there until the vehicle stands."""
    t = np.arange(steps + 1) * DT
    a = np.maximum(a0 - jerk * t, -decel)
    s, v, _ = integrate_jerk(DT, 0.0, v0, a0, np.diff(a) / DT)
    stop = int(np.argmax(v <= 0.0)) if np.any(v <= 0.0) else steps + 1
    v, a = np.where(np.arange(steps + 1) < stop, v, 0.0), np.where(np.arange(steps + 1) < stop, a, 0.0)
    s = np.maximum.accumulate(np.where(np.arange(steps + 1) < stop, s, s[max(stop - 1, 0)]))
    path = frenet_path(STRAIGHT, np.linspace(10.0, 10.0 + s[-1] + 5.0, 200), *np.zeros((3, 200)))
    return sample(path, t, s, v, a, np.diff(a) / DT, DT, STRAIGHT)


def test_an_ego_faster_than_max_speed_may_brake_with_the_emergency_jerk_but_never_speed_up() -> None:
    """Measured at 18 m/s and −0.5 m/s² with a max_speed of 7 m/s: braking at once (the acceleration falling
    at the emergency jerk to −8 m/s²) is not too fast, although it loses speed more slowly than half the
    deceleration from the start; a ramp at a third of that jerk is. Measured speeding up (+4 m/s²), even
    braking at once goes past the ego's speed first: too fast (no answer keeps the limit then)."""
    at_once = _braking_from(18.0, -0.5, EMERGENCY_JERK, 8.0)
    ego = Ego(x=float(at_once.x[0]), y=float(at_once.y[0]), heading=0.0, speed=18.0, acceleration=-0.5)
    vehicle = Vehicle(max_speed=7.0, max_acceleration=5.0, max_deceleration=8.0)
    problem = PlanningProblem(STRAIGHT.points, Lane(3.5, 3.5), ego, (), vehicle)
    assert at_once.v[1] > 18.0 - 0.5 * 8.0 * DT + 0.05  # beyond the allowance of half the deceleration
    assert speed_violations(problem, at_once) == []
    slow = _braking_from(18.0, -0.5, EMERGENCY_JERK / 3.0, 8.0)
    (too_fast,) = speed_violations(problem, slow)
    assert too_fast.kind is ViolationKind.SPEED
    speeding_up = replace(problem, ego=replace(ego, acceleration=4.0))
    overshoot = _braking_from(18.0, 4.0, EMERGENCY_JERK, 8.0)
    assert overshoot.v.max() > 18.2
    (past_its_speed,) = speed_violations(speeding_up, overshoot)
    assert past_its_speed.value == overshoot.v.max()
    # measured braking harder than half the deceleration, the allowance is half of it as before
    braking = replace(problem, ego=replace(ego, acceleration=-8.0))
    np.testing.assert_allclose(fastest_braking(braking, np.array([0.0, 1.0])), [18.0, 10.0])
    assert speed_violations(braking, _braking_from(18.0, -8.0, EMERGENCY_JERK, 4.0)) == []


def test_a_trajectory_starts_along_the_moving_egos_yaw() -> None:
    """Nothing turns on the spot at speed: a trajectory whose first heading is 0.3 rad off a moving ego's
    yaw does not start at the ego (a held offset along the reference from a yawed ego did, unchecked); a
    standing ego may set off in any direction (a robot turning in place), and 0.01 rad is within the
    tolerance."""
    problem = _problem(STRAIGHT, CLEAN)
    yawed = replace(problem, ego=replace(problem.ego, heading=0.3))
    assert {v.kind for v in trajectory_violations(STRAIGHT, yawed, CLEAN, [])} == {ViolationKind.START}
    nearly = replace(problem, ego=replace(problem.ego, heading=0.01))
    assert trajectory_violations(STRAIGHT, nearly, CLEAN, []) == []
    setting_off = _along(STRAIGHT, speed=0.0)
    standing = _problem(STRAIGHT, setting_off)
    turned = replace(standing, ego=replace(standing.ego, heading=0.3, speed=0.0))
    assert trajectory_violations(STRAIGHT, turned, setting_off, []) == []


def test_a_car_whose_steering_rate_is_bounded_starts_at_its_measured_steering_angle() -> None:
    """A moving car measured steering (curvature 0.05 1/m: 0.134 rad at its 2.7 m wheelbase) is not at
    another steering angle at once when its steering rate is bounded: a trajectory that starts straight
    does not start at the ego (a fallback braking straight on did, unchecked). 0.004 rad is within the
    tolerance; a car that may steer at once, the point model and an ego without a measured curvature
    are not checked."""
    car = _problem(STRAIGHT, CLEAN, **CAR, max_steering_rate=0.4)
    steering = replace(car, ego=replace(car.ego, curvature=0.05))
    assert {v.kind for v in trajectory_violations(STRAIGHT, steering, CLEAN, [])} == {ViolationKind.START}
    nearly = replace(car, ego=replace(car.ego, curvature=0.0015))
    assert trajectory_violations(STRAIGHT, nearly, CLEAN, []) == []
    assert trajectory_violations(STRAIGHT, car, CLEAN, []) == []
    at_once = replace(steering, vehicle=replace(steering.vehicle, max_steering_rate=None))
    assert trajectory_violations(STRAIGHT, at_once, CLEAN, []) == []
    point = _problem(STRAIGHT, CLEAN)
    turning = replace(point, ego=replace(point.ego, curvature=0.05))
    assert trajectory_violations(STRAIGHT, turning, CLEAN, []) == []


@pytest.mark.parametrize(
    ("yaw", "turn", "leaves"), [(0.5, -0.15, False), (0.6, -0.15, True), (0.7, -0.2, True)]
)
def test_a_vehicle_outside_its_lane_may_stay_out_while_it_returns_but_never_leaves_the_road(
    yaw: float, turn: float, leaves: bool
) -> None:
    """An ego 3.1 m left of a lane ±1.75 m, in a road reaching 5.25 m left, yawed ``yaw`` [rad] towards
    its edge, turning back at curvature ``turn`` [1/m] over 5 m: its footprint's front swings out before
    it comes back. The start allowance lets it stay out of the lane that far; the road's edge is still
    checked, with or without a borrow (the answer that kept the lane from such a start left the road)."""
    sigma = np.linspace(0.0, 5.0, 21)
    heading = yaw + turn * sigma
    mid = 0.5 * (heading[1:] + heading[:-1])
    x = 10.0 + np.concatenate(([0.0], np.cumsum(np.cos(mid) * np.diff(sigma))))
    y = 3.1 + np.concatenate(([0.0], np.cumsum(np.sin(mid) * np.diff(sigma))))
    back = _from_frenet(STRAIGHT, x, y)  # along the x axis: (s, d) = (x, y)
    problem = replace(_problem(STRAIGHT, back), lane=Lane(1.75, 1.75), road=Road(5.25, 1.75))
    for borrowing in (False, True):
        kinds = {v.kind for v in trajectory_violations(STRAIGHT, problem, back, [], borrowing=borrowing)}
        assert kinds == ({ViolationKind.ROAD} if leaves else set())
    # without a road, the lane's start allowance lets it through
    assert trajectory_violations(STRAIGHT, replace(problem, road=None), back, []) == []


def test_a_footprint_that_starts_outside_its_lane_may_stay_out_only_while_it_returns() -> None:
    """Inside at the start: what the first pose reaches out is allowed within one vehicle length, as
    before. Outside by 1.2 m: within the return length (a smootherstep move at half the curvature the
    vehicle can drive at its speed, longer the faster and the farther out) the overshoot and the swing
    of its rear as it turns back; nothing beyond."""
    traj = _along(STRAIGHT)
    inside = _problem(STRAIGHT, traj, length=4.5)
    distance = np.array([0.0, 4.4, 4.6, 50.0])
    np.testing.assert_allclose(start_allowance(inside, 0.0, distance), 0.0)
    np.testing.assert_allclose(start_allowance(inside, 1e-3, distance), [1e-3, 1e-3, 0.0, 0.0])  # as before
    standing = replace(inside, ego=replace(inside.ego, speed=0.0))
    move, curvature = 1.2 + inside.options.lateral_margin, standing.vehicle.curvature_limit
    assert return_length(standing, 1.2) == pytest.approx(np.sqrt(10 / np.sqrt(3) * move / (0.5 * curvature)))
    far = replace(inside, ego=replace(inside.ego, speed=10.0))
    assert return_length(inside, 0.0) >= 4.5 and return_length(far, 1.2) > return_length(inside, 1.2)
    assert return_length(inside, 3.0) > return_length(inside, 1.2)
    length = return_length(inside, 1.2)
    allowed = start_allowance(inside, 1.2, np.array([0.0, 0.5 * length, 0.99 * length, 1.01 * length]))
    assert allowed[0] == allowed[1] == allowed[2] > 1.2 and allowed[3] == 0.0
    assert allowed[0] - 1.2 < 0.5 * inside.vehicle.length  # the swing: less than the rear half turned across
    np.testing.assert_allclose(still_out(np.array([0.0, 0.5, 1.0, 2.0]), 1.0), [1.0, 0.5, 0.0, 0.0])
