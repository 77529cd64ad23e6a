"""The planning request's optional ``goal``: where to be, when and how fast (:class:`planner.goal.Goal`).

``{"position": {"polygon": [[x, y], …]} | {"circle": {"center": [x, y], "radius": r}},
"time": [t_min, t_max], "speed": [v_min, v_max]}``, every key optional; times in seconds from now.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import Discriminator, Field, Tag, field_validator
from pydantic_core import PydanticCustomError

from app.limits import (
    MAX_OBSTACLE_SIZE,
    MAX_POLYGON_POINTS,
    MAX_PREDICTION_TIME,
    MAX_VEHICLE_SPEED,
    MIN_OBSTACLE_SIZE,
    MIN_POLYGON_AREA,
    MIN_POLYGON_POINTS,
)
from app.models.common import GOAL_CIRCLE, GOAL_POLYGON, Point, RequestModel, number, polygon_area

GoalTime = Annotated[float, number(ge=-MAX_PREDICTION_TIME, le=MAX_PREDICTION_TIME)]
GoalSpeed = Annotated[float, number(ge=0.0, le=MAX_VEHICLE_SPEED)]


class GoalPolygon(RequestModel):
    """A goal region given by its outline."""

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
                "degenerate_polygon", "the polygon has no area: its points coincide or are collinear"
            )
        return polygon


class GoalDisc(RequestModel):
    """A disc."""

    center: Point
    radius: float = number(ge=MIN_OBSTACLE_SIZE, le=MAX_OBSTACLE_SIZE, description="Radius [m].")


class GoalCircle(RequestModel):
    """A goal region given as a disc."""

    circle: GoalDisc


def _position_kind(value: Any) -> str | None:
    """The union member of a position: by its one shape key (JSON) or by its class (Python)."""
    if isinstance(value, dict):
        tags = [tag for key, tag in (("polygon", GOAL_POLYGON), ("circle", GOAL_CIRCLE)) if key in value]
        return tags[0] if len(tags) == 1 else None
    if isinstance(value, GoalPolygon):
        return GOAL_POLYGON
    if isinstance(value, GoalCircle):
        return GOAL_CIRCLE
    return None


GoalPosition = Annotated[
    Annotated[GoalPolygon, Tag(GOAL_POLYGON)] | Annotated[GoalCircle, Tag(GOAL_CIRCLE)],
    Discriminator(
        _position_kind,
        custom_error_type="goal_position_shape",
        custom_error_message="a goal position is an object with exactly one of 'polygon' or 'circle'",
    ),
]


class Goal(RequestModel):
    """Where to be, when and how fast; every key optional. The goal is met at a time t of the trajectory
    when the vehicle is inside `position`, t inside `time` and its speed inside `speed`, for each key
    given; `diagnostics.goal` says whether the plan meets it."""

    position: GoalPosition | None = Field(None, description="The goal region: a polygon or a circle.")
    time: tuple[GoalTime, GoalTime] | None = Field(
        None, description="Time window [t_min, t_max] [s] from now (the ego's state is at t = 0)."
    )
    speed: tuple[GoalSpeed, GoalSpeed] | None = Field(
        None,
        description="Speed range [v_min, v_max] [m/s]; a range from 0 to below 1 m/s means: stop inside.",
    )

    @field_validator("time", "speed")
    @classmethod
    def _ordered(cls, interval: tuple[float, float] | None) -> tuple[float, float] | None:
        if interval is not None and interval[0] > interval[1]:
            raise PydanticCustomError(
                "interval_order", f"the low end {interval[0]:g} is above the high end {interval[1]:g}"
            )
        return interval
