"""Coordinate transforms between the Cartesian plane and a reference line's Frenet frame, computed in a
plan process (:func:`app.jobs.frenet_job`, :func:`app.jobs.cartesian_job`)."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from app.compute import compute
from app.deps import PlanExecutorDep, SettingsDep
from app.errors import COMPUTE_RESPONSES
from app.models.coordinates import CartesianRequest, CartesianResponse, FrenetRequest, FrenetResponse
from app.routes.examples import json_body, on_the_demo_road

router = APIRouter(prefix="/v1", tags=["coordinates"], responses=COMPUTE_RESPONSES)

_FRENET_EXAMPLES = on_the_demo_road(
    "points", [[-30.0, 0.0], [0.0, 5.0], [4.0, 8.0]], "Points on the demo U-turn"
)
_CARTESIAN_EXAMPLES = on_the_demo_road(
    "frenet", [[10.0, 0.0], [50.0, 2.0], [60.0, -1.5]], "Offsets on the demo U-turn"
)


@router.post(
    "/frenet",
    operation_id="to_frenet",
    summary="Cartesian points to Frenet coordinates (s, d) by TransF-κ",
    response_model=FrenetResponse,
    openapi_extra=json_body(FrenetRequest, _FRENET_EXAMPLES),
)
async def frenet(request: Request, settings: SettingsDep, executor: PlanExecutorDep) -> Response:
    """Arc length s and signed lateral offset d (left > 0) of each point on the reference [m]."""
    return await compute(request, "frenet", settings, executor)


@router.post(
    "/cartesian",
    operation_id="to_cartesian",
    summary="Frenet coordinates (s, d) to Cartesian points",
    response_model=CartesianResponse,
    openapi_extra=json_body(CartesianRequest, _CARTESIAN_EXAMPLES),
)
async def cartesian(request: Request, settings: SettingsDep, executor: PlanExecutorDep) -> Response:
    """Cartesian point [m] of each (s, d) pair, the exact inverse of `/v1/frenet`."""
    return await compute(request, "cartesian", settings, executor)
