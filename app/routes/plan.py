"""A planned trajectory for a planning request: the whole pipeline of :func:`planner.pipeline.plan`.

The answer is written straight from the planner's arrays (:func:`app.schemas.plan_data`, finiteness
checked on the arrays) rather than through pydantic objects: with the demo's candidates that is 2×
faster than validating the data once and 4× faster than one object per point, 5× at the size limit.
:class:`app.schemas.PlanResponse` documents the answer; the tests check that every answer is exactly
its JSON.
"""

from __future__ import annotations

from typing import Annotated

import pydantic_core
from fastapi import APIRouter, Body, Response

from app.errors import ERROR_RESPONSES
from app.schemas import PlanningRequest, PlanResponse, demo_request, plan_data, to_problem
from planner.pipeline import plan

router = APIRouter(prefix="/v1", tags=["planning"], responses=ERROR_RESPONSES)


@router.post(
    "/plan",
    operation_id="plan_trajectory",
    summary="Plan a trajectory: candidate paths, lateral QP, speed profile",
    response_model=PlanResponse,
)
def plan_trajectory(
    body: Annotated[
        PlanningRequest,
        Body(
            openapi_examples={
                "demo": {
                    "summary": "The demo U-turn (GET /v1/demo)",
                    "value": demo_request().model_dump(mode="json"),
                }
            }
        ),
    ],
) -> Response:
    """Trajectory from the ego every `options.dt` [s]; a planning failure is a 200 with status `fallback`."""
    data = plan_data(plan(to_problem(body)))
    return Response(pydantic_core.to_json(data), media_type="application/json")
