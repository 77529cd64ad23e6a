"""The planning request of ``/v1/plan`` and ``/v1/candidates``: reference line, lane, obstacles, ego
state, vehicle and options, each with its limits (:mod:`app.limits`) and cross-field checks.

The defaults of the vehicle and the options are the planner's (:class:`planner.problem.Vehicle`,
:class:`planner.problem.Options`); :mod:`app.conversions` turns a request into the planner's problem.
"""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from pydantic import ConfigDict, Discriminator, Field, Tag, field_validator, model_validator, with_config
from pydantic_core import PydanticCustomError
from typing_extensions import TypedDict

from app.limits import (
    MAX_CANDIDATES,
    MAX_HEADING,
    MAX_ID_LENGTH,
    MAX_LANE_WIDTH,
    MAX_OBSTACLE_OUTLINE,
    MAX_OBSTACLE_POINTS,
    MAX_OBSTACLE_SIZE,
    MAX_OBSTACLES,
    MAX_PLAN_HORIZON,
    MAX_POINTS_PER_CANDIDATE,
    MAX_POLYGON_POINTS,
    MAX_PREDICTION_STATES,
    MAX_PREDICTION_TIME,
    MAX_SEED,
    MAX_STEERING_ANGLE,
    MAX_STEERING_RATE,
    MAX_TIME_BUDGET_MS,
    MAX_TOTAL_CANDIDATE_POINTS,
    MAX_TRAJECTORY_STEP,
    MAX_VEHICLE_ACCELERATION,
    MAX_VEHICLE_CURVATURE,
    MAX_VEHICLE_LENGTH,
    MAX_VEHICLE_SPEED,
    MAX_VEHICLE_WIDTH,
    MAX_WHEELBASE,
    MIN_OBSTACLE_SIZE,
    MIN_POINTS_PER_CANDIDATE,
    MIN_POLYGON_AREA,
    MIN_POLYGON_POINTS,
    MIN_STEERING_ANGLE,
    MIN_STEERING_RATE,
    MIN_TIME_BUDGET_MS,
    MIN_TRAJECTORY_STEP,
    MIN_VEHICLE_ACCELERATION,
    MIN_VEHICLE_CURVATURE,
)
from app.models.common import (
    CIRCLE,
    DYNAMIC,
    PER_POINT_WIDTH,
    POLYGON,
    SCALAR_WIDTH,
    Coordinate,
    Point,
    ReferencePolyline,
    RequestModel,
    field_error,
    number,
    polygon_area,
)
from app.models.goal import Goal
from planner import problem as pp

Heading = Annotated[float, number(ge=-MAX_HEADING, le=MAX_HEADING)]
Time = Annotated[float, number(ge=-MAX_PREDICTION_TIME, le=MAX_PREDICTION_TIME)]
Width = Annotated[float, number(ge=0.0, le=MAX_LANE_WIDTH)]
Size = Annotated[float, number(ge=MIN_OBSTACLE_SIZE, le=MAX_OBSTACLE_SIZE)]
Speed = Annotated[float, number(ge=0.0, le=MAX_VEHICLE_SPEED)]
#: a vehicle's acceleration or deceleration limit [m/s²]
AccelerationLimit = Annotated[float, number(ge=MIN_VEHICLE_ACCELERATION, le=MAX_VEHICLE_ACCELERATION)]
ObstacleId = Annotated[str, Field(strict=True, min_length=1, max_length=MAX_ID_LENGTH)]


def _width_kind(value: Any) -> str | None:
    if isinstance(value, list | tuple | np.ndarray):
        return PER_POINT_WIDTH
    if isinstance(value, int | float) and not isinstance(value, bool):
        return SCALAR_WIDTH
    return None


LaneWidth = Annotated[
    Annotated[Width, Tag(SCALAR_WIDTH)] | Annotated[list[Width], Field(fail_fast=True), Tag(PER_POINT_WIDTH)],
    Discriminator(
        _width_kind,
        custom_error_type="width_type",
        custom_error_message="must be a number ≥ 0 or a list with one number per reference point",
    ),
]


class Lane(RequestModel):
    """Lane bounds either side of the reference [m]: one width for the whole lane, or one per
    reference point (interpolated along the reference; 0 allowed)."""

    left_width: LaneWidth = Field(description="Width to the left of the reference [m].")
    right_width: LaneWidth = Field(description="Width to the right of the reference [m].")


class Road(RequestModel):
    """The drivable surface either side of the reference [m], beyond the lane (adjacent lanes of either
    direction, the opposite lane, shoulders): one width for the whole road, or one per reference point,
    like the lane's; on each side at least the lane's. The vehicle keeps to its lane and leaves it for
    the road only to get past what blocks the lane (`diagnostics.decision` says when)."""

    left_width: LaneWidth = Field(description="Width of the road to the left of the reference [m].")
    right_width: LaneWidth = Field(description="Width of the road to the right of the reference [m].")


class PolygonObstacle(RequestModel):
    """A static obstacle given by its outline."""

    id: ObstacleId
    polygon: list[Point] = Field(
        min_length=MIN_POLYGON_POINTS,
        max_length=MAX_POLYGON_POINTS,
        fail_fast=True,
        description=f"Outline [[x, y], …] [m], at least {MIN_POLYGON_POINTS} points enclosing a nonzero "
        "area.",
    )

    @field_validator("polygon")
    @classmethod
    def _non_degenerate(cls, polygon: list[tuple[float, float]]) -> list[tuple[float, float]]:
        if not polygon_area(polygon) > MIN_POLYGON_AREA:
            raise PydanticCustomError(
                "degenerate_polygon",
                "the polygon has no area: its points coincide or are collinear",
            )
        return polygon


class Circle(RequestModel):
    """A disc."""

    center: Point
    radius: Size = Field(description="Radius [m].")


class CircleObstacle(RequestModel):
    """A static disc."""

    id: ObstacleId
    circle: Circle


# a typed dict rather than a model: a request may hold 100 000 of them, and pydantic validates dicts
# several times faster than it builds models
@with_config(ConfigDict(extra="forbid"))
class PredictedState(TypedDict):
    """One predicted state of a moving obstacle's centre."""

    t: Annotated[Time, Field(description="Time [s] (the ego's state is at t = 0).")]
    x: Annotated[Coordinate, Field(description="Centre x [m].")]
    y: Annotated[Coordinate, Field(description="Centre y [m].")]
    heading: Annotated[Heading, Field(description="Heading, counter-clockwise from +x [rad].")]


class DynamicObstacle(RequestModel):
    """A moving box ``length × width`` centred at each predicted state."""

    id: ObstacleId
    length: Size = Field(description="Length [m].")
    width: Size = Field(description="Width [m].")
    prediction: list[PredictedState] = Field(
        min_length=1,
        max_length=MAX_PREDICTION_STATES,
        fail_fast=True,
        description="Predicted states, t strictly increasing.",
    )

    @field_validator("prediction")
    @classmethod
    def _increasing_time(cls, states: list[PredictedState]) -> list[PredictedState]:
        t = np.fromiter((state["t"] for state in states), dtype=float, count=len(states))
        late = np.flatnonzero(~(np.diff(t) > 0.0))
        if late.size:
            i = int(late[0]) + 1
            raise field_error(
                (i, "t"),
                "t_not_increasing",
                f"t must increase strictly: {t[i]} follows {t[i - 1]}",
                t[i],
            )
        return states


#: an obstacle of a request, whichever its shape
AnyObstacle = PolygonObstacle | CircleObstacle | DynamicObstacle


def _outline_length(o: AnyObstacle) -> float:
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


class Ego(RequestModel):
    """The vehicle's current state: its footprint's centre; with a `vehicle.wheelbase` (a car), heading
    is the body's yaw and speed, acceleration and curvature are its rear axle's."""

    x: Coordinate = Field(description="Centre x [m].")
    y: Coordinate = Field(description="Centre y [m].")
    heading: Heading = Field(
        description="Heading, counter-clockwise from +x [rad]: the centre's direction of travel; a car's "
        "body yaw."
    )
    speed: Speed = Field(0.0, description="Speed [m/s] of the centre; of a car's rear axle.")
    acceleration: float = number(
        ge=-MAX_VEHICLE_ACCELERATION,
        le=MAX_VEHICLE_ACCELERATION,
        default=0.0,
        description="Acceleration [m/s²] of the centre; of a car's rear axle.",
    )
    curvature: float | None = number(
        ge=-MAX_VEHICLE_CURVATURE,
        le=MAX_VEHICLE_CURVATURE,
        default=None,
        description="Path curvature [1/m], if known: of the centre's path; of a car's rear axle path "
        "(tan(steering angle) / wheelbase). A moving car whose steering rate is bounded starts every "
        "answer at this steering angle. Unknown: taken to follow the road's, within what the vehicle "
        "can drive at its speed.",
    )


_VEHICLE = pp.Vehicle()
_OPTIONS = pp.Options()


class Vehicle(RequestModel):
    """Vehicle footprint and limits (all positive; the acceleration and curvature limits at least
    0.01 m/s² and 1e-4 1/m).

    Without `wheelbase`, the planner's model is a vehicle whose footprint's centre does not slip (a
    differential-drive robot, say): the footprint turns with the tangent of the centre's path. With
    `wheelbase` (and `rear_axle_offset`), a car: a kinematic single-track vehicle whose rear axle does
    not slip, planned at its rear axle, its footprint placed from there along the body's yaw."""

    model_config = ConfigDict(
        json_schema_extra={
            "description": "Vehicle footprint and limits. Without `wheelbase`: a vehicle whose "
            "footprint's centre does not slip (a differential-drive robot, say). With `wheelbase` and "
            "`rear_axle_offset`: a car (kinematic single-track model), planned at its rear axle; "
            "`rear_axle_offset` is at most half the `length`, and the steering limits need a `wheelbase`."
        }
    )

    length: float = number(gt=0.0, le=MAX_VEHICLE_LENGTH, default=_VEHICLE.length, description="Length [m].")
    width: float = number(gt=0.0, le=MAX_VEHICLE_WIDTH, default=_VEHICLE.width, description="Width [m].")
    max_speed: float = number(
        gt=0.0, le=MAX_VEHICLE_SPEED, default=_VEHICLE.max_speed, description="Speed limit [m/s]."
    )
    max_acceleration: AccelerationLimit = Field(_VEHICLE.max_acceleration, description="[m/s²]")
    max_deceleration: AccelerationLimit = Field(_VEHICLE.max_deceleration, description="[m/s²], positive.")
    max_lateral_acceleration: AccelerationLimit = Field(
        _VEHICLE.max_lateral_acceleration, description="[m/s²]"
    )
    max_curvature: float = number(
        ge=MIN_VEHICLE_CURVATURE,
        le=MAX_VEHICLE_CURVATURE,
        default=_VEHICLE.max_curvature,
        description="[1/m]; of a car's rear axle path with a `wheelbase`.",
    )
    wheelbase: float | None = number(
        gt=0.0,
        le=MAX_WHEELBASE,
        default=None,
        description="A car's wheelbase [m]; null: the point model (a vehicle whose centre does not slip).",
    )
    rear_axle_offset: float | None = number(
        ge=0.0,
        le=MAX_VEHICLE_LENGTH / 2,
        default=None,
        description="How far a car's rear axle lies behind the footprint's centre [m], at most "
        "`length`/2; required with `wheelbase`.",
    )
    max_steering_angle: float | None = number(
        ge=MIN_STEERING_ANGLE,
        le=MAX_STEERING_ANGLE,
        default=None,
        description="A car's largest |steering angle| [rad]; null: atan(`wheelbase` · `max_curvature`).",
    )
    max_steering_rate: float | None = number(
        ge=MIN_STEERING_RATE,
        le=MAX_STEERING_RATE,
        default=None,
        description="A car's largest |steering rate| [rad/s]; null: no bound.",
    )

    @model_validator(mode="after")
    def _car(self) -> Vehicle:
        if self.wheelbase is None:
            for name in ("rear_axle_offset", "max_steering_angle", "max_steering_rate"):
                if getattr(self, name) is not None:
                    raise field_error(
                        (name,), "needs_wheelbase", "needs a wheelbase (a car)", getattr(self, name)
                    )
            return self
        if self.rear_axle_offset is None:
            raise field_error(
                ("rear_axle_offset",),
                "missing",
                "is required with a wheelbase: how far the rear axle lies behind the footprint's centre",
                None,
            )
        if self.rear_axle_offset > 0.5 * self.length:
            raise field_error(
                ("rear_axle_offset",),
                "rear_axle_outside",
                f"{self.rear_axle_offset} m is more than half the length ({0.5 * self.length} m): the rear "
                "axle must lie under the footprint",
                self.rear_axle_offset,
            )
        return self


class Options(RequestModel):
    """Planning options."""

    model_config = ConfigDict(
        json_schema_extra={
            "description": "Planning options; dt may not exceed horizon_time, and num_candidates × "
            f"num_points may not exceed {MAX_TOTAL_CANDIDATE_POINTS} (the size of the candidates' answer)."
        }
    )

    horizon_time: float = number(
        gt=0.0, le=MAX_PLAN_HORIZON, default=_OPTIONS.horizon_time, description="Planning horizon [s]."
    )
    dt: float = number(
        ge=MIN_TRAJECTORY_STEP,
        le=MAX_TRAJECTORY_STEP,
        default=_OPTIONS.dt,
        description="Trajectory sampling step [s].",
    )
    target_speed: float | None = number(
        ge=0.0,
        le=MAX_VEHICLE_SPEED,
        default=_OPTIONS.target_speed,
        description="Desired speed [m/s]; null means the vehicle's max_speed (within speed_limit).",
    )
    speed_limit: float | None = number(
        ge=0.0,
        le=MAX_VEHICLE_SPEED,
        default=_OPTIONS.speed_limit,
        description="Highest speed allowed [m/s], at least target_speed: the vehicle cruises at the target "
        "and may drive faster, up to this, to keep clear of a vehicle from behind or to meet the goal's "
        "time window. null: the target speed is the limit.",
    )
    num_candidates: int = Field(
        _OPTIONS.num_candidates, strict=True, ge=1, le=MAX_CANDIDATES, description="Candidate paths."
    )
    num_points: int = Field(
        _OPTIONS.num_points,
        strict=True,
        ge=MIN_POINTS_PER_CANDIDATE,
        le=MAX_POINTS_PER_CANDIDATE,
        description="Points per candidate.",
    )
    generator: pp.Generator = Field(
        _OPTIONS.generator,
        description="`naive` (Algorithm 4, folds where κ·d ≥ 1) or `transf_kappa` (Algorithm 5).",
    )
    seed: int = Field(_OPTIONS.seed, strict=True, ge=0, le=MAX_SEED, description="Seed of the candidates.")
    return_candidates: bool = Field(
        _OPTIONS.return_candidates, strict=True, description="Include candidates in a plan."
    )
    time_budget_ms: float | None = number(
        ge=MIN_TIME_BUDGET_MS,
        le=MAX_TIME_BUDGET_MS,
        default=None,
        description="Compute budget of a plan [ms]: a stage that ends past it makes the answer a braking "
        "`fallback` saying so. null: the server's default (setting KAPPA_TIME_BUDGET_MS).",
    )

    @model_validator(mode="after")
    def _answer_size(self) -> Options:
        limit, target = self.speed_limit, self.target_speed
        if limit is not None and target is not None and limit < target:
            raise field_error(
                ("speed_limit",),
                "speed_limit_below_target",
                f"speed_limit = {limit} m/s is below target_speed = {target} m/s",
                limit,
            )
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


class PlanningRequest(RequestModel):
    """A planning problem: reference line, lane, obstacles, ego state, vehicle and options."""

    reference_line: ReferencePolyline
    lane: Lane
    obstacles: list[Obstacle] = Field(
        default_factory=list,
        max_length=MAX_OBSTACLES,
        description="Obstacles, ids unique, their outlines at most "
        f"{MAX_OBSTACLE_OUTLINE:.0f} m long in all, at most {MAX_OBSTACLE_POINTS} polygon vertices "
        "and predicted states in all.",
    )
    ego: Ego
    vehicle: Vehicle = Field(default_factory=Vehicle)
    options: Options = Field(default_factory=Options)
    road: Road | None = Field(
        None, description="The whole road beyond the lane; null: the vehicle keeps to its lane."
    )
    goal: Goal | None = Field(None, description="Where to be, when and how fast; null: no goal.")

    @field_validator("obstacles")
    @classmethod
    def _unique_ids(cls, obstacles: list[AnyObstacle]) -> list[AnyObstacle]:
        seen: set[str] = set()
        for i, obstacle in enumerate(obstacles):
            if obstacle.id in seen:
                raise field_error((i, "id"), "duplicate_id", "another obstacle has this id", obstacle.id)
            seen.add(obstacle.id)
        points = sum(
            len(o.polygon) if isinstance(o, PolygonObstacle) else len(o.prediction)
            for o in obstacles
            if not isinstance(o, CircleObstacle)
        )
        if points > MAX_OBSTACLE_POINTS:
            raise PydanticCustomError(
                "obstacles_too_many_points",
                f"the obstacles have {points} polygon vertices and predicted states in all; "
                f"at most {MAX_OBSTACLE_POINTS} are accepted",
            )
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
        for key, widths in (("lane", self.lane), ("road", self.road)):
            for name in ("left_width", "right_width"):
                width = getattr(widths, name, None)
                if isinstance(width, list) and len(width) != n:
                    raise field_error(
                        (key, name),
                        "width_length",
                        f"has {len(width)} values but reference_line has {n} points; "
                        "give one width per reference point or a single number",
                        len(width),
                    )
        if self.road is not None:
            for name in ("left_width", "right_width"):
                lane, road = np.broadcast_arrays(getattr(self.lane, name), getattr(self.road, name))
                narrow = np.flatnonzero(np.atleast_1d(road < lane))
                if narrow.size:
                    i = int(narrow[0])
                    per_point = isinstance(getattr(self.road, name), list)
                    raise field_error(
                        ("road", name, i) if per_point else ("road", name),
                        "road_narrower_than_lane",
                        f"{float(np.atleast_1d(road)[i])} m is narrower than the lane's "
                        f"{float(np.atleast_1d(lane)[i])} m: the road holds the lane",
                        float(np.atleast_1d(road)[i]),
                    )
        return self
