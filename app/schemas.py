"""Request and response models of the HTTP API, their limits, and the converters to the planner.

This is the only module that knows both pydantic and the planner's dataclasses: a request is
validated here (types, finiteness, ranges, lengths, cross-field consistency) and turned into a
:class:`planner.problem.PlanningProblem` by :func:`to_problem`; :func:`from_problem` goes the other
way (the demo endpoint); :func:`candidate_data` and :func:`plan_data` turn the planner's answers into
the JSON data of :class:`CandidatesResponse` and :class:`PlanResponse`. Every limit is declared on its
field, so it shows in the OpenAPI schema.

Scalars are strict: a number must be a JSON number (``"5"`` and ``true`` are refused), an integer a
JSON integer, a flag a JSON boolean. Unknown fields are refused so that a misspelt option is an
error rather than silently ignored. Units: metres [m], seconds [s], radians [rad], metres per second
[m/s].
"""

from __future__ import annotations

from functools import cache
from typing import Annotated, Any, get_args

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic.json_schema import SkipJsonSchema
from pydantic_core import InitErrorDetails, PydanticCustomError

from planner import problem as pp
from planner.candidates import CandidateSet
from planner.pipeline import PlanResult
from planner.pipeline import Status as PlanStatus
from planner.roads import demo_problem
from solvers.result import SolverStatus

# --------------------------------------------------------------------------------------------------
# Limits
# --------------------------------------------------------------------------------------------------

#: largest absolute coordinate [m]
MAX_COORDINATE = 1e7
#: reference line points
MIN_REFERENCE_POINTS, MAX_REFERENCE_POINTS = 2, 20_000
#: longest reference line (sum of its chords) [m]
MAX_REFERENCE_LENGTH = 20_000.0
#: points of one /v1/frenet or /v1/cartesian request
MAX_QUERY_POINTS = 10_000
#: obstacles per request, vertices per polygon, states per prediction
MAX_OBSTACLES, MAX_POLYGON_POINTS, MAX_PREDICTION_STATES = 1000, 1000, 2000
#: smallest polygon area [m²]; below it the polygon is degenerate
MIN_POLYGON_AREA = 1e-6
#: smallest obstacle dimension (circle radius, box length and width) [m]
MIN_OBSTACLE_SIZE = 1e-3
#: longest total outline of a request's obstacles (polygon perimeters, circle circumferences, box
#: perimeters) [m]: a bound on the work one request can ask for (the planner cuts long outlines to the road)
MAX_OBSTACLE_OUTLINE = 20_000.0
#: most points over all candidates (num_candidates × num_points) of one request
MAX_TOTAL_CANDIDATE_POINTS = 200_000
#: largest lane width, obstacle size [m], |heading| [rad], |time| [s], speed [m/s]
MAX_WIDTH, MAX_SIZE, MAX_ANGLE, MAX_TIME, MAX_SPEED = 1000.0, 1000.0, 1000.0, 1e6, 200.0
#: smallest vehicle acceleration limits [m/s²] and curvature limit [1/m]: a vehicle that cannot brake
#: harder than 1 cm/s² or turn tighter than a 10 km radius is no vehicle, and below these the
#: planner's braking distances and curvature bounds overflow
MIN_VEHICLE_ACCELERATION, MIN_VEHICLE_CURVATURE = 0.01, 1e-4
#: limits of a plan's compute budget [ms]
MIN_TIME_BUDGET_MS, MAX_TIME_BUDGET_MS = 1.0, 60_000.0


def _number(
    ge: float | None = None, gt: float | None = None, le: float | None = None, **kw: Any
) -> Any:
    """A strict, finite JSON number field with bounds (ints are accepted, strings and bools not)."""
    return Field(strict=True, allow_inf_nan=False, ge=ge, gt=gt, le=le, **kw)


Coordinate = Annotated[float, _number(ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
Angle = Annotated[float, _number(ge=-MAX_ANGLE, le=MAX_ANGLE)]
Time = Annotated[float, _number(ge=-MAX_TIME, le=MAX_TIME)]
Width = Annotated[float, _number(ge=0.0, le=MAX_WIDTH)]
Size = Annotated[float, _number(ge=MIN_OBSTACLE_SIZE, le=MAX_SIZE)]
Speed = Annotated[float, _number(ge=0.0, le=MAX_SPEED)]
Point = Annotated[tuple[Coordinate, Coordinate], Field(description="[x, y] [m]")]
FrenetPoint = Annotated[tuple[Coordinate, Coordinate], Field(description="[s, d] [m]")]


def field_error(loc: tuple[str | int, ...], kind: str, message: str, value: Any) -> ValidationError:
    """A validation error at ``loc`` (relative to the value validated) for a validator to raise.

    pydantic prefixes the location of the validator, so an error raised on the request for
    ``("lane", "left_width")`` is reported at ``lane.left_width``.
    """
    detail = InitErrorDetails(type=PydanticCustomError(kind, message), loc=loc, input=value)
    return ValidationError.from_exception_data("request", [detail])


def _check_reference(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Refuse a reference longer than :data:`MAX_REFERENCE_LENGTH` (geometry is the planner's check)."""
    step = np.diff(np.asarray(points, dtype=float), axis=0)
    chord = np.linalg.norm(step, axis=1)
    length = float(chord.sum())
    if length > MAX_REFERENCE_LENGTH:
        raise PydanticCustomError(
            "reference_too_long",
            f"the reference line is {length:.0f} m long; "
            f"at most {MAX_REFERENCE_LENGTH:.0f} m is accepted",
        )
    return points


ReferencePolyline = Annotated[
    list[Point],
    Field(
        min_length=MIN_REFERENCE_POINTS,
        max_length=MAX_REFERENCE_POINTS,
        description=(
            "Reference polyline [[x, y], …] [m] in driving order: at least two distinct points, "
            f"at most {MAX_REFERENCE_LENGTH:.0f} m long, never turning straight back (180°)."
        ),
    ),
    AfterValidator(_check_reference),
]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid")


# --------------------------------------------------------------------------------------------------
# Planning request
# --------------------------------------------------------------------------------------------------

#: labels of union members; pydantic puts them in error locations, the error handler drops them
SCALAR_WIDTH, PER_POINT_WIDTH = "<scalar width>", "<per-point widths>"
POLYGON, CIRCLE, DYNAMIC = "<polygon obstacle>", "<circle obstacle>", "<dynamic obstacle>"
UNION_TAGS = frozenset({SCALAR_WIDTH, PER_POINT_WIDTH, POLYGON, CIRCLE, DYNAMIC})


def _width_kind(value: Any) -> str | None:
    if isinstance(value, list | tuple | np.ndarray):
        return PER_POINT_WIDTH
    if isinstance(value, int | float) and not isinstance(value, bool):
        return SCALAR_WIDTH
    return None


LaneWidth = Annotated[
    Annotated[Width, Tag(SCALAR_WIDTH)] | Annotated[list[Width], Tag(PER_POINT_WIDTH)],
    Discriminator(
        _width_kind,
        custom_error_type="width_type",
        custom_error_message="must be a number ≥ 0 or a list with one number per reference point",
    ),
]


class Lane(_Model):
    """Lane bounds either side of the reference [m]: one width for the whole lane, or one per
    reference point (interpolated along the reference; 0 allowed)."""

    left_width: LaneWidth = Field(description="Width to the left of the reference [m].")
    right_width: LaneWidth = Field(description="Width to the right of the reference [m].")


class PolygonObstacle(_Model):
    """A static obstacle given by its outline."""

    id: str = Field(strict=True, min_length=1, max_length=200)
    polygon: list[Point] = Field(
        min_length=3,
        max_length=MAX_POLYGON_POINTS,
        description="Outline [[x, y], …] [m], at least 3 points enclosing a nonzero area.",
    )

    @field_validator("polygon")
    @classmethod
    def _non_degenerate(cls, polygon: list[tuple[float, float]]) -> list[tuple[float, float]]:
        p = np.asarray(polygon, dtype=float)
        p = p - p[0]  # shoelace relative to a vertex: no cancellation far from the origin
        q = np.roll(p, -1, axis=0)
        area = 0.5 * abs(float(np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1])))
        if not area > MIN_POLYGON_AREA:
            raise PydanticCustomError(
                "degenerate_polygon",
                "the polygon has no area: its points coincide or are collinear",
            )
        return polygon


class Circle(_Model):
    """A disc."""

    center: Point
    radius: Size = Field(description="Radius [m].")


class CircleObstacle(_Model):
    """A static disc."""

    id: str = Field(strict=True, min_length=1, max_length=200)
    circle: Circle


class PredictedState(_Model):
    """One predicted state of a moving obstacle's centre."""

    t: Time = Field(description="Time [s] (the ego's state is at t = 0).")
    x: Coordinate = Field(description="Centre x [m].")
    y: Coordinate = Field(description="Centre y [m].")
    heading: Angle = Field(description="Heading, counter-clockwise from +x [rad].")


class DynamicObstacle(_Model):
    """A moving box ``length × width`` centred at each predicted state."""

    id: str = Field(strict=True, min_length=1, max_length=200)
    length: Size = Field(description="Length [m].")
    width: Size = Field(description="Width [m].")
    prediction: list[PredictedState] = Field(
        min_length=1,
        max_length=MAX_PREDICTION_STATES,
        description="Predicted states, t strictly increasing.",
    )

    @field_validator("prediction")
    @classmethod
    def _increasing_time(cls, states: list[PredictedState]) -> list[PredictedState]:
        for i in range(1, len(states)):
            if not states[i].t > states[i - 1].t:
                raise field_error(
                    (i, "t"),
                    "t_not_increasing",
                    f"t must increase strictly: {states[i].t} follows {states[i - 1].t}",
                    states[i].t,
                )
        return states


def _outline_length(o: PolygonObstacle | CircleObstacle | DynamicObstacle) -> float:
    """Length of an obstacle's outline [m]: perimeter, circumference, or its box's perimeter."""
    if isinstance(o, PolygonObstacle):
        p = np.asarray(o.polygon, dtype=float)
        return float(np.linalg.norm(p - np.roll(p, -1, axis=0), axis=1).sum())
    if isinstance(o, CircleObstacle):
        return 2.0 * np.pi * o.circle.radius
    return 2.0 * (o.length + o.width)


def _obstacle_kind(value: Any) -> str | None:
    """The union member of an obstacle: by its one shape key (JSON) or by its class (Python)."""
    if isinstance(value, dict):
        tags = [
            tag
            for key, tag in (("polygon", POLYGON), ("circle", CIRCLE), ("prediction", DYNAMIC))
            if key in value
        ]
        return tags[0] if len(tags) == 1 else None
    for model, tag in (
        (PolygonObstacle, POLYGON),
        (CircleObstacle, CIRCLE),
        (DynamicObstacle, DYNAMIC),
    ):
        if isinstance(value, model):
            return tag
    return None


Obstacle = Annotated[
    Annotated[PolygonObstacle, Tag(POLYGON)]
    | Annotated[CircleObstacle, Tag(CIRCLE)]
    | Annotated[DynamicObstacle, Tag(DYNAMIC)],
    Discriminator(
        _obstacle_kind,
        custom_error_type="obstacle_shape",
        custom_error_message=(
            "an obstacle is an object with exactly one of 'polygon', 'circle' or 'prediction'"
        ),
    ),
]


class Ego(_Model):
    """The vehicle's current state (its geometric centre)."""

    x: Coordinate = Field(description="Centre x [m].")
    y: Coordinate = Field(description="Centre y [m].")
    heading: Angle = Field(description="Heading, counter-clockwise from +x [rad].")
    speed: Speed = Field(0.0, description="Speed [m/s].")
    acceleration: float = _number(
        ge=-100.0, le=100.0, default=0.0, description="Acceleration [m/s²]."
    )
    curvature: float | None = _number(
        ge=-100.0, le=100.0, default=None, description="Path curvature [1/m], if known."
    )


_VEHICLE = pp.Vehicle()
_OPTIONS = pp.Options()


class Vehicle(_Model):
    """Vehicle footprint and limits (all positive; the acceleration and curvature limits at least
    0.01 m/s² and 1e-4 1/m)."""

    length: float = _number(gt=0.0, le=100.0, default=_VEHICLE.length, description="Length [m].")
    width: float = _number(gt=0.0, le=20.0, default=_VEHICLE.width, description="Width [m].")
    max_speed: float = _number(
        gt=0.0, le=MAX_SPEED, default=_VEHICLE.max_speed, description="Speed limit [m/s]."
    )
    max_acceleration: float = _number(
        ge=MIN_VEHICLE_ACCELERATION, le=100.0, default=_VEHICLE.max_acceleration, description="[m/s²]"
    )
    max_deceleration: float = _number(
        ge=MIN_VEHICLE_ACCELERATION,
        le=100.0,
        default=_VEHICLE.max_deceleration,
        description="[m/s²], positive.",
    )
    max_lateral_acceleration: float = _number(
        ge=MIN_VEHICLE_ACCELERATION,
        le=100.0,
        default=_VEHICLE.max_lateral_acceleration,
        description="[m/s²]",
    )
    max_curvature: float = _number(
        ge=MIN_VEHICLE_CURVATURE, le=100.0, default=_VEHICLE.max_curvature, description="[1/m]"
    )


class Options(_Model):
    """Planning options."""

    model_config = ConfigDict(
        json_schema_extra={
            "description": "Planning options; dt may not exceed horizon_time, and num_candidates × "
            f"num_points may not exceed {MAX_TOTAL_CANDIDATE_POINTS} (the size of the candidates' answer)."
        }
    )

    horizon_time: float = _number(
        gt=0.0, le=20.0, default=_OPTIONS.horizon_time, description="Planning horizon [s]."
    )
    dt: float = _number(
        ge=0.02, le=1.0, default=_OPTIONS.dt, description="Trajectory sampling step [s]."
    )
    target_speed: float | None = _number(
        ge=0.0,
        le=MAX_SPEED,
        default=_OPTIONS.target_speed,
        description="Desired speed [m/s]; null means the vehicle's max_speed.",
    )
    num_candidates: int = Field(
        _OPTIONS.num_candidates, strict=True, ge=1, le=2000, description="Candidate paths."
    )
    num_points: int = Field(
        _OPTIONS.num_points, strict=True, ge=10, le=1000, description="Points per candidate."
    )
    generator: pp.Generator = Field(
        _OPTIONS.generator,
        description="`naive` (Algorithm 4, folds where κ·d ≥ 1) or `transf_kappa` (Algorithm 5).",
    )
    seed: int = Field(
        _OPTIONS.seed, strict=True, ge=0, le=2**32 - 1, description="Seed of the candidates."
    )
    return_candidates: bool = Field(
        _OPTIONS.return_candidates, strict=True, description="Include candidates in a plan."
    )
    time_budget_ms: float | None = _number(
        ge=MIN_TIME_BUDGET_MS,
        le=MAX_TIME_BUDGET_MS,
        default=None,
        description="Compute budget of a plan [ms]: a stage that ends past it makes the answer a braking "
        "`fallback` saying so. null: the server's default (setting KAPPA_TIME_BUDGET_MS).",
    )

    @model_validator(mode="after")
    def _answer_size(self) -> Options:
        if self.dt > self.horizon_time:
            raise field_error(
                ("dt",),
                "dt_above_horizon",
                f"dt = {self.dt} s is longer than horizon_time = {self.horizon_time} s: the trajectory "
                "would be its start alone",
                self.dt,
            )
        total = self.num_candidates * self.num_points
        if total > MAX_TOTAL_CANDIDATE_POINTS:
            raise field_error(
                ("num_points",),
                "too_many_points",
                f"num_candidates × num_points = {total}; at most {MAX_TOTAL_CANDIDATE_POINTS}",
                self.num_points,
            )
        return self


class PlanningRequest(_Model):
    """A planning problem: reference line, lane, obstacles, ego state, vehicle and options."""

    reference_line: ReferencePolyline
    lane: Lane
    obstacles: list[Obstacle] = Field(
        default_factory=list,
        max_length=MAX_OBSTACLES,
        description="Obstacles, ids unique, their outlines at most "
        f"{MAX_OBSTACLE_OUTLINE:.0f} m long in all.",
    )
    ego: Ego
    vehicle: Vehicle = Field(default_factory=Vehicle)
    options: Options = Field(default_factory=Options)

    @field_validator("obstacles")
    @classmethod
    def _unique_ids(
        cls, obstacles: list[PolygonObstacle | CircleObstacle | DynamicObstacle]
    ) -> list[PolygonObstacle | CircleObstacle | DynamicObstacle]:
        seen: set[str] = set()
        for i, obstacle in enumerate(obstacles):
            if obstacle.id in seen:
                raise field_error(
                    (i, "id"), "duplicate_id", "another obstacle has this id", obstacle.id
                )
            seen.add(obstacle.id)
        total = sum(_outline_length(o) for o in obstacles)
        if total > MAX_OBSTACLE_OUTLINE:
            raise PydanticCustomError(
                "obstacles_too_large",
                f"the obstacles' outlines are {total:.0f} m long in all; "
                f"at most {MAX_OBSTACLE_OUTLINE:.0f} m is accepted",
            )
        return obstacles

    @model_validator(mode="after")
    def _widths_match_reference(self) -> PlanningRequest:
        n = len(self.reference_line)
        for name in ("left_width", "right_width"):
            width = getattr(self.lane, name)
            if isinstance(width, list) and len(width) != n:
                raise field_error(
                    ("lane", name),
                    "width_length",
                    f"has {len(width)} values but reference_line has {n} points; "
                    "give one width per reference point or a single number",
                    len(width),
                )
        return self


# --------------------------------------------------------------------------------------------------
# Converters
# --------------------------------------------------------------------------------------------------


def _array(value: Any) -> Any:
    return np.asarray(value, dtype=float) if isinstance(value, list) else float(value)


def _obstacle_to_problem(
    o: PolygonObstacle | CircleObstacle | DynamicObstacle,
) -> pp.Obstacle:
    if isinstance(o, PolygonObstacle):
        return pp.PolygonObstacle(id=o.id, polygon=np.asarray(o.polygon, dtype=float))
    if isinstance(o, CircleObstacle):
        return pp.CircleObstacle(
            id=o.id, center=np.asarray(o.circle.center, dtype=float), radius=o.circle.radius
        )
    states = np.array([[p.t, p.x, p.y, p.heading] for p in o.prediction], dtype=float)
    return pp.DynamicObstacle(id=o.id, length=o.length, width=o.width, prediction=states)


def to_problem(request: PlanningRequest, *, time_budget_ms: float | None = None) -> pp.PlanningProblem:
    """The planner's :class:`~planner.problem.PlanningProblem` of a validated request;
    ``time_budget_ms`` [ms] stands in for a budget the request leaves out."""
    options = request.options.model_dump()
    if options["time_budget_ms"] is None:
        options["time_budget_ms"] = time_budget_ms
    return pp.PlanningProblem(
        reference_line=np.asarray(request.reference_line, dtype=float),
        lane=pp.Lane(
            left_width=_array(request.lane.left_width),
            right_width=_array(request.lane.right_width),
        ),
        ego=pp.Ego(**request.ego.model_dump()),
        obstacles=tuple(_obstacle_to_problem(o) for o in request.obstacles),
        vehicle=pp.Vehicle(**request.vehicle.model_dump()),
        options=pp.Options(**options),
    )


def _points(array: Any) -> list[tuple[float, float]]:
    return [(float(x), float(y)) for x, y in np.asarray(array, dtype=float).tolist()]


def _width_from_problem(width: Any) -> float | list[float]:
    arr = np.asarray(width, dtype=float)
    return float(arr) if arr.ndim == 0 else [float(w) for w in arr.tolist()]


def _obstacle_from_problem(o: pp.Obstacle) -> PolygonObstacle | CircleObstacle | DynamicObstacle:
    if isinstance(o, pp.PolygonObstacle):
        return PolygonObstacle(id=o.id, polygon=_points(o.polygon))
    if isinstance(o, pp.CircleObstacle):
        x, y = (float(v) for v in np.asarray(o.center, dtype=float))
        return CircleObstacle(id=o.id, circle=Circle(center=(x, y), radius=float(o.radius)))
    states = [
        PredictedState(t=t, x=x, y=y, heading=h)
        for t, x, y, h in np.asarray(o.prediction, dtype=float).tolist()
    ]
    return DynamicObstacle(id=o.id, length=float(o.length), width=float(o.width), prediction=states)


def from_problem(problem: pp.PlanningProblem) -> PlanningRequest:
    """The request that :func:`to_problem` turns into ``problem`` (validated like any request).

    ``Options.lateral_margin`` and ``Options.min_path_length`` are not part of the HTTP contract and
    are dropped.
    """
    o = problem.options
    return PlanningRequest(
        reference_line=_points(problem.reference_line),
        lane=Lane(
            left_width=_width_from_problem(problem.lane.left_width),
            right_width=_width_from_problem(problem.lane.right_width),
        ),
        obstacles=[_obstacle_from_problem(ob) for ob in problem.obstacles],
        ego=Ego(
            x=problem.ego.x,
            y=problem.ego.y,
            heading=problem.ego.heading,
            speed=problem.ego.speed,
            acceleration=problem.ego.acceleration,
            curvature=problem.ego.curvature,
        ),
        vehicle=Vehicle(**{k: getattr(problem.vehicle, k) for k in Vehicle.model_fields}),
        options=Options(**{k: getattr(o, k) for k in Options.model_fields}),
    )


# --------------------------------------------------------------------------------------------------
# Coordinates
# --------------------------------------------------------------------------------------------------


class FrenetRequest(_Model):
    """Cartesian points to express in the Frenet frame of a reference line."""

    reference_line: ReferencePolyline
    points: list[Point] = Field(
        min_length=1, max_length=MAX_QUERY_POINTS, description="Cartesian points [[x, y], …] [m]."
    )


class _Response(BaseModel):
    """An answer: a non-finite number in it is a bug of the server, never sent as null."""

    model_config = ConfigDict(allow_inf_nan=False)


class FrenetResponse(_Response):
    """Frenet coordinates, one pair per requested point."""

    s: list[float] = Field(description="Arc length along the reference [m].")
    d: list[float] = Field(description="Signed lateral offset, positive to the left [m].")


class CartesianRequest(_Model):
    """Frenet coordinates to express in Cartesian coordinates."""

    reference_line: ReferencePolyline
    frenet: list[FrenetPoint] = Field(
        min_length=1, max_length=MAX_QUERY_POINTS, description="Frenet points [[s, d], …] [m]."
    )


class CartesianResponse(_Response):
    """Cartesian points, one per requested Frenet pair."""

    points: list[tuple[float, float]] = Field(description="[[x, y], …] [m].")


# --------------------------------------------------------------------------------------------------
# Candidates
# --------------------------------------------------------------------------------------------------


class CandidatePoint(_Response):
    """One point of a candidate path, in both frames."""

    s: float = Field(description="Arc length [m].")
    d: float = Field(description="Lateral offset, positive to the left [m].")
    x: float = Field(description="x [m].")
    y: float = Field(description="y [m].")


class Candidate(_Response):
    """One candidate path: the points it keeps, in driving order."""

    points: list[CandidatePoint]
    repaired: bool = Field(description="Whether TransF-κ repaired or jumped any of its points.")


class CandidatesDiagnostics(_Response):
    """Figures about the reference and the generated candidates."""

    generated: int = Field(description="Number of candidates generated.")
    repaired: int = Field(description="Number of candidates with repaired or jumped points.")
    generator: pp.Generator
    reference_samples: int = Field(description="Samples of the uniformly resampled reference.")
    reference_spacing: float = Field(description="Arc length between samples [m].")
    reference_length: float = Field(description="Arc length of the reference [m].")
    reference_max_curvature: float = Field(description="Largest |κ| of the reference [1/m].")
    ego_s: float = Field(description="Ego's arc length on the reference [m].")
    ego_d: float = Field(description="Ego's lateral offset [m].")
    kept_points: int = Field(description="Points kept over all candidates.")


class CandidatesResponse(_Response):
    """Candidate paths and diagnostics."""

    candidates: list[Candidate]
    diagnostics: CandidatesDiagnostics


def require_finite(what: str, *arrays: Any) -> None:
    """Raise ``ValueError`` (a bug of the server: answered 500) if any of ``arrays`` is not finite."""
    for array in arrays:
        if not np.isfinite(np.asarray(array, dtype=float)).all():
            raise ValueError(f"{what} holds a non-finite number")


def candidate_data(cs: CandidateSet) -> list[dict[str, Any]]:
    """The kept points of every candidate of ``cs`` in driving order, as the JSON data of
    ``list[Candidate]`` (plain lists and dicts: no model per point; finiteness checked on the arrays).
    """
    keep = cs.valid
    require_finite("a candidate", cs.s[keep], cs.d[keep], cs.xy[keep])
    out: list[dict[str, Any]] = []
    for i in range(cs.count):
        s, d, xy = cs.points(i)
        points = [
            {"s": a, "d": b, "x": x, "y": y}
            for a, b, x, y in zip(s.tolist(), d.tolist(), xy[:, 0].tolist(), xy[:, 1].tolist(), strict=True)
        ]
        out.append({"points": points, "repaired": bool(cs.repaired[i])})
    return out


# --------------------------------------------------------------------------------------------------
# Plan
# --------------------------------------------------------------------------------------------------


class TrajectoryPoint(_Response):
    """One sample of the planned motion of the vehicle's centre."""

    t: float = Field(description="Time from now [s]; the first point is the ego at t = 0.")
    x: float = Field(description="Centre x [m].")
    y: float = Field(description="Centre y [m].")
    heading: float = Field(
        description="Heading, counter-clockwise from +x [rad]; continuous along the trajectory (not "
        "wrapped to [-π, π])."
    )
    curvature: float = Field(description="Path curvature, positive to the left [1/m].")
    v: float = Field(description="Speed [m/s], never negative.")
    a: float = Field(description="Acceleration along the path [m/s²].")
    s: float = Field(description="Arc length on the reference [m].")
    d: float = Field(description="Lateral offset from the reference, positive to the left [m].")


class CandidateCounts(_Response):
    """How many candidate paths were generated, repaired by TransF-κ, and clear of static obstacles."""

    generated: int = Field(description="Candidates generated.")
    repaired: int = Field(description="Candidates with repaired or jumped points.")
    collision_free: int = Field(description="Candidates clear of every static obstacle.")


class LateralSolveInfo(_Response):
    """How the lateral QP (offset d along the path) went."""

    status: SolverStatus
    iterations: int = Field(description="Iterations of the QP solver (0 when it did not run).")
    solve_time_ms: float = Field(description="Wall time of the solve [ms].")


class SpeedSolveInfo(_Response):
    """How the speed profile went (`failed` when it did not run because the lateral QP failed)."""

    status: SolverStatus
    solve_time_ms: float = Field(description="Wall time of the solve [ms].")


class PlanTiming(_Response):
    """Wall time of the planner's stages [ms]; 0 for a stage that did not run."""

    total: float = Field(description="All stages.")
    reference: float = Field(description="Reference line and the ego's Frenet state.")
    candidates: float = Field(description="Candidate paths, their collision check and the choice.")
    lateral: float = Field(description="Lateral bounds and the lateral QP.")
    speed: float = Field(description="Speed profile.")


class PlanDiagnostics(_Response):
    """What each stage of the planner did."""

    candidates: CandidateCounts
    lateral_qp: LateralSolveInfo
    speed: SpeedSolveInfo
    timing_ms: PlanTiming


class PlanResponse(_Response):
    """A planned trajectory, how it came about and, on request, the candidates behind it."""

    status: PlanStatus = Field(
        description="`ok`: planned; `stopped`: the road ahead is blocked and the trajectory stops "
        "before it; `fallback`: a stage failed or its result broke a check, and the trajectory brakes "
        "along the best path known."
    )
    message: str = Field(description="Why, in words.")
    trajectory: list[TrajectoryPoint] = Field(
        description="Samples at t = 0 (the ego), `options.dt`, 2·`options.dt`, … up to "
        "`options.horizon_time`."
    )
    candidates: list[Candidate] | SkipJsonSchema[None] = Field(
        None,
        description="The candidate paths (as `/v1/candidates` answers them); the key is present only "
        "when `options.return_candidates` is true.",
    )
    diagnostics: PlanDiagnostics


_TRAJECTORY_FIELDS = tuple(TrajectoryPoint.model_fields)
_TIMING_FIELDS = tuple(PlanTiming.model_fields)


def plan_data(result: PlanResult) -> dict[str, Any]:
    """The answer to :func:`planner.pipeline.plan`'s ``result`` as the JSON data of
    :class:`PlanResponse` (plain lists and dicts built from the arrays, ready for
    ``pydantic_core.to_json``; ``candidates`` only when the planner returned them).

    A non-finite number or an unknown solver status is a bug and raises ``ValueError``.
    """
    if result.status not in get_args(PlanStatus):
        raise ValueError(f"unknown plan status {result.status!r}")
    traj = result.trajectory
    columns = [np.asarray(getattr(traj, name), dtype=float) for name in _TRAJECTORY_FIELDS]
    require_finite("the trajectory", *columns)
    rows = zip(*(c.tolist() for c in columns), strict=True)
    diag = result.diagnostics
    timing = [float(diag.timing_ms.get(name, 0.0)) for name in _TIMING_FIELDS]
    require_finite("the diagnostics", diag.lateral_qp.solve_time_ms, diag.speed.solve_time_ms, timing)
    data: dict[str, Any] = {
        "status": result.status,
        "message": str(result.message),
        "trajectory": [dict(zip(_TRAJECTORY_FIELDS, row, strict=True)) for row in rows],
    }
    if result.candidates is not None:
        data["candidates"] = candidate_data(result.candidates)
    data["diagnostics"] = {
        "candidates": {
            "generated": int(diag.candidates.generated),
            "repaired": int(diag.candidates.repaired),
            "collision_free": int(diag.candidates.collision_free),
        },
        "lateral_qp": {
            "status": SolverStatus(diag.lateral_qp.status).value,
            "iterations": int(diag.lateral_qp.iterations),
            "solve_time_ms": float(diag.lateral_qp.solve_time_ms),
        },
        "speed": {
            "status": SolverStatus(diag.speed.status).value,
            "solve_time_ms": float(diag.speed.solve_time_ms),
        },
        "timing_ms": dict(zip(_TIMING_FIELDS, timing, strict=True)),
    }
    return data


@cache
def demo_request() -> PlanningRequest:
    """The built-in demo problem (:func:`planner.roads.demo_problem`) as a request."""
    return from_problem(demo_problem())
