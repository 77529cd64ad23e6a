"""Checks of paths and trajectories: the properties Algorithm 5 guarantees and Algorithm 4 breaks, and
every check a returned trajectory must pass, as typed :class:`Violation` records.

A violation's message (:attr:`Violation.message`) is rendered from the record; decisions (the fallback's
ranking) read its ``kind`` and ``obstacle_id``, never the text.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from numpy.typing import ArrayLike, NDArray
from shapely import LineString
from shapely.geometry.base import BaseGeometry

from planner.collision import outline_points
from planner.config import DEFAULT_CONFIG
from planner.frenet import to_cartesian, to_frenet
from planner.kinematics import lateral_acceleration, planned_point, steering_angle
from planner.problem import DynamicObstacle, Lane, PlanningProblem, Vehicle
from planner.reference import FloatArray, ReferenceLine
from planner.swept import moving_contacts, static_contacts
from planner.trajectory import Trajectory


def backward_steps(ref: ReferenceLine, xy: ArrayLike) -> int:
    """Number of consecutive points of a path whose TransF-κ ``s`` does not increase."""
    pts = np.asarray(xy, dtype=float)
    if pts.shape[0] < 2:
        return 0
    s = to_frenet(ref, pts).s
    return int(np.count_nonzero(np.diff(s) <= 0.0))


def self_intersects(xy: ArrayLike) -> bool:
    """Whether the polyline through the points crosses or overlaps itself."""
    pts = np.asarray(xy, dtype=float)
    if pts.shape[0] < 3:
        return False
    return not LineString(pts).is_simple


def folds_back(ref: ReferenceLine, xy: ArrayLike) -> bool:
    """Whether a path runs backwards along the reference or crosses itself."""
    return backward_steps(ref, xy) > 0 or self_intersects(xy)


#: the jerk [m/s³] at which the speed check lets a vehicle that starts faster than ``max_speed`` reach
#: full braking (:func:`fastest_braking`): the emergency jerk the fallback's braking profile uses
EMERGENCY_JERK = DEFAULT_CONFIG.speed.emergency_jerk
#: a vehicle that starts with its footprint outside its lane returns into it within this share of the
#: curvature it can drive at its speed (:func:`return_length`)
RETURN_SHARE = 0.5
#: tolerances of the trajectory checks
_GEOMETRY_TOL = 1e-3  # [m]
_RATE_TOL = 1e-3  # relative, on limits
#: the first point may be this far from the ego [m] ...
_START_TOL = 0.05
#: ... and, while the ego moves, its heading this far from the ego's yaw [rad] (nothing turns on the
#: spot at speed; the plans' own first headings are within 2e-3 of it) and, for a car whose steering rate
#: is bounded and whose curvature is measured, its steering angle this far from the measured one [rad]
#: (the plans' own are within 5e-3 of it)
_START_HEADING_TOL = _START_STEERING_TOL = 0.02
#: a point moves when its speed exceeds this [m/s]
_MOVING = 0.05
#: absolute tolerances on the curvature [1/m], lateral acceleration and acceleration [m/s²]
_CURVATURE_TOL, _LATERAL_TOL, _ACCELERATION_TOL = 1e-4, 1e-3, 1e-3
#: a step may differ from the mean speed × dt by this [m] and this share of it
_STEP_ABS_TOL, _STEP_REL_TOL = 0.05, 0.05
#: ``s`` may fall back by this [m] (rounding)
_S_TOL = 1e-6
#: steps shorter than this [m] are left out of the self-intersection check (a standstill)
_STANDSTILL_STEP = 1e-3
#: a point's (x, y) may be this far from the position of its reported (s, d) [m]
_FRENET_TOL = 0.1
#: a step's heading change may differ from its length × the mean reported curvature by this [rad],
#: plus this share of the change
_TURN_ABS_TOL, _TURN_REL_TOL = 0.05, 0.1
#: speed above ``max_speed`` tolerated, relative and absolute [m/s]
_SPEED_REL_TOL, _SPEED_ABS_TOL = 1e-3, 0.05


class ViolationKind(StrEnum):
    """Which check a trajectory breaks."""

    #: the first point is not at the ego
    START = "start"
    #: ``1 − κ·d ≤ 0`` somewhere (the offset is past the reference's centre of curvature)
    KAPPA_D = "kappa_d"
    #: ``|curvature| > max_curvature`` while moving
    CURVATURE = "curvature"
    #: ``v²·|curvature| > max_lateral_acceleration``
    LATERAL_ACCELERATION = "lateral_acceleration"
    #: acceleration outside ``[−max_deceleration, max_acceleration]``
    ACCELERATION = "acceleration"
    #: consecutive positions inconsistent with ``v·dt``
    STEP = "step"
    #: ``s`` decreases, or does not increase while moving
    S_DECREASES = "s_decreases"
    #: the path crosses or overlaps itself
    SELF_INTERSECTS = "self_intersects"
    #: the footprint leaves the lane (not checked while the plan borrows the road beyond it)
    LANE = "lane"
    #: the footprint leaves the road (``PlanningProblem.road``) while the plan borrows it
    ROAD = "road"
    #: the footprint meets a static obstacle
    HITS_OBSTACLE = "hits_obstacle"
    #: the footprint meets a moving obstacle at its predicted pose at the same time
    HITS_MOVING_OBSTACLE = "hits_moving_obstacle"
    #: a point's (x, y) is not the position of its reported (s, d)
    FRENET = "frenet"
    #: the heading is off the direction of motion
    HEADING = "heading"
    #: the reported curvature disagrees with the heading's change along the trajectory
    TURN = "turn"
    #: faster than ``max_speed`` (beyond an ego already faster, braking from it)
    SPEED = "speed"
    #: the vehicle's front passes the reference line's end (beyond where it started)
    ROAD_END = "road_end"
    #: a car's rear axle does not move along the body's yaw (:func:`car_violations`)
    REAR_AXLE_SLIPS = "rear_axle_slips"
    #: a car's ``|steering_angle|`` above its ``max_steering_angle``
    STEERING_ANGLE = "steering_angle"
    #: a car's steering rate ``|dδ/dt|`` above its ``max_steering_rate``
    STEERING_RATE = "steering_rate"


#: the kinds that are collisions; the others break a limit without hitting anything by themselves
HITS = frozenset({ViolationKind.HITS_OBSTACLE, ViolationKind.HITS_MOVING_OBSTACLE})
#: the kinds whose numbers disagree with each other or with a motion along the road: such a trajectory
#: is no motion at all (not a drivable one, nor one that stays on the reference's side of its curves)
CONSISTENCY = frozenset(
    {
        ViolationKind.START,
        ViolationKind.KAPPA_D,
        ViolationKind.STEP,
        ViolationKind.S_DECREASES,
        ViolationKind.SELF_INTERSECTS,
        ViolationKind.FRENET,
        ViolationKind.HEADING,
        ViolationKind.TURN,
        ViolationKind.REAR_AXLE_SLIPS,
    }
)
#: the kinds that break the vehicle's own limits: a trajectory with one cannot be driven as planned
LIMITS = frozenset(
    {
        ViolationKind.CURVATURE,
        ViolationKind.LATERAL_ACCELERATION,
        ViolationKind.ACCELERATION,
        ViolationKind.SPEED,
        ViolationKind.STEERING_ANGLE,
        ViolationKind.STEERING_RATE,
    }
)


@dataclass(frozen=True)
class Violation:
    """One broken check of a trajectory.

    Attributes:
        kind: which check.
        obstacle_id: the obstacle hit (the two ``HITS_*`` kinds), else None.
        t: the first time it happens [s], None where a time means nothing (self-intersection).
        value: the worst value where the message states one (``CURVATURE`` [1/m],
            ``LATERAL_ACCELERATION`` [m/s²], ``SPEED`` [m/s], ``REAR_AXLE_SLIPS``, ``STEERING_ANGLE`` [rad],
            ``STEERING_RATE`` [rad/s]), else None.
    """

    kind: ViolationKind
    obstacle_id: str | None = None
    t: float | None = None
    value: float | None = None

    @property
    def message(self) -> str:
        """The check in words, as answers report it."""
        template = _TEMPLATES.get(self.kind)
        if template is None:
            return _MESSAGES[self.kind]
        return template.format(value=self.value, obstacle_id=self.obstacle_id)

    def __str__(self) -> str:
        return self.message


#: the messages of the kinds that state a value or an obstacle
_TEMPLATES = {
    ViolationKind.CURVATURE: "curvature {value:.3f} 1/m above max_curvature",
    ViolationKind.LATERAL_ACCELERATION: "lateral acceleration {value:.2f} m/s² above the limit",
    ViolationKind.SPEED: "speed {value:.2f} m/s above max_speed",
    ViolationKind.HITS_OBSTACLE: "footprint hits obstacle {obstacle_id}",
    ViolationKind.HITS_MOVING_OBSTACLE: "footprint hits moving obstacle {obstacle_id}",
    ViolationKind.REAR_AXLE_SLIPS: "the rear axle moves {value:.3f} rad off the body's yaw",
    ViolationKind.STEERING_ANGLE: "steering angle {value:.3f} rad above max_steering_angle",
    ViolationKind.STEERING_RATE: "steering rate {value:.3f} rad/s above max_steering_rate",
}
#: the messages of the others
_MESSAGES = {
    ViolationKind.START: "does not start at the ego",
    ViolationKind.KAPPA_D: "1 − κ·d ≤ 0 at some point",
    ViolationKind.ACCELERATION: "acceleration outside the limits",
    ViolationKind.STEP: "positions inconsistent with v·dt",
    ViolationKind.S_DECREASES: "s does not increase while moving",
    ViolationKind.SELF_INTERSECTS: "self-intersects",
    ViolationKind.LANE: "footprint leaves the lane",
    ViolationKind.ROAD: "footprint leaves the road",
    ViolationKind.FRENET: "positions inconsistent with the reported (s, d)",
    ViolationKind.HEADING: "heading off the direction of motion",
    ViolationKind.TURN: "curvature inconsistent with the heading's change",
    ViolationKind.ROAD_END: "the front passes the end of the reference line",
}


def _first(t: FloatArray, where: NDArray[np.bool_]) -> float:
    """The first time [s] of ``t`` at which ``where`` holds (``where`` holds somewhere)."""
    return float(t[int(np.argmax(where))])


def _side_excess(
    ref: ReferenceLine,
    problem: PlanningProblem,
    x: FloatArray,
    y: FloatArray,
    heading: FloatArray,
    surface: Lane | None,
) -> tuple[FloatArray, FloatArray]:
    """Per pose and point of the footprint's outline (its corners and points along its sides,
    :func:`planner.collision.outline_points`, shape (N, 10)), how far [m] the point is beyond the lane's
    right edge and beyond its left edge (``surface``, default the problem's lane), by TransF-κ; negative
    inside."""
    vehicle = problem.vehicle
    outline = outline_points(x, y, heading, vehicle.length, vehicle.width)
    fr = to_frenet(ref, outline.reshape(-1, 2))
    left, right = (problem.lane if surface is None else surface).widths(ref, fr.s)
    shape = outline.shape[:-1]
    return (-right - fr.d).reshape(shape), (fr.d - left).reshape(shape)


def _lane_excess(
    ref: ReferenceLine,
    problem: PlanningProblem,
    x: FloatArray,
    y: FloatArray,
    heading: FloatArray,
    surface: Lane | None,
) -> FloatArray:
    """Per pose and point of the footprint's outline (shape (N, 10)), how far [m] the point is outside the
    lane (:func:`_side_excess`, the farther side); negative inside."""
    right, left = _side_excess(ref, problem, x, y, heading, surface)
    return np.maximum(left, right)


def outside_lane(
    ref: ReferenceLine,
    problem: PlanningProblem,
    x: FloatArray,
    y: FloatArray,
    heading: FloatArray,
    surface: Lane | None = None,
) -> NDArray[np.bool_]:
    """Per pose (the footprint's centre ``(x, y)`` [m], yaw ``heading`` [rad]), whether a corner of the
    footprint (or a point along a side, :func:`_lane_excess`) is outside the lane (``surface``, default
    the problem's lane) beyond :data:`_GEOMETRY_TOL`, the first pose included (unlike :func:`leaves_lane`)."""
    return np.asarray(np.any(_lane_excess(ref, problem, x, y, heading, surface) > _GEOMETRY_TOL, axis=1))


def leaves_lane(
    ref: ReferenceLine,
    problem: PlanningProblem,
    x: FloatArray,
    y: FloatArray,
    heading: FloatArray,
    surface: Lane | None = None,
) -> NDArray[np.bool_]:
    """Per pose (the footprint's centre ``(x, y)`` [m], yaw ``heading`` [rad]), whether a corner of the
    footprint or a point along a side (:func:`_lane_excess`) is outside the lane (``surface``, default the
    problem's lane: the road when it borrows) (by TransF-κ, beyond :data:`_GEOMETRY_TOL`). The first pose
    is a measurement: what it reaches out is allowed near the start as :func:`start_allowance` says (a
    vehicle partly outside may stay out by that, and the swing of turning back, while it returns)."""
    outside = _lane_excess(ref, problem, x, y, heading, surface)
    distance = np.hypot(x - x[0], y - y[0])
    allowance = start_allowance(problem, float(outside[0].max()), distance)[:, None]
    return np.asarray(np.any(outside - allowance > _GEOMETRY_TOL, axis=1))


def start_overshoot(ref: ReferenceLine, problem: PlanningProblem, surface: Lane | None = None) -> float:
    """How far [m] the ego's footprint reaches outside the lane (``surface``, default the problem's lane)
    at the start, by TransF-κ; 0 inside or within the checks' tolerance of the edge."""
    ego = problem.ego
    pose = (np.array([ego.x]), np.array([ego.y]), np.array([ego.heading]))
    excess = float(_lane_excess(ref, problem, *pose, surface).max())
    return excess if excess > _GEOMETRY_TOL else 0.0


def return_length(problem: PlanningProblem, overshoot: float) -> float:
    """How far [m] a vehicle whose footprint starts ``overshoot`` [m] outside its lane may drive before it
    is back inside: the length ``L`` of a :func:`still_out` move sideways by the overshoot and the lane
    margin it plans to keep (``options.lateral_margin``) whose largest second derivative,
    ``(10/√3)·move/L²``, is :data:`RETURN_SHARE` of the curvature the vehicle can drive at its speed (its
    curvature limit, and ``max_lateral_acceleration / v²``); at least one vehicle length."""
    vehicle = problem.vehicle
    speed_sq = max(problem.ego.speed, 0.0) ** 2
    drivable = min(vehicle.curvature_limit, vehicle.max_lateral_acceleration / max(speed_sq, 1e-9))
    move = _return_move(problem, overshoot)
    return max(vehicle.length, math.sqrt(10.0 / math.sqrt(3.0) * move / (RETURN_SHARE * drivable)))


def _return_move(problem: PlanningProblem, overshoot: float) -> float:
    """How far [m] a return moves the footprint sideways: the start's ``overshoot`` [m] and the lane
    margin it plans to keep."""
    return max(overshoot, 0.0) + problem.options.lateral_margin


def still_out(distance: FloatArray, length: float) -> FloatArray:
    """The share of a start's overshoot left at ``distance`` [m] of a return over ``length`` [m]: one
    minus the smootherstep ``x³(10 − 15x + 6x²)`` of ``x = distance / length`` (no slope or curvature
    sideways at either end: a vehicle driving straight can start on it and end on it)."""
    x = np.clip(distance / length, 0.0, 1.0)
    return np.asarray(1.0 - x**3 * (10.0 - 15.0 * x + 6.0 * x * x))


def start_allowance(problem: PlanningProblem, overshoot: float, distance: FloatArray) -> FloatArray:
    """How far [m] the footprint may reach outside its lane at ``distance`` [m] from the start when it
    starts ``overshoot`` [m] outside: within :func:`return_length` (at least one vehicle length), the
    overshoot and what turning back towards the lane swings the footprint's rear out (its rear extent
    times the sine of one and a half times the return's steepest heading, ``atan(15/8 · move / L)``); 0
    beyond. A start inside the lane (within the checks' tolerance) allows what it reaches out within one
    vehicle length."""
    vehicle = problem.vehicle
    if overshoot <= _GEOMETRY_TOL:
        return np.where(distance < vehicle.length, max(overshoot, 0.0), 0.0)
    length = return_length(problem, overshoot)
    steepest = math.atan(15.0 / 8.0 * _return_move(problem, overshoot) / length)
    swing = vehicle.rear_extent * math.sin(min(1.5 * steepest, 0.5 * math.pi))
    return np.where(distance < length, overshoot + swing, 0.0)


def lane_overshoot(
    ref: ReferenceLine,
    problem: PlanningProblem,
    x: FloatArray,
    y: FloatArray,
    heading: FloatArray,
    surface: Lane | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Per pose (the footprint's centre ``(x, y)`` [m], yaw ``heading`` [rad]), how far [m] the footprint
    reaches beyond the lane's right edge and beyond its left edge (by TransF-κ), as :func:`leaves_lane`
    judges it: less what the first pose already reaches out as :func:`start_allowance` lets it, and 0
    where within the checks' tolerance; a pose leaves the lane exactly where one of the two is positive."""
    right_points, left_points = _side_excess(ref, problem, x, y, heading, surface)
    right, left = right_points.max(axis=1), left_points.max(axis=1)
    distance = np.hypot(x - x[0], y - y[0])
    allowance = start_allowance(problem, max(float(right[0]), float(left[0])), distance)
    right, left = right - allowance, left - allowance
    return np.where(right > _GEOMETRY_TOL, right, 0.0), np.where(left > _GEOMETRY_TOL, left, 0.0)


def trajectory_violations(
    ref: ReferenceLine,
    problem: PlanningProblem,
    traj: Trajectory,
    static: list[tuple[str, BaseGeometry]],
    *,
    borrowing: bool = False,
) -> list[Violation]:
    """Every check a returned trajectory must pass, in this order; an empty list when it passes them all.

    Starts at the ego (its position, and while it moves its yaw and, for a car whose steering rate is
    bounded, its measured steering angle); ``1 − κ·d > 0``; ``|curvature| ≤ max_curvature`` (a car's
    :attr:`~planner.problem.Vehicle.curvature_limit`) while moving and the body's lateral acceleration
    (:func:`planner.kinematics.lateral_acceleration`, ``v²·|curvature|`` for the point model) at most
    ``max_lateral_acceleration``; acceleration within the limits; consecutive positions of the
    planned point (the centre, a car's rear axle) consistent with ``v·dt``; ``s`` never decreasing and
    strictly increasing while moving; no self-intersection; footprint inside the lane, or inside the road when
    ``borrowing`` (the lane decision borrows the road beyond it: :mod:`planner.decision`; the lane lies in the
    road, so the footprint is in the road always) (all four corners by TransF-κ; no further out than the
    measured start where that is already partly outside, and then inside the road as well) and clear of every
    static obstacle and of every moving one at its predicted pose at the same time — in continuous time,
    between the samples too (:mod:`planner.swept`: the pose moves linearly between samples, as the predictions
    do); for a car, its kinematics (:func:`car_violations`).
    And the numbers agree with each other (:func:`consistency_violations`), the speed keeps ``max_speed``
    (:func:`speed_violations`) and the front stays before the reference line's end.
    """
    vehicle, ego, t = problem.vehicle, problem.ego, traj.t
    kind = ViolationKind
    out: list[Violation] = []
    turned = abs(math.remainder(float(traj.heading[0]) - ego.heading, 2.0 * math.pi))
    if np.hypot(traj.x[0] - ego.x, traj.y[0] - ego.y) > _START_TOL or (
        ego.speed > _MOVING and (turned > _START_HEADING_TOL or _steered_at_start(problem, traj))
    ):
        out.append(Violation(kind.START, t=float(t[0])))
    moving = traj.v > _MOVING
    kappa = ref.kappa_at(traj.s)
    folded = 1.0 - kappa * traj.d <= 0.0
    if np.any(folded):
        out.append(Violation(kind.KAPPA_D, t=_first(t, folded)))
    curv = np.abs(traj.curvature)
    sharp = moving & (curv > vehicle.curvature_limit * (1 + _RATE_TOL) + _CURVATURE_TOL)
    if np.any(sharp):
        out.append(Violation(kind.CURVATURE, t=_first(t, sharp), value=float(curv[moving].max())))
    lat = lateral_acceleration(traj.v, curv, vehicle)
    sliding = lat > vehicle.max_lateral_acceleration * (1 + _RATE_TOL) + _LATERAL_TOL
    if np.any(sliding):
        out.append(Violation(kind.LATERAL_ACCELERATION, t=_first(t, sliding), value=float(lat.max())))
    outside_limits = (traj.a > vehicle.max_acceleration + _ACCELERATION_TOL) | (
        traj.a < -vehicle.max_deceleration - _ACCELERATION_TOL
    )
    if np.any(outside_limits):
        out.append(Violation(kind.ACCELERATION, t=_first(t, outside_limits)))
    dt = np.diff(t)
    px, py = planned_point(traj.x, traj.y, traj.heading, vehicle)
    step = np.hypot(np.diff(px), np.diff(py))
    # a step of arc length v·dt turning monotonically by Δθ ≤ π has a chord in [v·dt·cos(Δθ/2), v·dt]
    arc = 0.5 * (traj.v[:-1] + traj.v[1:]) * dt
    shortest = arc * np.cos(0.5 * np.minimum(np.abs(np.diff(traj.heading)), np.pi))
    inconsistent = np.maximum(step - arc, shortest - step) > _STEP_ABS_TOL + _STEP_REL_TOL * arc
    if np.any(inconsistent):
        out.append(Violation(kind.STEP, t=_first(t, inconsistent)))
    ds = np.diff(traj.s)
    backwards = (ds < -_S_TOL) | ((ds <= 0) & moving[:-1] & moving[1:])
    if np.any(backwards):
        out.append(Violation(kind.S_DECREASES, t=_first(t, backwards)))
    travelled = np.concatenate(([True], step > _STANDSTILL_STEP))
    if self_intersects(np.column_stack((traj.x, traj.y))[travelled]):
        out.append(Violation(kind.SELF_INTERSECTS))
    # the lane lies inside the road: while the lane is checked from a start inside it, the road's check
    # would only repeat it
    surfaces: list[tuple[ViolationKind, Lane]] = [(kind.LANE, problem.lane)]
    if borrowing:
        surfaces = [] if problem.road is None else [(kind.ROAD, problem.road)]
    elif problem.road is not None and start_overshoot(ref, problem) > 0.0:
        # a vehicle that starts outside its lane may stay out while it returns (start_allowance), as
        # far as its overshoot and the swing of turning back: the road's edge still bounds it
        surfaces.append((kind.ROAD, problem.road))
    for surface_kind, surface in surfaces:
        off = leaves_lane(ref, problem, traj.x, traj.y, traj.heading, surface)
        if np.any(off):
            out.append(Violation(surface_kind, t=_first(t, off)))
    # past the reference's end the road is not known: the front (by the reported s) no further past it
    # than at the start
    beyond = traj.s + 0.5 * vehicle.length - ref.length
    past_end = beyond > max(float(beyond[0]), 0.0) + _GEOMETRY_TOL
    if np.any(past_end):
        out.append(Violation(kind.ROAD_END, t=_first(t, past_end)))
    out += consistency_violations(ref, vehicle, traj) + speed_violations(problem, traj)
    # in continuous time: the footprint between the samples too (planner.swept)
    for contact in static_contacts(traj, vehicle, static):
        out.append(Violation(kind.HITS_OBSTACLE, obstacle_id=contact.obstacle_id, t=contact.t))
    static_ids = {ob_id for ob_id, _ in static}
    movers = [ob for ob in problem.obstacles if isinstance(ob, DynamicObstacle) and ob.id not in static_ids]
    for contact in moving_contacts(traj, vehicle, movers):
        out.append(Violation(kind.HITS_MOVING_OBSTACLE, obstacle_id=contact.obstacle_id, t=contact.t))
    if vehicle.is_car:
        out += car_violations(vehicle, traj)
    return out


def _steered_at_start(problem: PlanningProblem, traj: Trajectory) -> bool:
    """Whether ``traj`` starts at another steering angle than the ego's measured one (its curvature),
    for a car whose steering rate is bounded: it cannot be at another one at once."""
    vehicle, measured = problem.vehicle, problem.ego.curvature
    if not vehicle.is_car or vehicle.max_steering_rate is None or measured is None:
        return False
    first = steering_angle(np.array([traj.curvature[0], measured]), vehicle)
    return bool(abs(first[0] - first[1]) > _START_STEERING_TOL)


#: a car's rear axle may move this far off its yaw [rad]: far below the slip of its centre in a turn
#: (``atan(l_r κ)``, 10–20° for a car's), above the chord-vs-heading error of a path sampled between
#: knots half a metre apart (``κΔ/2``, 4° at 0.3 1/m)
_SLIP_TOL = 0.1
#: steps shorter than this [m] carry no usable direction
_DIRECTION_STEP = 0.01
#: absolute tolerances on a car's steering angle [rad] and rate [rad/s]
_STEERING_TOL, _STEERING_RATE_TOL = 1e-4, 1e-3


def car_violations(vehicle: Vehicle, traj: Trajectory) -> list[Violation]:
    """A car's steering along ``traj`` (its points the footprint's centre, ``heading`` the body's yaw,
    ``curvature`` the rear axle's path's, ``steering_angle`` δ): ``|δ| ≤ max_steering_angle``;
    ``|Δδ/Δt| ≤ max_steering_rate`` between consecutive points (when given). In this order; [] for the
    point model. That the rear axle does not slip is :func:`consistency_violations`' heading check."""
    if not vehicle.is_car:
        return []
    kind, t = ViolationKind, traj.t
    out: list[Violation] = []
    delta = traj.steering_angle
    if delta is None:
        delta = steering_angle(traj.curvature, vehicle)
    limit = vehicle.steering_limit
    if limit is not None:
        beyond = np.abs(delta) > limit * (1 + _RATE_TOL) + _STEERING_TOL
        if np.any(beyond):
            worst = float(np.abs(delta).max())
            out.append(Violation(kind.STEERING_ANGLE, t=_first(t, beyond), value=worst))
    rate_limit = vehicle.max_steering_rate
    if rate_limit is not None and t.shape[0] > 1:
        rate = np.abs(np.diff(delta)) / np.maximum(np.diff(t), 1e-12)
        fast = rate > rate_limit * (1 + _RATE_TOL) + _STEERING_RATE_TOL
        if np.any(fast):
            out.append(Violation(kind.STEERING_RATE, t=_first(t, fast), value=float(rate.max())))
    return out


def consistency_violations(ref: ReferenceLine, vehicle: Vehicle, traj: Trajectory) -> list[Violation]:
    """Whether the trajectory's numbers agree with each other: each point's ``(x, y)`` is the position of
    its ``(s, d)`` (TransF-κ's inverse); over each step of the planned point (the centre, a car's rear
    axle) longer than :data:`_DIRECTION_STEP`, the chord's direction is the heading at the step's middle
    (for a car: its rear axle does not slip, ``REAR_AXLE_SLIPS``) and the heading's change is the step's
    length times the mean reported curvature (both within their tolerances)."""
    kind, t = ViolationKind, traj.t
    out: list[Violation] = []
    xy = to_cartesian(ref, traj.s, traj.d)
    apart = np.hypot(xy[:, 0] - traj.x, xy[:, 1] - traj.y) > _FRENET_TOL
    if np.any(apart):
        out.append(Violation(kind.FRENET, t=_first(t, apart)))
    px, py = planned_point(traj.x, traj.y, traj.heading, vehicle)
    dx, dy = np.diff(px), np.diff(py)
    step = np.hypot(dx, dy)
    moves = step > _DIRECTION_STEP
    turn = np.diff(traj.heading)  # continuous, not wrapped
    chord = traj.heading[:-1] + 0.5 * turn
    off = np.abs(np.angle(np.exp(1j * (np.arctan2(dy, dx) - chord))))
    skewed = moves & (off > _SLIP_TOL)
    if np.any(skewed):
        if vehicle.is_car:
            out.append(Violation(kind.REAR_AXLE_SLIPS, t=_first(t, skewed), value=float(off[skewed].max())))
        else:
            out.append(Violation(kind.HEADING, t=_first(t, skewed)))
    expected = 0.5 * (traj.curvature[:-1] + traj.curvature[1:]) * step
    bent = moves & (np.abs(turn - expected) > _TURN_ABS_TOL + _TURN_REL_TOL * np.abs(turn))
    if np.any(bent):
        out.append(Violation(kind.TURN, t=_first(t, bent)))
    return out


def speed_violations(problem: PlanningProblem, traj: Trajectory) -> list[Violation]:
    """Faster than ``max_speed`` [m/s] where an ego that starts faster could have braked below the
    speed: the allowance falls from the ego's speed at half ``max_deceleration`` (the jerk-limited
    ramp to full braking takes a while), never faster than :func:`fastest_braking` can (an ego measured
    braking lightly needs the ramp first), and never above the ego's speed (an ego measured speeding up
    cannot keep it: its answer breaks the limit, a braking fallback)."""
    vehicle, ego = problem.vehicle, problem.ego
    braking = np.maximum(
        ego.speed - 0.5 * vehicle.max_deceleration * traj.t,
        np.minimum(fastest_braking(problem, traj.t), ego.speed),
    )
    allowed = np.maximum(vehicle.max_speed, braking) * (1 + _SPEED_REL_TOL) + _SPEED_ABS_TOL
    fast = traj.v > allowed
    if not np.any(fast):
        return []
    return [Violation(ViolationKind.SPEED, t=_first(traj.t, fast), value=float(traj.v.max()))]


def fastest_braking(problem: PlanningProblem, t: FloatArray, jerk: float = EMERGENCY_JERK) -> FloatArray:
    """The speed [m/s] at times ``t`` [s] of braking at once: the ego's measured acceleration [m/s²]
    falls at ``jerk`` [m/s³] to ``−max_deceleration`` and stays there (the speed no lower than 0)."""
    a0, decel = problem.ego.acceleration, problem.vehicle.max_deceleration
    ramp = max((a0 + decel) / jerk, 0.0)  # [s] until full braking (none where the ego brakes harder)
    on_ramp = np.minimum(t, ramp)
    v = problem.ego.speed + a0 * on_ramp - 0.5 * jerk * on_ramp**2 - decel * np.maximum(t - ramp, 0.0)
    return np.maximum(v, 0.0)
