"""The planning problem as plain frozen dataclasses over numpy arrays (no pydantic here).

The HTTP layer (`app/`) validates a request and converts it into a :class:`PlanningProblem`; the
planner never sees JSON. Units: metres [m], seconds [s], radians [rad], metres per second [m/s].
A trajectory point is the vehicle's geometric centre; ``heading`` is counter-clockwise from +x. A
:class:`Vehicle` with a ``wheelbase`` is a car, planned at its rear axle (see :class:`Vehicle`).

Every dataclass here checks its fields when it is built (:class:`Ego`, :class:`Lane`,
:class:`Vehicle`, :class:`Options`), and a :class:`PlanningProblem` checks its obstacles and that
per-point lane widths match the reference line; what they refuse raises
:class:`~planner.errors.InvalidInputError` naming the field as the JSON request does
(``ego.speed``, ``lane.left_width.3``, ``vehicle.max_deceleration``, ``options.dt``,
``obstacles.2.circle.radius``). Everything they accept the planner handles: a vanishing obstacle is a
point, a braking distance too long to matter is capped. The ranges accepted include every request the
HTTP API (``app.models``) accepts, and every state the simulator (``planner_tools.sim``) reaches. The
reference line's points are checked by :func:`~planner.reference.build_reference`, when planning.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal, get_args

import numpy as np

from planner import checks
from planner.checks import MAX_SIZE
from planner.errors import InvalidInputError, InvalidReferenceError
from planner.goal import Goal
from planner.reference import FloatArray, ReferenceLine, widths_at

Generator = Literal["naive", "transf_kappa"]


@dataclass(frozen=True)
class PolygonObstacle:
    """A static obstacle given by its outline, shape (k, 2) [m], k ≥ 3."""

    id: str
    polygon: FloatArray


@dataclass(frozen=True)
class CircleObstacle:
    """A static disc: centre (2,) [m] and radius [m]."""

    id: str
    center: FloatArray
    radius: float


@dataclass(frozen=True)
class DynamicObstacle:
    """A moving box ``length × width`` [m] centred at each predicted state.

    ``prediction`` has columns ``t [s], x [m], y [m], heading [rad]``, shape (k, 4), ``t`` increasing.
    """

    id: str
    length: float
    width: float
    prediction: FloatArray


Obstacle = PolygonObstacle | CircleObstacle | DynamicObstacle


@dataclass(frozen=True)
class Lane:
    """Lane bounds: width to the left and right of the reference [m]; scalar or one per input point.

    A width is a number in ``[0, MAX_SIZE]``, or a 1-D array of them (stored as a float array), one per
    point of the reference line (the :class:`PlanningProblem` checks the count).

    Raises:
        InvalidInputError: naming the field (``lane.left_width``, ``lane.right_width.3``).
    """

    #: the request's key of these widths, which an error's field starts with
    KEY: ClassVar[str] = "lane"

    left_width: float | FloatArray
    right_width: float | FloatArray

    def __post_init__(self) -> None:
        for name in ("left_width", "right_width"):
            value = getattr(self, name)
            width = checks.width(value, f"{self.KEY}.{name}")
            if width is not value:
                object.__setattr__(self, name, width)

    def widths(self, ref: ReferenceLine, s: Any) -> tuple[FloatArray, FloatArray]:
        """The left and right widths [m] at arc lengths ``s`` [m] of ``ref``
        (:func:`planner.reference.widths_at`), each of the shape of ``s``."""
        return (
            widths_at(self.left_width, ref, s, field_name=f"{self.KEY}.left_width"),
            widths_at(self.right_width, ref, s, field_name=f"{self.KEY}.right_width"),
        )


@dataclass(frozen=True)
class Road(Lane):
    """The drivable surface either side of the reference [m]: the lane and what lies beyond it (adjacent
    lanes of either direction, shoulders), given as a lane is; on each side at least the lane's width
    (the :class:`PlanningProblem` checks it). A vehicle keeps to its lane and may leave it for the
    road only to get past what blocks the lane.

    Raises:
        InvalidInputError: naming the field (``road.left_width``, ``road.right_width.3``).
    """

    KEY: ClassVar[str] = "road"


@dataclass(frozen=True)
class Ego:
    """The vehicle's current state: centre position [m], heading [rad], speed [m/s], acceleration
    [m/s²] and, if known, path curvature [1/m].

    For the point model (a :class:`Vehicle` without a wheelbase) heading, speed, acceleration and
    curvature are the centre's path's; for a car the centre is still the footprint's, and heading is
    the body's yaw, speed and acceleration the rear axle's, curvature the rear axle's path's
    (``tan δ / wheelbase``).

    Every field must be finite (``curvature`` may be ``None``). ``speed`` is at most
    :data:`MAX_EGO_SPEED`; a speed just below zero, down to ``-STANDSTILL_TOLERANCE``, is a standstill
    measured with noise or integrated with rounding and is stored as 0 (the planner drives forwards
    only). ``|acceleration|`` is at most :data:`MAX_ACCELERATION`, ``|curvature|`` at most
    :data:`MAX_EGO_CURVATURE`. Position and heading have no bound here: the planner refuses an ego far
    from the road (``ego``) or pointing away from it (``ego.heading``). The checks are a few float
    comparisons (the simulator builds an ego at every step).

    Raises:
        InvalidInputError: naming the field (``ego.speed``).
    """

    x: float
    y: float
    heading: float
    speed: float = 0.0
    acceleration: float = 0.0
    curvature: float | None = None

    def __post_init__(self) -> None:
        checks.number(self.x, "ego.x")
        checks.number(self.y, "ego.y")
        checks.number(self.heading, "ego.heading")
        speed = checks.number(self.speed, "ego.speed")
        if not -STANDSTILL_TOLERANCE <= speed <= MAX_EGO_SPEED:
            raise InvalidInputError(
                f"must be between 0 and {MAX_EGO_SPEED:g} m/s (the planner drives forwards)",
                field="ego.speed",
            )
        if speed < 0.0:
            object.__setattr__(self, "speed", 0.0)
        if abs(checks.number(self.acceleration, "ego.acceleration")) > MAX_ACCELERATION:
            raise InvalidInputError(f"must be between ±{MAX_ACCELERATION:g} m/s²", field="ego.acceleration")
        curvature = self.curvature
        if curvature is not None and abs(checks.number(curvature, "ego.curvature")) > MAX_EGO_CURVATURE:
            raise InvalidInputError(f"must be between ±{MAX_EGO_CURVATURE:g} 1/m", field="ego.curvature")


#: the smallest positive normal float; an acceleration or curvature limit below it is a denormal
SMALLEST_LIMIT = float(np.finfo(np.float64).tiny)
#: the limits of :class:`Vehicle` whose reciprocals the planner takes (braking distances ``v²/a``, time
#: to reach a speed ``v/a``, turning radius ``1/κ``): they must be normal floats
RECIPROCAL_LIMITS = ("max_acceleration", "max_deceleration", "max_lateral_acceleration", "max_curvature")
#: largest acceleration limit [m/s²]: about 1000 g, which no vehicle's tyres transmit nor occupants
#: survive (road vehicles reach about 1 g); far beyond it the speed profile's braking terms overflow
MAX_ACCELERATION = 1e4
#: a negative ego speed down to minus this [m/s] is a standstill (sensor noise, rounding), taken as 0
STANDSTILL_TOLERANCE = 1e-3
#: largest ego speed [m/s]: the speed of light; far beyond it (≈ 10¹⁵⁴) the squares of speeds overflow
MAX_EGO_SPEED = 3e8
#: largest |ego curvature| [1/m]: a turning radius of a nanometre, no vehicle's; far beyond it the lateral
#: QP's start constraint leaves the range a QP solver accepts (OSQP: 10³⁰)
MAX_EGO_CURVATURE = 1e9
#: longest planning horizon [s] (ten minutes; the path is capped at 20 km anyway)
MAX_HORIZON_TIME = 600.0
#: shortest trajectory sampling step [s] (a millisecond)
MIN_DT = 1e-3
#: most trajectory points of one plan (``horizon_time / dt``): a bound on the work one plan asks for
MAX_TRAJECTORY_POINTS = 20_000
#: most points per candidate, and over all candidates (``num_candidates × num_points``)
MAX_NUM_POINTS, MAX_CANDIDATE_POINTS = 10_000, 1_000_000
#: the fields of :class:`Vehicle` with an upper bound, and the bound
_VEHICLE_MAXIMA = {
    "length": MAX_SIZE,
    "width": MAX_SIZE,
    "max_acceleration": MAX_ACCELERATION,
    "max_deceleration": MAX_ACCELERATION,
    "max_lateral_acceleration": MAX_ACCELERATION,
}


@dataclass(frozen=True)
class Vehicle:
    """Vehicle footprint [m] and limits: speed [m/s], accelerations [m/s²], curvature [1/m]; with a
    ``wheelbase``, a car (a kinematic single-track vehicle) with its steering limits.

    Every field given must be positive and finite. The acceleration and curvature limits
    (:data:`RECIPROCAL_LIMITS`) must moreover be *normal* floats (at least :data:`SMALLEST_LIMIT`,
    ≈ 2.2·10⁻³⁰⁸): a denormal such as ``5e-324`` is no measurement of a vehicle, it has lost its
    precision, and its reciprocal (a braking distance ``v²/a``, a turning radius ``1/κ``) overflows.
    Tiny normal limits are accepted: the planner caps the distances they imply. ``length``, ``width``
    and ``wheelbase`` are at most :data:`MAX_SIZE`, the accelerations at most :data:`MAX_ACCELERATION`;
    ``max_speed`` and ``max_curvature`` have no upper bound (a vehicle that turns on the spot has
    an unbounded curvature limit).

    Two models of motion (:attr:`is_car`):

    * **point** (no ``wheelbase``): a vehicle whose footprint's centre does not slip, as a
      differential-drive robot's: the planned point is the centre, the footprint turns with the
      tangent of the centre's path, ``curvature`` is the centre path's.
    * **car** (``wheelbase`` W given, with ``rear_axle_offset`` l_r: how far the rear axle lies behind
      the footprint's centre, ``0 ≤ l_r ≤ length/2``): a kinematic single-track vehicle. Its rear axle
      does not slip: it moves along the body's yaw ``ψ``, on a path of curvature ``κ = tan δ / W`` for
      the steering angle ``δ``; the footprint is the ``length × width`` box centred ``l_r`` ahead of the
      rear axle along ``ψ``, i.e. it spans ``[−(L/2 − l_r), L/2 + l_r]`` along the yaw from the rear
      axle (:attr:`rear_extent`, :attr:`front_extent`). The planned point is the rear axle.
      ``max_steering_angle`` [rad] (``< π/2``; default ``atan(W · max_curvature)``) bounds ``|δ|``,
      ``max_steering_rate`` [rad/s] (default: no bound) bounds ``|dδ/dt|``.

    Raises:
        InvalidInputError: naming the field (``vehicle.max_deceleration``).
    """

    length: float = 4.5
    width: float = 1.8
    max_speed: float = 20.0
    max_acceleration: float = 2.5
    max_deceleration: float = 6.0
    max_lateral_acceleration: float = 3.0
    max_curvature: float = 0.2
    wheelbase: float | None = None
    rear_axle_offset: float | None = None
    max_steering_angle: float | None = None
    max_steering_rate: float | None = None

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            where = f"vehicle.{f.name}"
            if f.name in CAR_FIELDS:
                continue
            value = checks.number(getattr(self, f.name), where)
            if not value > 0.0:
                raise InvalidInputError("must be positive", field=where)
            if value < SMALLEST_LIMIT and f.name in RECIPROCAL_LIMITS:
                raise InvalidInputError(
                    f"{value:g} is a denormal, not a vehicle limit (at least {SMALLEST_LIMIT:.3g})",
                    field=where,
                )
            if value > _VEHICLE_MAXIMA.get(f.name, np.inf):
                raise InvalidInputError(f"must be at most {_VEHICLE_MAXIMA[f.name]:g}", field=where)
        self._check_car()

    def _check_car(self) -> None:
        """The car's fields: all or none of them need a wheelbase, and the rear axle lies under the body."""
        if self.wheelbase is None:
            given = [name for name in CAR_FIELDS[1:] if getattr(self, name) is not None]
            if given:
                raise InvalidInputError("needs vehicle.wheelbase (a car)", field=f"vehicle.{given[0]}")
            return
        wheelbase = checks.number(self.wheelbase, "vehicle.wheelbase")
        if not 0.0 < wheelbase <= MAX_SIZE:
            raise InvalidInputError(f"must be positive and at most {MAX_SIZE:g} m", field="vehicle.wheelbase")
        if self.rear_axle_offset is None:
            raise InvalidInputError(
                "is required with a wheelbase: how far the rear axle lies behind the footprint's centre",
                field="vehicle.rear_axle_offset",
            )
        offset = checks.number(self.rear_axle_offset, "vehicle.rear_axle_offset")
        if not 0.0 <= offset <= 0.5 * self.length:
            raise InvalidInputError(
                f"must be between 0 and half the length ({0.5 * self.length:g} m)",
                field="vehicle.rear_axle_offset",
            )
        if self.max_steering_angle is not None:
            angle = checks.number(self.max_steering_angle, "vehicle.max_steering_angle")
            if not 0.0 < angle < 0.5 * math.pi:
                raise InvalidInputError("must be between 0 and π/2 rad", field="vehicle.max_steering_angle")
            if math.tan(angle) / wheelbase < SMALLEST_LIMIT:  # the curvature it allows: a reciprocal limit
                raise InvalidInputError(
                    f"allows a curvature tan(δ)/wheelbase below {SMALLEST_LIMIT:.3g} 1/m, a denormal",
                    field="vehicle.max_steering_angle",
                )
        if self.max_steering_rate is not None:
            rate = checks.number(self.max_steering_rate, "vehicle.max_steering_rate")
            if not rate >= SMALLEST_LIMIT:
                raise InvalidInputError("must be positive", field="vehicle.max_steering_rate")

    @property
    def is_car(self) -> bool:
        """Whether this is a car (a kinematic single-track vehicle planned at its rear axle)."""
        return self.wheelbase is not None

    @property
    def rear_offset(self) -> float:
        """How far the planned point lies behind the footprint's centre [m]: the rear axle's offset for a
        car, 0 for the point model (whose planned point is the centre)."""
        return 0.0 if self.rear_axle_offset is None else float(self.rear_axle_offset)

    @property
    def front_extent(self) -> float:
        """How far the footprint reaches ahead of the planned point along the heading [m]:
        ``L/2 + l_r``."""
        return 0.5 * self.length + self.rear_offset

    @property
    def rear_extent(self) -> float:
        """How far the footprint reaches behind the planned point along the heading [m]:
        ``L/2 − l_r``."""
        return 0.5 * self.length - self.rear_offset

    @property
    def curvature_limit(self) -> float:
        """The largest path curvature of the planned point [1/m]: ``max_curvature``, and for a car with
        a ``max_steering_angle`` also ``tan(δ_max)/W``."""
        if self.wheelbase is None or self.max_steering_angle is None:
            return self.max_curvature
        return min(self.max_curvature, math.tan(self.max_steering_angle) / self.wheelbase)

    @property
    def steering_limit(self) -> float | None:
        """A car's largest steering angle [rad]: ``max_steering_angle``, default ``atan(W·max_curvature)``;
        None for the point model."""
        if self.wheelbase is None:
            return None
        if self.max_steering_angle is not None:
            return self.max_steering_angle
        return math.atan(self.wheelbase * self.max_curvature)


#: the fields of a car (:attr:`Vehicle.is_car`), ``wheelbase`` first; optional, checked together
CAR_FIELDS = ("wheelbase", "rear_axle_offset", "max_steering_angle", "max_steering_rate")


@dataclass(frozen=True)
class Options:
    """Planning options.

    Attributes:
        horizon_time: planning horizon [s].
        dt: trajectory sampling step [s].
        target_speed: desired speed [m/s]; ``None`` means the vehicle's max speed (within
            ``speed_limit``).
        speed_limit: the highest speed allowed [m/s], at least ``target_speed``: the vehicle cruises at
            the target and may drive faster, up to this, to keep clear of a vehicle from behind or to
            meet a goal's time window. ``None``: the target speed is the limit.
        num_candidates: candidate lateral profiles to generate.
        num_points: points per candidate.
        generator: ``naive`` (Algorithm 4) or ``transf_kappa`` (Algorithm 5).
        seed: seed of the candidates' random end offsets and lengths.
        return_candidates: include the candidates in the answer.
        lateral_margin: clearance [m] the lateral bounds keep from the lane edges and the static
            obstacles, and the candidates from the lane edges (candidate scoring and the moving
            obstacles' bounds keep ``PlannerConfig.obstacle_margin``: see :mod:`planner.config`).
        min_path_length: shortest path the candidates cover [m].
        time_budget_ms: wall-clock budget of one plan [ms]; a stage that ends past it makes the answer
            a braking ``fallback`` saying so. ``None``: no budget.

    Ranges: ``0 < horizon_time ≤ MAX_HORIZON_TIME``; ``MIN_DT ≤ dt ≤ MAX_HORIZON_TIME`` with at most
    :data:`MAX_TRAJECTORY_POINTS` steps ``horizon_time / dt`` (a ``dt`` longer than the horizon gives a
    single point); ``target_speed``, ``speed_limit`` and ``min_path_length`` finite and ≥ 0, ``speed_limit``
    at least ``target_speed`` (the planner caps them at
    the vehicle's speed and its longest path); ``0 ≤ lateral_margin ≤ MAX_SIZE``; ``num_candidates ≥ 1``,
    ``2 ≤ num_points ≤ MAX_NUM_POINTS`` and ``num_candidates × num_points ≤ MAX_CANDIDATE_POINTS``;
    ``seed ≥ 0``; ``time_budget_ms`` positive.

    Raises:
        InvalidInputError: naming the field (``options.dt``).
    """

    horizon_time: float = 8.0
    dt: float = 0.1
    target_speed: float | None = None
    speed_limit: float | None = None
    num_candidates: int = 32
    num_points: int = 100
    generator: Generator = "transf_kappa"
    seed: int = 0
    return_candidates: bool = False
    lateral_margin: float = 0.2
    min_path_length: float = 20.0
    time_budget_ms: float | None = None

    def __post_init__(self) -> None:
        horizon = checks.number(self.horizon_time, "options.horizon_time")
        if not 0.0 < horizon <= MAX_HORIZON_TIME:
            raise InvalidInputError(
                f"must be positive and at most {MAX_HORIZON_TIME:g} s", field="options.horizon_time"
            )
        dt = checks.number(self.dt, "options.dt")
        if not MIN_DT <= dt <= MAX_HORIZON_TIME:
            raise InvalidInputError(
                f"must be between {MIN_DT:g} and {MAX_HORIZON_TIME:g} s", field="options.dt"
            )
        if horizon / dt > MAX_TRAJECTORY_POINTS:
            raise InvalidInputError(
                f"horizon_time / dt = {horizon / dt:.0f} trajectory steps; at most {MAX_TRAJECTORY_POINTS}",
                field="options.dt",
            )
        for name in ("target_speed", "speed_limit", "lateral_margin", "min_path_length"):
            value = getattr(self, name)
            if value is not None and not checks.number(value, f"options.{name}") >= 0.0:
                raise InvalidInputError("must be at least 0", field=f"options.{name}")
        limit, target = self.speed_limit, self.target_speed
        if limit is not None and target is not None and limit < target:
            raise InvalidInputError(
                f"must be at least target_speed ({target:g} m/s)", field="options.speed_limit"
            )
        if self.lateral_margin > MAX_SIZE:  # far beyond, the lateral QP's bounds leave OSQP's range (10³⁰)
            raise InvalidInputError(f"must be at most {MAX_SIZE:g} m", field="options.lateral_margin")
        candidates = checks.integer(self.num_candidates, "options.num_candidates", 1)
        points = checks.integer(self.num_points, "options.num_points", 2)
        if points > MAX_NUM_POINTS:
            raise InvalidInputError(f"must be at most {MAX_NUM_POINTS}", field="options.num_points")
        if candidates * points > MAX_CANDIDATE_POINTS:
            raise InvalidInputError(
                f"num_candidates × num_points = {candidates * points}; at most {MAX_CANDIDATE_POINTS}",
                field="options.num_points",
            )
        if not isinstance(self.generator, str) or self.generator not in get_args(Generator):
            raise InvalidInputError(
                f"must be one of {', '.join(get_args(Generator))}", field="options.generator"
            )
        checks.integer(self.seed, "options.seed", 0)
        if not isinstance(self.return_candidates, bool | np.bool_):
            raise InvalidInputError("must be true or false", field="options.return_candidates")
        budget = self.time_budget_ms
        if budget is not None and not checks.number(budget, "options.time_budget_ms") > 0.0:
            raise InvalidInputError("must be positive", field="options.time_budget_ms")


@dataclass(frozen=True)
class PlanningProblem:
    """Everything one plan needs: reference polyline (n, 2) [m] in driving order, lane, obstacles,
    ego state, vehicle and options; optionally the whole road beyond the lane (``road``, on each side
    at least the lane: see :class:`Road`) and a goal (:class:`planner.goal.Goal`)."""

    reference_line: FloatArray
    lane: Lane
    ego: Ego
    obstacles: tuple[Obstacle, ...] = ()
    vehicle: Vehicle = field(default_factory=Vehicle)
    options: Options = field(default_factory=Options)
    road: Road | None = None
    goal: Goal | None = None

    def __post_init__(self) -> None:
        try:
            reference = np.asarray(self.reference_line, dtype=float)
        except (TypeError, ValueError):
            raise InvalidReferenceError(
                "must be a list of [x, y] pairs of numbers", field="reference_line"
            ) from None
        object.__setattr__(self, "reference_line", reference)
        parts: tuple[tuple[str, type, bool], ...] = (
            ("lane", Lane, False),
            ("ego", Ego, False),
            ("vehicle", Vehicle, False),
            ("options", Options, False),
            ("road", Road, True),
            ("goal", Goal, True),
        )
        for name, kind, optional in parts:
            value = getattr(self, name)
            if not isinstance(value, kind) and not (optional and value is None):
                raise InvalidInputError(f"must be a {kind.__name__}", field=name)
        if reference.ndim == 2:  # any other shape is build_reference's to refuse
            for widths in (self.lane, self.road):
                if widths is not None:
                    _check_count(widths, reference.shape[0])
            if self.road is not None:
                _check_road(self.lane, self.road)
        obstacles = tuple(_checked_obstacle(ob, i) for i, ob in enumerate(self.obstacles))
        object.__setattr__(self, "obstacles", obstacles)


def target_speed(problem: PlanningProblem) -> float:
    """The speed the profile cruises at [m/s]: the options' target (without one, the speed limit, else the
    vehicle's max speed) within the vehicle's max speed."""
    options = problem.options
    target = options.target_speed
    if target is None:
        target = problem.vehicle.max_speed if options.speed_limit is None else options.speed_limit
    return min(target, problem.vehicle.max_speed)


def speed_cap(problem: PlanningProblem) -> float:
    """The fastest the profile may drive [m/s]: ``options.speed_limit`` within the vehicle's max speed (at
    least the target), else the target speed (:func:`target_speed`)."""
    limit = problem.options.speed_limit
    target = target_speed(problem)
    return target if limit is None else max(min(limit, problem.vehicle.max_speed), target)


def _check_count(widths: Lane, points: int) -> None:
    """Per-point widths of a lane or road come one per reference point."""
    for name in ("left_width", "right_width"):
        width = getattr(widths, name)
        if isinstance(width, np.ndarray) and width.shape[0] != points:
            raise InvalidInputError(
                f"has {width.shape[0]} values but reference_line has {points} points; "
                "give one width per reference point or a single number",
                field=f"{widths.KEY}.{name}",
            )


def _check_road(lane: Lane, road: Road) -> None:
    """The road reaches at least as far as the lane on each side, at every reference point."""
    for name in ("left_width", "right_width"):
        lane_w, road_w = np.broadcast_arrays(getattr(lane, name), getattr(road, name))
        narrow = np.flatnonzero(np.atleast_1d(road_w < lane_w))
        if narrow.size:
            i = int(narrow[0])
            per_point = np.ndim(getattr(road, name)) == 1
            at = f"road.{name}.{i}" if per_point else f"road.{name}"
            lane_at = float(np.atleast_1d(lane_w)[i])
            raise InvalidInputError(
                f"is narrower than the lane ({lane_at:g} m{f' at point {i}' if np.ndim(lane_w) else ''}):"
                " the road holds the lane",
                field=at,
            )


def _checked_obstacle(ob: Any, index: int) -> Obstacle:
    """``ob`` (with float arrays), or :class:`InvalidInputError` naming the field as the JSON request
    does (``obstacles.2.circle.radius``, ``obstacles.2.length``, ``obstacles.2.prediction.3.t``)."""
    where = f"obstacles.{index}"
    if isinstance(ob, PolygonObstacle):
        polygon = checks.array(ob.polygon, f"{where}.polygon", (None, 2), min_rows=3)
        return ob if polygon is ob.polygon else dataclasses.replace(ob, polygon=polygon)
    if isinstance(ob, CircleObstacle):
        center = checks.array(ob.center, f"{where}.circle.center", (2,))
        radius = checks.size(ob.radius, f"{where}.circle.radius")
        same = center is ob.center and radius is ob.radius
        return ob if same else dataclasses.replace(ob, center=center, radius=radius)
    if isinstance(ob, DynamicObstacle):
        length = checks.size(ob.length, f"{where}.length")
        width = checks.size(ob.width, f"{where}.width")
        prediction = checks.array(ob.prediction, f"{where}.prediction", (None, 4))
        if prediction.shape[0] > 1:
            step = np.flatnonzero(~(prediction[1:, 0] > prediction[:-1, 0]))
            if step.size:
                at = f"{where}.prediction.{step[0] + 1}.t"
                raise InvalidInputError("t must increase strictly", field=at)
        same = prediction is ob.prediction and length is ob.length and width is ob.width
        return ob if same else dataclasses.replace(ob, length=length, width=width, prediction=prediction)
    raise InvalidInputError("must be a polygon, circle or dynamic obstacle", field=where)
