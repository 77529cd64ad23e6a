"""``/v1/frenet`` and ``/v1/cartesian``: points to express in the other frame of a reference line, and
the answers."""

from __future__ import annotations

from pydantic import Field

from app.limits import MAX_QUERY_POINTS
from app.models.common import FrenetPoint, Point, ReferencePolyline, RequestModel, ResponseModel


class FrenetRequest(RequestModel):
    """Cartesian points to express in the Frenet frame of a reference line."""

    reference_line: ReferencePolyline
    points: list[Point] = Field(
        min_length=1,
        max_length=MAX_QUERY_POINTS,
        fail_fast=True,
        description="Cartesian points [[x, y], …] [m].",
    )


class FrenetResponse(ResponseModel):
    """Frenet coordinates, one pair per requested point."""

    s: list[float] = Field(description="Arc length along the reference [m].")
    d: list[float] = Field(description="Signed lateral offset, positive to the left [m].")


class CartesianRequest(RequestModel):
    """Frenet coordinates to express in Cartesian coordinates."""

    reference_line: ReferencePolyline
    frenet: list[FrenetPoint] = Field(
        min_length=1,
        max_length=MAX_QUERY_POINTS,
        fail_fast=True,
        description="Frenet points [[s, d], …] [m].",
    )


class CartesianResponse(ResponseModel):
    """Cartesian points, one per requested Frenet pair."""

    points: list[tuple[float, float]] = Field(description="[[x, y], …] [m].")
