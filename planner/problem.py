"""The planning problem as plain frozen dataclasses over numpy arrays (no pydantic here).

The HTTP layer (`app/`) validates a request and converts it into a :class:`PlanningProblem`; the
planner never sees JSON. Units: metres [m], seconds [s], radians [rad], metres per second [m/s].
A trajectory point is the vehicle's geometric centre; ``heading`` is counter-clockwise from +x.

A :class:`Vehicle` checks its fields when it is built and a :class:`PlanningProblem` checks its
obstacles; what they refuse raises :class:`~planner.errors.InvalidInputError` naming the field
(``vehicle.max_deceleration``, ``obstacles.2.circle.radius``). Everything they accept the planner
handles: a vanishing obstacle is a point, a braking distance too long to matter is capped.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from planner.errors import InvalidInputError
from planner.reference import FloatArray

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
    """Lane bounds: width to the left and right of the reference [m]; scalar or one per input point."""

    left_width: float | FloatArray
    right_width: float | FloatArray


@dataclass(frozen=True)
class Ego:
    """The vehicle's current state: centre position [m], heading [rad], speed [m/s], acceleration
    [m/s²] and, if known, path curvature [1/m]."""

    x: float
    y: float
    heading: float
    speed: float = 0.0
    acceleration: float = 0.0
    curvature: float | None = None


#: the smallest positive normal float; an acceleration or curvature limit below it is a denormal
SMALLEST_LIMIT = float(np.finfo(np.float64).tiny)
#: the limits of :class:`Vehicle` whose reciprocals the planner takes (braking distances ``v²/a``, time
#: to reach a speed ``v/a``, turning radius ``1/κ``): they must be normal floats
RECIPROCAL_LIMITS = ("max_acceleration", "max_deceleration", "max_lateral_acceleration", "max_curvature")
#: largest vehicle or obstacle dimension [m]: longer than the equator (4·10⁷ m), so no real object's;
#: far beyond it the squares of lengths overflow
MAX_SIZE = 1e8
#: largest acceleration limit [m/s²]: about 1000 g, which no vehicle's tyres transmit nor occupants
#: survive (road vehicles reach about 1 g); far beyond it the speed profile's braking terms overflow
MAX_ACCELERATION = 1e4
#: the fields of :class:`Vehicle` with an upper bound, and the bound
_VEHICLE_MAXIMA = {
    "length": MAX_SIZE,
    "width": MAX_SIZE,
    "max_acceleration": MAX_ACCELERATION,
    "max_deceleration": MAX_ACCELERATION,
    "max_lateral_acceleration": MAX_ACCELERATION,
}


def _number(value: Any, where: str) -> float:
    """``value`` as a finite float, or :class:`InvalidInputError` naming ``where``."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidInputError("must be a number", field=where)
    number = float(value)
    if not math.isfinite(number):
        raise InvalidInputError("must be finite", field=where)
    return number


@dataclass(frozen=True)
class Vehicle:
    """Vehicle footprint [m] and limits: speed [m/s], accelerations [m/s²], curvature [1/m].

    Every field must be positive and finite. The acceleration and curvature limits
    (:data:`RECIPROCAL_LIMITS`) must moreover be *normal* floats (at least :data:`SMALLEST_LIMIT`,
    ≈ 2.2·10⁻³⁰⁸): a denormal such as ``5e-324`` is no measurement of a vehicle, it has lost its
    precision, and its reciprocal (a braking distance ``v²/a``, a turning radius ``1/κ``) overflows.
    Tiny normal limits are accepted: the planner caps the distances they imply. ``length`` and
    ``width`` are at most :data:`MAX_SIZE`, the accelerations at most :data:`MAX_ACCELERATION`;
    ``max_speed`` and ``max_curvature`` have no upper bound (a vehicle that turns on the spot has
    an unbounded curvature limit).

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

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            where = f"vehicle.{f.name}"
            value = _number(getattr(self, f.name), where)
            if not value > 0.0:
                raise InvalidInputError("must be positive", field=where)
            if value < SMALLEST_LIMIT and f.name in RECIPROCAL_LIMITS:
                raise InvalidInputError(
                    f"{value:g} is a denormal, not a vehicle limit (at least {SMALLEST_LIMIT:.3g})",
                    field=where,
                )
            if value > _VEHICLE_MAXIMA.get(f.name, np.inf):
                raise InvalidInputError(f"must be at most {_VEHICLE_MAXIMA[f.name]:g}", field=where)


@dataclass(frozen=True)
class Options:
    """Planning options.

    Attributes:
        horizon_time: planning horizon [s].
        dt: trajectory sampling step [s].
        target_speed: desired speed [m/s]; ``None`` means the vehicle's max speed.
        num_candidates: candidate lateral profiles to generate.
        num_points: points per candidate.
        generator: ``naive`` (Algorithm 4) or ``transf_kappa`` (Algorithm 5).
        seed: seed of the candidates' random end offsets and lengths.
        return_candidates: include the candidates in the answer.
        lateral_margin: clearance kept from the lane edges and obstacles [m].
        min_path_length: shortest path the candidates cover [m].
        time_budget_ms: wall-clock budget of one plan [ms]; a stage that ends past it makes the answer
            a braking ``fallback`` saying so. ``None``: no budget.
    """

    horizon_time: float = 8.0
    dt: float = 0.1
    target_speed: float | None = None
    num_candidates: int = 32
    num_points: int = 100
    generator: Generator = "transf_kappa"
    seed: int = 0
    return_candidates: bool = False
    lateral_margin: float = 0.2
    min_path_length: float = 20.0
    time_budget_ms: float | None = None


@dataclass(frozen=True)
class PlanningProblem:
    """Everything one plan needs: reference polyline (n, 2) [m] in driving order, lane, obstacles,
    ego state, vehicle and options."""

    reference_line: FloatArray
    lane: Lane
    ego: Ego
    obstacles: tuple[Obstacle, ...] = ()
    vehicle: Vehicle = field(default_factory=Vehicle)
    options: Options = field(default_factory=Options)

    def __post_init__(self) -> None:
        object.__setattr__(self, "reference_line", np.asarray(self.reference_line, dtype=float))
        if not isinstance(self.vehicle, Vehicle):
            raise InvalidInputError("must be a Vehicle", field="vehicle")
        obstacles = tuple(_checked_obstacle(ob, i) for i, ob in enumerate(self.obstacles))
        object.__setattr__(self, "obstacles", obstacles)


def _array(value: Any, where: str, shape: tuple[int | None, ...], *, min_rows: int = 1) -> FloatArray:
    """``value`` as a finite float array of ``shape`` (``None``: any length, at least ``min_rows``);
    ``value`` itself when it is one already."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError("must be an array of numbers", field=where) from None
    if arr.ndim != len(shape) or (shape[-1] is not None and arr.shape[-1] != shape[-1]):
        wanted = " × ".join("k" if n is None else str(n) for n in shape)
        raise InvalidInputError(f"must have shape ({wanted}), not {arr.shape}", field=where)
    if arr.ndim and arr.shape[0] < min_rows:
        raise InvalidInputError(f"needs at least {min_rows} rows, has {arr.shape[0]}", field=where)
    if not np.isfinite(arr).all():
        raise InvalidInputError("must be finite", field=where)
    return arr


def _size(value: Any, where: str) -> float:
    """A size [m] in ``[0, MAX_SIZE]``; zero (or a size below rounding) makes the obstacle a point or a
    segment."""
    size = _number(value, where)
    if not 0.0 <= size <= MAX_SIZE:
        raise InvalidInputError(f"must be between 0 and {MAX_SIZE:g} m", field=where)
    return size


def _checked_obstacle(ob: Any, index: int) -> Obstacle:
    """``ob`` (with float arrays), or :class:`InvalidInputError` naming the field as the JSON request
    does (``obstacles.2.circle.radius``, ``obstacles.2.length``, ``obstacles.2.prediction.3.t``)."""
    where = f"obstacles.{index}"
    if isinstance(ob, PolygonObstacle):
        polygon = _array(ob.polygon, f"{where}.polygon", (None, 2), min_rows=3)
        return ob if polygon is ob.polygon else dataclasses.replace(ob, polygon=polygon)
    if isinstance(ob, CircleObstacle):
        center = _array(ob.center, f"{where}.circle.center", (2,))
        radius = _size(ob.radius, f"{where}.circle.radius")
        same = center is ob.center and radius is ob.radius
        return ob if same else dataclasses.replace(ob, center=center, radius=radius)
    if isinstance(ob, DynamicObstacle):
        length = _size(ob.length, f"{where}.length")
        width = _size(ob.width, f"{where}.width")
        prediction = _array(ob.prediction, f"{where}.prediction", (None, 4))
        if prediction.shape[0] > 1:
            step = np.flatnonzero(~(prediction[1:, 0] > prediction[:-1, 0]))
            if step.size:
                at = f"{where}.prediction.{step[0] + 1}.t"
                raise InvalidInputError("t must increase strictly", field=at)
        same = prediction is ob.prediction and length is ob.length and width is ob.width
        return ob if same else dataclasses.replace(ob, length=length, width=width, prediction=prediction)
    raise InvalidInputError("must be a polygon, circle or dynamic obstacle", field=where)
