"""Closed-loop simulation: replan every ``replan_period`` from the vehicle's state, drive the plan's
first stretch with a kinematic bicycle model and a simple tracker, record everything, score the run.

Vehicle model — kinematic bicycle (kinematic single-track) with wheelbase ``ℓ``, the rear axle ``ℓ_r``
behind the footprint's centre ``(x, y)``, body yaw ``ψ`` [rad] and front-wheel steering angle ``δ``
[rad]. The rear axle does not slip; a point ``a`` ahead of it along the body (the centre: ``a = ℓ_r``)
moves at its slip angle ``β_a = atan(a/ℓ · tan δ)`` off the yaw. The model is referenced at the point
the planner plans (:attr:`BicycleModel.at_rear_axle`): ``speed`` ``v`` [m/s], path ``curvature`` ``κ``
[1/m] and ``course`` ``χ = ψ + β`` [rad] are that point's::

    ẋ_p = v cos(ψ + β),  ẏ_p = v sin(ψ + β),  ψ̇ = v tan δ cos β / ℓ,  v̇ = a  (v ≥ 0)

At constant ``δ`` the point runs on a circle of curvature ``κ = tan δ cos β / ℓ``; its course is what
the planner calls the heading. The footprint, ``length × width`` centred at ``(x, y)``, is turned by the
body yaw ``ψ``; the simulator scores collisions with that footprint.

* A car (a :class:`~planner.problem.Vehicle` with a ``wheelbase``; :meth:`BicycleModel.for_vehicle`):
  the vehicle's own wheelbase, rear axle and steering limits, referenced at the rear axle (β = 0,
  ``κ = tan δ / ℓ``, the course is the yaw): CommonRoad's kinematic single-track model, driven from
  the answer's pose (the rear axle ``ℓ_r`` behind each trajectory point along its heading, the body's
  yaw).
* The point model (no wheelbase): by default ``ℓ_r = 0``, the vehicle the planner's contract
  describes, whose footprint is centred on the trajectory point and turned with the path (β = 0; a
  differential-drive robot). With ``centre_midway=True`` (``--centre-midway`` on the command line) it
  is a car referenced midway between its axles but planned as a point: in a turn its body is yawed by
  ``β`` against the path (≈ 11° at κ = 0.14 1/m for a 4.5 m car), which the point model's footprint does
  not model — its outer front corner swings out by about ``(length/2)·sin β``.

Inputs are held for a sub-step of ``h = replan_period / substeps`` (zero-order hold, 100 Hz by
default): the steering moves towards its command at most ``max_steering_rate·h``, then the motion
over ``h`` is integrated *exactly* — an arc of curvature ``κ(δ)`` and length ``v h + a h²/2`` (stopping
at ``v = 0``; the vehicle never reverses).

Tracker — feed-forward plus feedback, recomputed every sub-step:

* lateral: the centre is projected on the plan's path near where the plan is at this time; with the
  lateral error ``e`` [m] (left positive) and course error ``e_χ`` [rad] to the path there,
  ``κ_cmd = κ_plan − e/ℓ_d² − 2 sin(e_χ)/ℓ_d`` (for small errors ``e″ + (2/ℓ_d) e′ + e/ℓ_d² = 0`` along
  the path: critically damped over the preview distance ``ℓ_d = max(min_preview, preview_time·v)``);
* longitudinal: ``a_cmd = a_plan(τ) + k_v (v_plan(τ) − v) + k_s (σ_plan(τ) − σ)`` with ``σ`` the
  projection's arc length along the plan, clipped to the vehicle's limits.

The plan's path is followed, not re-created: the simulator's only knowledge of the road is what it
hands the planner. At sim time ``T`` the problem sent has the vehicle's state as ego and every
dynamic obstacle's prediction shifted by ``T`` (:func:`shift_obstacle`); static obstacles unchanged.
A plan that raises a :class:`~planner.errors.PlannerError` is a failure step: the vehicle brakes at
its full deceleration for that step. The run stops at the goal, at the first collision, or at
``duration``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any, Literal

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from planner.candidates import CandidateSet
from planner.collision import box_corners, footprints, obstacle_shape, outline_points, prediction_at
from planner.decision import Decision
from planner.errors import InvalidInputError, PlannerError
from planner.frenet import to_frenet
from planner.pipeline import plan
from planner.problem import DynamicObstacle, Ego, Obstacle, PlanningProblem, Vehicle
from planner.reference import FloatArray, ReferenceLine, build_reference
from planner.result import PlanResult
from planner.trajectory import Trajectory

StepStatus = Literal["ok", "stopped", "fallback", "error"]
Termination = Literal["goal", "collision", "timeout"]

#: a coordinate or an array of them
Coordinates = float | FloatArray
#: the default goal is the reference's end less this many vehicle lengths [-]
GOAL_MARGIN_LENGTHS = 1.0
#: default duration: this many times the time to drive the rest of the reference at the target speed…
DURATION_FACTOR = 2.0
#: … plus this [s]
DURATION_SLACK = 20.0
#: moving: the centre travelled more than this in a step [m]
MOVING = 1e-3
#: decreasing s: by more than this [m] (TransF-κ rounding)
S_TOLERANCE = 1e-6
#: the plan's path is searched for the projection this far either side of where the plan is now [m]
PROJECTION_WINDOW = 5.0


# --------------------------------------------------------------------------------------------------
# Vehicle model
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BicycleModel:
    """Kinematic bicycle referenced at the planned point (see the module docstring).

    Attributes:
        wheelbase: ``ℓ`` [m].
        rear_to_centre: ``ℓ_r``, rear axle to the footprint's centre [m]; with the model referenced at
            the centre, 0 puts it on the rear axle, so that the footprint turns with the path (the point
            model, β = 0).
        max_steering: largest ``|δ|`` [rad].
        max_steering_rate: largest ``|δ̇|`` [rad/s].
        substeps: sub-steps per replan period (inputs held over each).
        at_rear_axle: referenced at the rear axle (a car: speed, curvature and course are the rear
            axle's) rather than at the footprint's centre.
    """

    wheelbase: float
    rear_to_centre: float
    max_steering: float
    max_steering_rate: float = 0.7
    substeps: int = 10
    at_rear_axle: bool = False

    @classmethod
    def for_vehicle(cls, vehicle: Vehicle, *, centre_midway: bool = False, **overrides: Any) -> BicycleModel:
        """A car's own wheelbase, rear axle and steering limits (its steering rate: ``max_steering_rate``
        when it has one), referenced at the rear axle. The point model: wheelbase ``0.6·length``,
        steering limited to the vehicle's ``max_curvature``; the rear axle at the centre (no slip: the
        planner's vehicle), or midway between the axles with ``centre_midway``.

        Raises:
            InvalidInputError: ``centre_midway`` for a car (it is planned as the car it is).
        """
        if vehicle.wheelbase is not None:
            if centre_midway:
                raise InvalidInputError(
                    "a car is planned at its rear axle; centre_midway drives a point model as a car",
                    field="centre_midway",
                )
            limit = vehicle.steering_limit or 0.0  # a car has one
            car = cls(vehicle.wheelbase, vehicle.rear_offset, limit, at_rear_axle=True)
            if vehicle.max_steering_rate is not None:
                car = replace(car, max_steering_rate=vehicle.max_steering_rate)
            return replace(car, **overrides)
        wheelbase = 0.6 * vehicle.length
        rear = 0.5 * wheelbase if centre_midway else 0.0
        base = replace(cls(wheelbase=wheelbase, rear_to_centre=rear, max_steering=np.pi / 3), **overrides)
        limit = vehicle.max_curvature
        if base.ahead > 0.0:
            limit = min(limit, 0.999 / base.ahead)
        return replace(base, max_steering=base.steering_for(limit))

    @property
    def ahead(self) -> float:
        """How far the reference point lies ahead of the rear axle [m]."""
        return 0.0 if self.at_rear_axle else self.rear_to_centre

    @property
    def behind_centre(self) -> float:
        """How far the reference point lies behind the footprint's centre [m]."""
        return self.rear_to_centre if self.at_rear_axle else 0.0

    def slip_angle(self, steering: float) -> float:
        """``β`` [rad] of the reference point at steering ``δ`` [rad]."""
        return math.atan(self.ahead / self.wheelbase * math.tan(steering))

    def curvature(self, steering: float) -> float:
        """Path curvature of the reference point [1/m] at steering ``δ`` [rad]:
        ``tan δ · cos β / ℓ``."""
        return math.tan(steering) * math.cos(self.slip_angle(steering)) / self.wheelbase

    def steering_for(self, curvature: float) -> float:
        """The steering angle [rad] whose reference point's path has ``curvature`` [1/m]
        (``|κ a|`` clipped below 1): ``tan δ = κ ℓ / cos β`` with ``sin β = κ a``."""
        sin_beta = float(np.clip(curvature * self.ahead, -0.999, 0.999))
        return math.atan(curvature * self.wheelbase / math.sqrt(1.0 - sin_beta**2))

    def centre_speed_ratio(self, steering: FloatArray) -> FloatArray:
        """The footprint centre's speed over the reference point's at steering ``δ`` [rad]:
        ``cos β / cos β_c`` (every point of the body moves along it at the rear axle's speed), 1 for a
        model referenced at the centre."""
        tan = np.tan(steering)
        beta = np.arctan(self.ahead / self.wheelbase * tan)
        beta_c = np.arctan(self.rear_to_centre / self.wheelbase * tan)
        return np.asarray(np.cos(beta) / np.cos(beta_c))

    def reference_point(
        self, x: Coordinates, y: Coordinates, yaw: Coordinates
    ) -> tuple[Coordinates, Coordinates]:
        """The reference point [m] of footprint centres ``(x, y)`` [m] with body yaw ``ψ`` [rad]."""
        back = self.behind_centre
        if back == 0.0:
            return x, y
        return x - back * np.cos(yaw), y - back * np.sin(yaw)


@dataclass(frozen=True)
class VehicleState:
    """The simulated vehicle at time ``t`` [s]: centre ``x, y`` [m], body ``yaw`` [rad], ``steering``
    [rad], speed [m/s] and acceleration [m/s²] of the model's reference point (the centre, a car's rear
    axle); its ``course`` [rad] (direction of travel) and path ``curvature`` [1/m] follow from them."""

    t: float
    x: float
    y: float
    yaw: float
    steering: float
    speed: float
    acceleration: float
    course: float
    curvature: float

    def as_ego(self) -> Ego:
        """The planner's ego: the centre, and the reference point's direction of travel (a car's yaw),
        speed, acceleration and curvature."""
        return Ego(
            x=self.x,
            y=self.y,
            heading=self.course,
            speed=self.speed,
            acceleration=self.acceleration,
            curvature=self.curvature,
        )


def initial_state(model: BicycleModel, ego: Ego, vehicle: Vehicle) -> VehicleState:
    """The vehicle at an ego state (heading read as the reference point's course; unknown curvature taken
    as 0)."""
    limit = vehicle.curvature_limit
    curvature = float(np.clip(ego.curvature or 0.0, -limit, limit))
    steering = float(np.clip(model.steering_for(curvature), -model.max_steering, model.max_steering))
    beta = model.slip_angle(steering)
    return VehicleState(
        t=0.0,
        x=ego.x,
        y=ego.y,
        yaw=ego.heading - beta,
        steering=steering,
        speed=max(ego.speed, 0.0),
        acceleration=ego.acceleration,
        course=ego.heading,
        curvature=model.curvature(steering),
    )


def step_exact(
    model: BicycleModel, state: VehicleState, acceleration: float, steering: float, h: float
) -> VehicleState:
    """Hold ``acceleration`` [m/s²] and ``steering`` [rad] for ``h`` [s] and integrate exactly.

    The steering is applied as given (limits are the caller's, see :func:`advance`). The reference
    point moves along an arc of curvature ``κ(δ)`` by ``v h + a h²/2`` (up to where the speed reaches 0);
    the yaw turns by ``κ`` times that distance; the centre is placed from the point along the yaw.
    """
    beta = model.slip_angle(steering)
    kappa = model.curvature(steering)
    v0 = state.speed
    if acceleration < 0.0 and v0 + acceleration * h <= 0.0:
        stop = -v0 / acceleration if v0 > 0.0 else 0.0
        dist = v0 * stop + 0.5 * acceleration * stop**2
        v1, a1 = 0.0, 0.0
    else:
        dist = v0 * h + 0.5 * acceleration * h**2
        v1, a1 = v0 + acceleration * h, acceleration
    chi0 = state.yaw + beta
    turn = kappa * dist
    if abs(turn) < 1e-9:
        dx = dist * (math.cos(chi0) - 0.5 * turn * math.sin(chi0))
        dy = dist * (math.sin(chi0) + 0.5 * turn * math.cos(chi0))
    else:
        dx = (math.sin(chi0 + turn) - math.sin(chi0)) / kappa
        dy = (math.cos(chi0) - math.cos(chi0 + turn)) / kappa
    yaw = state.yaw + turn
    x, y = state.x + dx, state.y + dy
    back = model.behind_centre
    if back:  # the reference point moved by (dx, dy); the centre is `back` ahead of it along the yaw
        x += back * (math.cos(yaw) - math.cos(state.yaw))
        y += back * (math.sin(yaw) - math.sin(state.yaw))
    return VehicleState(
        t=state.t + h,
        x=x,
        y=y,
        yaw=yaw,
        steering=steering,
        speed=v1,
        acceleration=a1,
        course=yaw + beta,
        curvature=kappa,
    )


def advance(
    model: BicycleModel,
    vehicle: Vehicle,
    state: VehicleState,
    acceleration: float,
    curvature: float,
    h: float,
) -> VehicleState:
    """One sub-step towards commanded ``acceleration`` [m/s²] and path ``curvature`` [1/m]: both
    clipped to the vehicle's limits, the steering moved at most ``max_steering_rate·h``."""
    a = float(np.clip(acceleration, -vehicle.max_deceleration, vehicle.max_acceleration))
    target = float(np.clip(model.steering_for(curvature), -model.max_steering, model.max_steering))
    reach = model.max_steering_rate * h
    steering = state.steering + float(np.clip(target - state.steering, -reach, reach))
    return step_exact(model, state, a, steering, h)


# --------------------------------------------------------------------------------------------------
# Tracker
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TrackerGains:
    """Gains of the tracker: preview ``ℓ_d = max(min_preview, preview_time·v)`` [m, s]; speed gain
    ``k_v`` [1/s]; station gain ``k_s`` [1/s²]."""

    preview_time: float = 1.0
    min_preview: float = 4.0
    speed_gain: float = 1.0
    station_gain: float = 0.5


@dataclass(frozen=True)
class PlanPath:
    """A plan's trajectory prepared for tracking: arc length ``sigma`` [m] of its points, their segments,
    unwrapped heading [rad]."""

    trajectory: Trajectory
    sigma: FloatArray
    start: FloatArray
    direction: FloatArray
    length: FloatArray
    heading: FloatArray

    @classmethod
    def of(cls, traj: Trajectory, model: BicycleModel | None = None) -> PlanPath:
        """The path of ``model``'s reference point along ``traj`` (default: its points, the centre's;
        a car's rear axle lies behind each point along its heading, the body's yaw)."""
        x, y = (traj.x, traj.y) if model is None else model.reference_point(traj.x, traj.y, traj.heading)
        xy = np.column_stack((x, y))
        seg = np.diff(xy, axis=0)
        length = np.hypot(seg[:, 0], seg[:, 1])
        direction = seg / np.where(length > 0.0, length, 1.0)[:, None]
        sigma = np.concatenate(([0.0], np.cumsum(length)))
        return cls(traj, sigma, xy[:-1], direction, length, np.unwrap(traj.heading))


@dataclass(frozen=True)
class TrackerOutput:
    """Commands [m/s², 1/m] and the errors behind them: lateral [m], course [rad], station [m]."""

    acceleration: float
    curvature: float
    lateral_error: float
    course_error: float
    station_error: float


def track(
    path: PlanPath, tau: float, state: VehicleState, gains: TrackerGains, model: BicycleModel | None = None
) -> TrackerOutput:
    """The tracker's commands at time ``tau`` [s] after the plan's start (see the module docstring), for
    ``model``'s reference point (default: the centre ``state.x, state.y``) on ``path`` (the same point's)."""
    traj = path.trajectory
    sigma_ref = float(np.interp(tau, traj.t, path.sigma))
    v_ref = float(np.interp(tau, traj.t, traj.v))
    a_ref = float(np.interp(tau, traj.t, traj.a))
    near = (
        (path.sigma[1:] >= sigma_ref - PROJECTION_WINDOW)
        & (path.sigma[:-1] <= sigma_ref + PROJECTION_WINDOW)
        & (path.length > 1e-9)
    )
    if not near.any():  # a plan standing still: nothing to steer along
        return TrackerOutput(
            acceleration=a_ref + gains.speed_gain * (v_ref - state.speed),
            curvature=float(traj.curvature[0]),
            lateral_error=0.0,
            course_error=0.0,
            station_error=0.0,
        )
    idx = np.flatnonzero(near)
    px, py = (state.x, state.y) if model is None else model.reference_point(state.x, state.y, state.yaw)
    rel = np.array([px, py]) - path.start[idx]
    along = np.clip(np.einsum("ij,ij->i", rel, path.direction[idx]), 0.0, path.length[idx])
    offset = rel - along[:, None] * path.direction[idx]
    best = int(np.argmin(np.hypot(offset[:, 0], offset[:, 1])))
    k = idx[best]
    sigma = float(path.sigma[k] + along[best])
    d = path.direction[k]
    lateral = float(d[0] * offset[best, 1] - d[1] * offset[best, 0])
    heading = float(np.interp(sigma, path.sigma, path.heading))
    kappa_ff = float(np.interp(sigma, path.sigma, traj.curvature))
    course_error = math.remainder(state.course - heading, 2.0 * math.pi)
    preview = max(gains.min_preview, gains.preview_time * state.speed)
    curvature = kappa_ff - lateral / preview**2 - 2.0 * math.sin(course_error) / preview
    station = sigma_ref - sigma
    acceleration = a_ref + gains.speed_gain * (v_ref - state.speed) + gains.station_gain * station
    return TrackerOutput(acceleration, curvature, lateral, course_error, station)


# --------------------------------------------------------------------------------------------------
# Scenario: goal, moving obstacles
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Goal:
    """Where a run ends well: every criterion given must hold for the vehicle's centre.

    Attributes:
        s_min: arc length on the reference (TransF-κ) at least this [m].
        polygon: inside this outline, shape (k, 2) [m], k ≥ 3.
        position, radius: within ``radius`` [m] of ``position`` (2,) [m].
        check: an outside judge of the vehicle's state (e.g. CommonRoad's goal region,
            :meth:`planner_tools.crjudge.CommonRoadScene.goal_check`), asked at every sub-step of a
            cycle; the goal is reached at the first state it accepts (the other criteria, when given,
            are asked at the cycle's end).
    """

    s_min: float | None = None
    polygon: FloatArray | None = None
    position: FloatArray | None = None
    radius: float | None = None
    check: Callable[[VehicleState], bool] | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if self.s_min is None and self.polygon is None and self.position is None and self.check is None:
            raise InvalidInputError("give at least one of s_min, polygon, position or check", field="goal")
        if (self.position is None) != (self.radius is None):
            raise InvalidInputError("position and radius go together", field="goal.radius")
        if self.radius is not None and not self.radius > 0.0:
            raise InvalidInputError("must be positive", field="goal.radius")
        if self.polygon is not None:
            poly = np.asarray(self.polygon, dtype=float)
            if poly.ndim != 2 or poly.shape[0] < 3 or poly.shape[1] != 2 or not np.isfinite(poly).all():
                raise InvalidInputError("must be ≥ 3 finite points [x, y]", field="goal.polygon")
            object.__setattr__(self, "polygon", poly)
        if self.position is not None:
            pos = np.asarray(self.position, dtype=float)
            if pos.shape != (2,) or not np.isfinite(pos).all():
                raise InvalidInputError("must be a finite point [x, y]", field="goal.position")
            object.__setattr__(self, "position", pos)

    @property
    def geometric(self) -> bool:
        """Whether it has a criterion of the centre's position (``s_min``, ``polygon``, ``position``)."""
        return self.s_min is not None or self.polygon is not None or self.position is not None

    def reached_in(self, states: list[VehicleState], s: float) -> VehicleState | None:
        """The first of a cycle's ``states`` that reaches the goal (``check`` on each; the geometric
        criteria, with the arc length ``s`` [m], on the last), or None."""
        if self.check is not None:
            hit = next((st for st in states if self.check(st)), None)
            if hit is not None or not self.geometric:
                return hit
        last = states[-1]
        return last if self.reached(last.x, last.y, s) else None

    def reached(self, x: float, y: float, s: float) -> bool:
        """Whether a centre at ``(x, y)`` [m] with arc length ``s`` [m] meets every geometric criterion."""
        if self.s_min is not None and s < self.s_min:
            return False
        if self.polygon is not None and not shapely.Polygon(self.polygon).covers(shapely.Point(x, y)):
            return False
        if self.position is not None and self.radius is not None:
            return bool(math.hypot(x - self.position[0], y - self.position[1]) <= self.radius)
        return True


def default_goal(ref: ReferenceLine, vehicle: Vehicle) -> Goal:
    """The reference's end less :data:`GOAL_MARGIN_LENGTHS` vehicle lengths."""
    return Goal(s_min=ref.length - GOAL_MARGIN_LENGTHS * vehicle.length)


def default_duration(ref: ReferenceLine, problem: PlanningProblem) -> float:
    """A generous bound [s]: twice the time to drive the rest of the reference at the target speed,
    plus :data:`DURATION_SLACK`."""
    start = float(to_frenet(ref, [[problem.ego.x, problem.ego.y]]).s[0])
    target = problem.options.target_speed
    speed = problem.vehicle.max_speed if target is None else min(target, problem.vehicle.max_speed)
    return DURATION_FACTOR * max(ref.length - start, 0.0) / max(speed, 1.0) + DURATION_SLACK


def shift_obstacle(obstacle: Obstacle, t0: float) -> Obstacle:
    """The obstacle as seen at sim time ``t0`` [s]: a dynamic one's prediction re-based to start at
    ``t0`` (states before it dropped, the state at ``t0`` interpolated in front); a static one as is."""
    if not isinstance(obstacle, DynamicObstacle) or t0 == 0.0:
        return obstacle
    pred = obstacle.prediction
    later = pred[pred[:, 0] > t0]
    if pred[0, 0] < t0:
        now = np.concatenate(([t0], prediction_at(obstacle, np.array([t0]))[0]))
        later = np.vstack((now[None, :], later))
    shifted = later.copy()
    shifted[:, 0] -= t0
    return replace(obstacle, prediction=shifted)


#: an obstacle leaving at ``t`` [s] is still there at a sim time this close to it (``k · period`` rounds)
_LEAVE_TOLERANCE = 1e-9


def in_scene(problem: PlanningProblem, leaves: Mapping[str, float], t: float) -> PlanningProblem:
    """``problem`` without the obstacles that have left the scene by sim time ``t`` [s]: those whose id
    ``leaves`` maps to a time before ``t`` (a recording that ends there, :func:`planner_tools.commonroad.
    continued_predictions`); ``problem`` itself when none has."""
    if not leaves:
        return problem
    kept = tuple(ob for ob in problem.obstacles if not leaves.get(ob.id, math.inf) < t - _LEAVE_TOLERANCE)
    return problem if len(kept) == len(problem.obstacles) else replace(problem, obstacles=kept)


def problem_at(problem: PlanningProblem, state: VehicleState) -> PlanningProblem:
    """The problem the planner gets at ``state.t``: the vehicle as ego, predictions shifted, and the
    goal's time window (times from now) shifted by ``state.t``."""
    goal = problem.goal
    if goal is not None and goal.time is not None and state.t != 0.0:
        goal = replace(goal, time=(goal.time[0] - state.t, goal.time[1] - state.t))
    return replace(
        problem,
        ego=state.as_ego(),
        obstacles=tuple(shift_obstacle(ob, state.t) for ob in problem.obstacles),
        goal=goal,
    )


def obstacle_outlines(problem: PlanningProblem, t: float) -> tuple[tuple[str, FloatArray], ...]:
    """Every obstacle's outline at sim time ``t`` [s], as ``(id, coordinates (k, 2))``."""
    return tuple(
        (ob.id, np.asarray(shapely.get_coordinates(shapely.boundary(obstacle_shape(ob, t)))))
        for ob in problem.obstacles
    )


# --------------------------------------------------------------------------------------------------
# Records
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SimStep:
    """One replan cycle starting at ``state.t``.

    Attributes:
        state: the vehicle when the plan was asked for.
        s, d: its Frenet coordinates by TransF-κ [m].
        status: the plan's status, or ``error`` when planning raised a domain error (then ``message``
            says why and ``trajectory`` is None).
        planning_ms: wall time of the ``plan`` call [ms].
        trajectory: the plan.
        candidates_xy: the plan's candidates (N, P, 2) [m], NaN where a point was jumped (Alg. 5).
        candidates_folded: per candidate, whether it runs backwards or crosses itself (N,).
        chosen: index of the candidate the plan was built on.
        obstacles: every obstacle's outline at ``state.t``.
        max_lateral_error: largest tracking error to the plan over the step [m].
        decision: the plan's lane decision (:mod:`planner.decision`), None when planning raised.
    """

    state: VehicleState
    s: float
    d: float
    status: StepStatus
    message: str
    planning_ms: float
    trajectory: Trajectory | None
    candidates_xy: FloatArray | None
    candidates_folded: NDArray[np.bool_] | None
    chosen: int | None
    obstacles: tuple[tuple[str, FloatArray], ...]
    max_lateral_error: float
    decision: Decision | None = None


@dataclass(frozen=True)
class Motion:
    """The executed motion at every sub-step, arrays of shape (n,): ``t`` [s], ``x, y`` [m], ``yaw``,
    ``course``, ``steering`` [rad], ``curvature`` [1/m], ``v`` [m/s], ``a`` [m/s²], ``s, d`` [m] on the
    reference; ``step`` is the index of the cycle each sample belongs to."""

    t: FloatArray
    x: FloatArray
    y: FloatArray
    yaw: FloatArray
    course: FloatArray
    steering: FloatArray
    curvature: FloatArray
    v: FloatArray
    a: FloatArray
    s: FloatArray
    d: FloatArray
    step: NDArray[np.intp]


@dataclass(frozen=True)
class SimMetrics:
    """What a run did. Lengths [m], times [s], accelerations [m/s²], jerks [m/s³].

    Attributes:
        generator: the candidates' generator.
        termination: ``goal``, ``collision`` or ``timeout``.
        goal_reached, time_to_goal: whether and when [s] the goal was reached.
        sim_time, steps: simulated time and replan cycles.
        distance: distance driven by the centre; ``final_s``: its last arc length on the reference.
        collisions: sub-steps whose footprint intersects an obstacle; ``collided_with`` their ids.
        min_clearance: smallest footprint-to-obstacle distance (None without obstacles).
        backward_steps: cycles whose centre moved and ended with a smaller ``s``.
        fold_steps: cycles with an executed sample where ``κ·d ≥ 1``.
        max_lane_departure: farthest a footprint corner, or a point along a side
            (:func:`planner.collision.outline_points`), got outside the lane (≤ 0: inside).
        max_road_departure: farthest a footprint point got outside the road (≤ 0: inside; the lane's
            departure when the problem has no road).
        max_lateral_acceleration: the centre's ``max v_c²/R_c`` (``v²|κ|`` at the centre, the yaw rate
            times the centre's speed); ``max_longitudinal_jerk``, ``max_lateral_jerk``: of
            ``a`` and ``v²κ`` by differences between consecutive sub-steps at which the vehicle moves.
        max_tracking_error: largest lateral error of the tracker to the plan.
        planning_ms: ``median``, ``p95``, ``max`` of the plan calls' wall time [ms].
        status_counts: cycles per plan status (``ok``, ``stopped``, ``fallback``, ``error``).
        folded_candidates: ``mean`` folded candidates per cycle, ``cycles`` with any, ``chosen``
            cycles whose chosen candidate folded.
    """

    generator: str
    termination: Termination
    goal_reached: bool
    time_to_goal: float | None
    sim_time: float
    steps: int
    distance: float
    final_s: float
    collisions: int
    collided_with: tuple[str, ...]
    min_clearance: float | None
    backward_steps: int
    fold_steps: int
    max_lane_departure: float
    max_road_departure: float
    max_lateral_acceleration: float
    max_longitudinal_jerk: float
    max_lateral_jerk: float
    max_tracking_error: float
    planning_ms: dict[str, float]
    status_counts: dict[str, int]
    folded_candidates: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON data (floats rounded to 4 decimals, tuples as lists)."""
        out: dict[str, Any] = {}
        for f in fields(self):
            out[f.name] = _plain(getattr(self, f.name))
        return out


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if isinstance(value, bool | str) or value is None:
        return value
    if isinstance(value, int | np.integer):
        return int(value)
    number = float(value)
    return round(number, 4) if math.isfinite(number) else None


@dataclass(frozen=True)
class SimResult:
    """A run: the problem, goal and model it ran with, every cycle, the executed motion, its metrics."""

    problem: PlanningProblem
    goal: Goal
    model: BicycleModel
    replan_period: float
    duration: float
    steps: tuple[SimStep, ...]
    motion: Motion
    metrics: SimMetrics
    termination: Termination
    reference: ReferenceLine = field(repr=False)


# --------------------------------------------------------------------------------------------------
# The loop
# --------------------------------------------------------------------------------------------------


def _hits(
    problem: PlanningProblem, static: list[tuple[str, BaseGeometry]], states: list[VehicleState]
) -> tuple[NDArray[np.bool_], FloatArray, list[str]]:
    """Per state: whether the footprint hits an obstacle, its clearance [m]; ids of obstacles hit."""
    x = np.array([st.x for st in states])
    y = np.array([st.y for st in states])
    yaw = np.array([st.yaw for st in states])
    t = np.array([st.t for st in states])
    prints = footprints(x, y, yaw, problem.vehicle)
    clearance = np.full(len(states), np.inf)
    hit = np.zeros(len(states), dtype=bool)
    ids: list[str] = []
    shapes: list[tuple[str, Any]] = list(static)
    for ob in problem.obstacles:
        if isinstance(ob, DynamicObstacle):
            pose = prediction_at(ob, t)
            shapes.append(
                (
                    ob.id,
                    shapely.polygons(box_corners(pose[:, 0], pose[:, 1], pose[:, 2], ob.length, ob.width)),
                )
            )
    for ob_id, shape in shapes:
        dist = np.asarray(shapely.distance(prints, shape), dtype=float)
        inter = np.asarray(shapely.intersects(prints, shape), dtype=bool)
        clearance = np.minimum(clearance, np.where(inter, 0.0, dist))
        if inter.any():
            ids.append(ob_id)
        hit |= inter
    return hit, clearance, ids


def _candidates(ref: ReferenceLine, result: PlanResult) -> tuple[FloatArray | None, NDArray[np.bool_] | None]:
    cands = result.candidates
    if cands is None:
        return None, None
    xy = np.where(cands.valid[..., None], cands.xy, np.nan)
    return xy, folded_candidates(ref, cands)


def folded_candidates(ref: ReferenceLine, cands: CandidateSet) -> NDArray[np.bool_]:
    """Per candidate, whether its kept points run backwards along the reference (TransF-κ ``s`` not
    increasing) or cross themselves — :func:`planner.validation.folds_back`, over all candidates at once."""
    n, p = cands.valid.shape
    s = to_frenet(ref, cands.xy.reshape(-1, 2)).s.reshape(n, p)
    # consecutive kept points: compare each kept point with the previous kept one
    order = np.where(cands.valid, np.arange(p), -1)
    prev = np.maximum.accumulate(np.concatenate((np.full((n, 1), -1), order[:, :-1]), axis=1), axis=1)
    has_prev = cands.valid & (prev >= 0)
    s_prev = np.take_along_axis(s, np.maximum(prev, 0), axis=1)
    backward = (has_prev & (s <= s_prev)).any(axis=1)
    lines = [shapely.LineString(cands.points(i)[2]) if cands.valid[i].sum() >= 3 else None for i in range(n)]
    simple = np.array([line is None or bool(line.is_simple) for line in lines], dtype=bool)
    return np.asarray(backward | ~simple)


def simulate(
    problem: PlanningProblem,
    *,
    duration: float | None = None,
    replan_period: float = 0.1,
    goal: Goal | None = None,
    progress: Callable[[int, int], None] | None = None,
    model: BicycleModel | None = None,
    gains: TrackerGains | None = None,
    collision: Callable[[VehicleState], bool] | None = None,
    leaves: Mapping[str, float] | None = None,
) -> SimResult:
    """Drive ``problem`` in closed loop (see the module docstring).

    Args:
        problem: the scenario at ``t = 0``; its ego is the vehicle's initial state.
        duration: longest simulated time [s]; default :func:`default_duration`.
        replan_period: time between plans [s]; the plan's first ``replan_period`` is executed.
        goal: default :func:`default_goal`.
        progress: called with ``(cycles done, most cycles)`` after each cycle.
        model: vehicle model; default :meth:`BicycleModel.for_vehicle`.
        gains: tracker gains; default :class:`TrackerGains`.
        collision: an outside collision check of the vehicle's state (e.g. CommonRoad's collision
            checker at the scenario's time steps, :meth:`planner_tools.crjudge.CommonRoadScene.
            collision_check`), asked at every sub-step of a cycle; given, a collision it finds ends the
            run, and the simulator's own footprint check against the problem's obstacles is only counted
            (``collisions``, ``collided_with``, ``min_clearance``).
        leaves: obstacle id → sim time [s] after which that obstacle is no longer in the scene (a
            recorded vehicle whose recording ends: :func:`planner_tools.commonroad.
            continued_predictions`); from the first cycle starting after it, neither the planner nor the
            simulator's own contact check sees it (:func:`in_scene`). Default: every obstacle stays.

    A ``problem.options.time_budget_ms`` is kept: plans that overrun it become fallbacks, so the run
    then depends on the machine's speed.

    Raises:
        InvalidInputError: for a non-positive ``duration`` or ``replan_period``, or a reference the
            planner refuses.
    """
    if not replan_period > 0.0:
        raise InvalidInputError("must be positive", field="replan_period")
    ref = build_reference(problem.reference_line)
    if duration is None:
        duration = default_duration(ref, problem)
    if not duration > 0.0:
        raise InvalidInputError("must be positive", field="duration")
    goal = default_goal(ref, problem.vehicle) if goal is None else goal
    model = BicycleModel.for_vehicle(problem.vehicle) if model is None else model
    gains = TrackerGains() if gains is None else gains
    vehicle = problem.vehicle
    asked = replace(problem, options=replace(problem.options, return_candidates=True))
    leaves = {} if leaves is None else dict(leaves)
    static = [(ob.id, obstacle_shape(ob)) for ob in problem.obstacles if not isinstance(ob, DynamicObstacle)]
    total = max(1, math.ceil(duration / replan_period - 1e-9))
    h = replan_period / model.substeps

    state = initial_state(model, problem.ego, vehicle)
    samples: list[VehicleState] = [state]
    sample_step: list[int] = [0]
    steps: list[SimStep] = []
    min_clearance = np.inf
    collisions = 0
    collided: list[str] = []
    termination: Termination = "timeout"
    time_to_goal: float | None = None
    fr = to_frenet(ref, [[state.x, state.y]])
    s_now, d_now = float(fr.s[0]), float(fr.d[0])

    hit0, clear0, ids0 = _hits(problem, static, [state])
    min_clearance = float(clear0.min()) if clear0.size else np.inf
    if hit0.any():
        collisions, collided = 1, ids0
    if (hit0.any() and collision is None) or (collision is not None and collision(state)):
        termination = "collision"
    elif goal.reached_in([state], s_now) is not None:
        termination, time_to_goal = "goal", 0.0

    for k in range(total if termination == "timeout" else 0):
        asked_now = problem_at(in_scene(asked, leaves, state.t), state)
        present = in_scene(problem, leaves, state.t)
        t0 = time.perf_counter()
        result: PlanResult | None
        try:
            result = plan(asked_now)
            error = ""
        except PlannerError as exc:
            result, error = None, str(exc)
        planning_ms = 1e3 * (time.perf_counter() - t0)

        cycle: list[VehicleState] = []
        worst = 0.0
        path = PlanPath.of(result.trajectory, model) if result is not None else None
        for i in range(model.substeps):
            if path is None:
                a_cmd, k_cmd = -vehicle.max_deceleration, state.curvature
            else:
                out = track(path, i * h, state, gains, model)
                a_cmd, k_cmd = out.acceleration, out.curvature
                worst = max(worst, abs(out.lateral_error))
            state = advance(model, vehicle, state, a_cmd, k_cmd, h)
            cycle.append(state)
        # t accumulates exactly on the replan grid
        state = replace(state, t=(k + 1) * replan_period)
        cycle[-1] = state

        xy, folded = _candidates(ref, result) if result is not None else (None, None)
        steps.append(
            SimStep(
                state=samples[-1],
                s=s_now,
                d=d_now,
                status="error" if result is None else result.status,
                message=error if result is None else result.message,
                planning_ms=planning_ms,
                trajectory=None if result is None else result.trajectory,
                candidates_xy=xy,
                candidates_folded=folded,
                chosen=None if result is None else result.diagnostics.chosen_candidate,
                obstacles=obstacle_outlines(present, samples[-1].t),
                max_lateral_error=worst,
                decision=None if result is None else result.diagnostics.decision,
            )
        )
        samples.extend(cycle)
        sample_step.extend([k] * len(cycle))
        fr = to_frenet(ref, [[state.x, state.y]])
        s_now, d_now = float(fr.s[0]), float(fr.d[0])

        hit, clearance, ids = _hits(present, static, cycle)
        if clearance.size:
            min_clearance = min(min_clearance, float(clearance.min()))
        if progress is not None:
            progress(k + 1, total)
        if hit.any():
            collisions += int(hit.sum())
            collided.extend(i for i in ids if i not in collided)
        if (hit.any() and collision is None) or (collision is not None and any(map(collision, cycle))):
            termination = "collision"
            break
        reached = goal.reached_in(cycle, s_now)
        if reached is not None:
            termination, time_to_goal = "goal", reached.t
            break

    motion = _motion(ref, samples, sample_step)
    metrics = _metrics(
        ref,
        problem,
        model,
        steps,
        motion,
        termination=termination,
        time_to_goal=time_to_goal,
        collisions=collisions,
        collided=collided,
        min_clearance=min_clearance if problem.obstacles else None,
    )
    return SimResult(
        problem=problem,
        goal=goal,
        model=model,
        replan_period=replan_period,
        duration=duration,
        steps=tuple(steps),
        motion=motion,
        metrics=metrics,
        termination=termination,
        reference=ref,
    )


def _motion(ref: ReferenceLine, samples: list[VehicleState], step: list[int]) -> Motion:
    cols = {
        name: np.array([getattr(st, name) for st in samples], dtype=float)
        for name in ("t", "x", "y", "yaw", "course", "steering", "curvature", "speed", "acceleration")
    }
    fr = to_frenet(ref, np.column_stack((cols["x"], cols["y"])))
    return Motion(
        t=cols["t"],
        x=cols["x"],
        y=cols["y"],
        yaw=cols["yaw"],
        course=cols["course"],
        steering=cols["steering"],
        curvature=cols["curvature"],
        v=cols["speed"],
        a=cols["acceleration"],
        s=fr.s,
        d=fr.d,
        step=np.asarray(step, dtype=np.intp),
    )


def _per_cycle_any(flags: NDArray[np.bool_], step: NDArray[np.intp], cycles: int) -> int:
    if cycles == 0:
        return 0
    return int(np.count_nonzero(np.bincount(step[flags], minlength=cycles)))


def _metrics(
    ref: ReferenceLine,
    problem: PlanningProblem,
    model: BicycleModel,
    steps: list[SimStep],
    motion: Motion,
    *,
    termination: Termination,
    time_to_goal: float | None,
    collisions: int,
    collided: list[str],
    min_clearance: float | None,
) -> SimMetrics:
    vehicle = problem.vehicle
    n = len(steps)
    # per cycle: the samples at the replan instants (the cycle's start and its end)
    ends = np.flatnonzero(np.diff(np.concatenate((motion.step, [n]))) != 0) if n else np.zeros(0, np.intp)
    s_cycle = np.concatenate(([motion.s[0]], motion.s[ends])) if n else motion.s[:1]
    xy = np.column_stack((motion.x, motion.y))
    xy_cycle = np.vstack((xy[:1], xy[ends])) if n else xy[:1]
    moved = np.hypot(*np.diff(xy_cycle, axis=0).T) > MOVING
    backward = int(np.count_nonzero(moved & (np.diff(s_cycle) < -S_TOLERANCE)))
    kappa = ref.kappa_at(motion.s)
    folded = kappa * motion.d >= 1.0
    fold_steps = _per_cycle_any(folded[1:], motion.step[1:], n)

    # the corners and points along the sides: a side cuts the inside of a curve between its corners
    outline = outline_points(motion.x, motion.y, motion.yaw, vehicle.length, vehicle.width).reshape(-1, 2)
    cf = to_frenet(ref, outline)
    left, right = problem.lane.widths(ref, cf.s)
    departure = float(np.max(np.maximum(cf.d - left, -right - cf.d)))
    road_departure = departure
    if problem.road is not None:
        left, right = problem.road.widths(ref, cf.s)
        road_departure = float(np.max(np.maximum(cf.d - left, -right - cf.d)))

    # the centre's: yaw rate v·κ times the centre's speed
    lat = motion.v**2 * motion.curvature * model.centre_speed_ratio(motion.steering)
    dt = np.diff(motion.t)
    safe = np.where(dt > 0, dt, np.inf)
    # while moving: the step to a = 0 when the vehicle comes to rest is the integrator's, not the motion's
    moving = (motion.v[:-1] > 0.0) & (motion.v[1:] > 0.0)
    jerk_long = np.where(moving, np.abs(np.diff(motion.a)) / safe, 0.0)
    jerk_lat = np.where(moving, np.abs(np.diff(lat)) / safe, 0.0)

    ms = np.array([st.planning_ms for st in steps])
    status_counts = {
        name: sum(st.status == name for st in steps) for name in ("ok", "stopped", "fallback", "error")
    }
    flags = [(st.candidates_folded, st.chosen) for st in steps if st.candidates_folded is not None]
    folded_counts = np.array([int(np.count_nonzero(f)) for f, _ in flags])
    chosen_folded = sum(1 for f, chosen in flags if chosen is not None and bool(f[chosen]))
    return SimMetrics(
        generator=problem.options.generator,
        termination=termination,
        goal_reached=termination == "goal",
        time_to_goal=time_to_goal,
        sim_time=float(motion.t[-1]),
        steps=n,
        distance=float(np.sum(np.hypot(np.diff(motion.x), np.diff(motion.y)))),
        final_s=float(motion.s[-1]),
        collisions=collisions,
        collided_with=tuple(collided),
        min_clearance=min_clearance,
        backward_steps=backward,
        fold_steps=fold_steps,
        max_lane_departure=departure,
        max_road_departure=road_departure,
        max_lateral_acceleration=float(np.max(np.abs(lat))),
        max_longitudinal_jerk=float(jerk_long.max()) if jerk_long.size else 0.0,
        max_lateral_jerk=float(jerk_lat.max()) if jerk_lat.size else 0.0,
        max_tracking_error=max((st.max_lateral_error for st in steps), default=0.0),
        planning_ms={
            "median": float(np.median(ms)) if n else 0.0,
            "p95": float(np.percentile(ms, 95)) if n else 0.0,
            "max": float(ms.max()) if n else 0.0,
        },
        status_counts=status_counts,
        folded_candidates={
            "mean": float(folded_counts.mean()) if folded_counts.size else 0.0,
            "cycles": int(np.count_nonzero(folded_counts)),
            "chosen": chosen_folded,
        },
    )
