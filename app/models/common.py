"""What the models of every resource share: the base models, the strict number field, the scalar
types with their limits (:mod:`app.limits`), the reference polyline, and the validation error a
validator raises.

Scalars are strict: a number must be a JSON number (``"5"`` and ``true`` are refused), an integer a
JSON integer, a flag a JSON boolean. Unknown fields of a request are refused so that a misspelt option
is an error rather than silently ignored. Units: metres [m], seconds [s], radians [rad], metres per
second [m/s].
"""

from __future__ import annotations

from typing import Annotated, Any

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError
from pydantic_core import InitErrorDetails, PydanticCustomError

from app.limits import (
    MAX_COORDINATE,
    MAX_REFERENCE_LENGTH,
    MAX_REFERENCE_POINTS,
    MIN_REFERENCE_POINTS,
)

#: labels of union members (lane widths, obstacles, goal positions); pydantic puts them in error
#: locations, the error handler drops them
SCALAR_WIDTH, PER_POINT_WIDTH = "<scalar width>", "<per-point widths>"
POLYGON, CIRCLE, DYNAMIC = "<polygon obstacle>", "<circle obstacle>", "<dynamic obstacle>"
GOAL_POLYGON, GOAL_CIRCLE = "<goal polygon>", "<goal circle>"
UNION_TAGS = frozenset({SCALAR_WIDTH, PER_POINT_WIDTH, POLYGON, CIRCLE, DYNAMIC, GOAL_POLYGON, GOAL_CIRCLE})


class RequestModel(BaseModel):
    """A request body or a part of one: unknown fields are refused."""

    model_config = ConfigDict(extra="forbid")


class ResponseModel(BaseModel):
    """An answer: a non-finite number in it is a bug of the server, never sent as null."""

    model_config = ConfigDict(allow_inf_nan=False)


def number(ge: float | None = None, gt: float | None = None, le: float | None = None, **kw: Any) -> Any:
    """A strict, finite JSON number field with bounds (ints are accepted, strings and bools not)."""
    return Field(strict=True, allow_inf_nan=False, ge=ge, gt=gt, le=le, **kw)


Coordinate = Annotated[float, number(ge=-MAX_COORDINATE, le=MAX_COORDINATE)]
Point = Annotated[tuple[Coordinate, Coordinate], Field(description="[x, y] [m]")]
FrenetPoint = Annotated[tuple[Coordinate, Coordinate], Field(description="[s, d] [m]")]


def polygon_area(polygon: list[tuple[float, float]]) -> float:
    """Area enclosed by a polygon's outline [m²] (shoelace, relative to a vertex: no cancellation far
    from the origin)."""
    p = np.asarray(polygon, dtype=float)
    p = p - p[0]
    q = np.roll(p, -1, axis=0)
    return 0.5 * abs(float(np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1])))


def field_error(loc: tuple[str | int, ...], kind: str, message: str, value: Any) -> ValidationError:
    """A validation error at ``loc`` (relative to the value validated) for a validator to raise.

    pydantic prefixes the location of the validator, so an error raised on the request for
    ``("lane", "left_width")`` is reported at ``lane.left_width``.
    """
    detail = InitErrorDetails(type=PydanticCustomError(kind, message), loc=loc, input=value)
    return ValidationError.from_exception_data("request", [detail])


def _check_reference(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Refuse a reference longer than :data:`MAX_REFERENCE_LENGTH` (geometry is the planner's check)."""
    chord = np.linalg.norm(np.diff(np.asarray(points, dtype=float), axis=0), axis=1)
    length = float(chord.sum())
    if length > MAX_REFERENCE_LENGTH:
        raise PydanticCustomError(
            "reference_too_long",
            f"the reference line is {length:.0f} m long; at most {MAX_REFERENCE_LENGTH:.0f} m is accepted",
        )
    return points


ReferencePolyline = Annotated[
    list[Point],
    Field(
        min_length=MIN_REFERENCE_POINTS,
        max_length=MAX_REFERENCE_POINTS,
        fail_fast=True,
        description=(
            "Reference polyline [[x, y], …] [m] in driving order: at least two distinct points, "
            f"at most {MAX_REFERENCE_LENGTH:.0f} m long, never turning straight back (180°)."
        ),
    ),
    AfterValidator(_check_reference),
]
