"""Coordinate transforms between the Cartesian plane and a reference line's Frenet frame."""

from __future__ import annotations

from typing import Annotated

import numpy as np
from fastapi import APIRouter, Body

from app.errors import ERROR_RESPONSES
from app.models.coordinates import CartesianRequest, CartesianResponse, FrenetRequest, FrenetResponse
from app.routes.examples import on_the_demo_road
from planner.frenet import to_cartesian, to_frenet
from planner.reference import build_reference

router = APIRouter(prefix="/v1", tags=["coordinates"], responses=ERROR_RESPONSES)


@router.post(
    "/frenet",
    operation_id="to_frenet",
    summary="Cartesian points to Frenet coordinates (s, d) by TransF-κ",
)
def frenet(
    body: Annotated[
        FrenetRequest,
        Body(
            openapi_examples=on_the_demo_road(
                "points", [[-30.0, 0.0], [0.0, 5.0], [4.0, 8.0]], "Points on the demo U-turn"
            )
        ),
    ],
) -> FrenetResponse:
    """Arc length s and signed lateral offset d (left > 0) of each point on the reference [m]."""
    ref = build_reference(body.reference_line)
    fr = to_frenet(ref, np.asarray(body.points, dtype=float))
    return FrenetResponse(s=fr.s.tolist(), d=fr.d.tolist())


@router.post(
    "/cartesian",
    operation_id="to_cartesian",
    summary="Frenet coordinates (s, d) to Cartesian points",
)
def cartesian(
    body: Annotated[
        CartesianRequest,
        Body(
            openapi_examples=on_the_demo_road(
                "frenet", [[10.0, 0.0], [50.0, 2.0], [60.0, -1.5]], "Offsets on the demo U-turn"
            )
        ),
    ],
) -> CartesianResponse:
    """Cartesian point [m] of each (s, d) pair, the exact inverse of `/v1/frenet`."""
    ref = build_reference(body.reference_line)
    frenet = np.asarray(body.frenet, dtype=float)
    xy = to_cartesian(ref, frenet[:, 0], frenet[:, 1])
    return CartesianResponse(points=[(x, y) for x, y in xy.tolist()])
