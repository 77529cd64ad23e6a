"""A planned trajectory for a planning request: the whole pipeline of :func:`planner.pipeline.plan`.

The body is parsed, validated and planned in a plan process (:func:`app.jobs.plan_job`, through
:func:`app.compute.compute`), which writes the answer straight from the planner's arrays
(:func:`app.conversions.plan_data`); :class:`app.models.plan.PlanResponse` documents the answer, and
the tests check that every answer is exactly its JSON.
"""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from app.compute import compute
from app.deps import PlanExecutorDep, SettingsDep
from app.errors import COMPUTE_RESPONSES
from app.models.plan import PlanResponse
from app.routes.examples import PLAN_BODY

router = APIRouter(prefix="/v1", tags=["planning"], responses=COMPUTE_RESPONSES)


@router.post(
    "/plan",
    operation_id="plan_trajectory",
    summary="Plan a trajectory: candidate paths, lateral QP, speed profile",
    response_model=PlanResponse,
    openapi_extra=PLAN_BODY,
)
async def plan_trajectory(request: Request, settings: SettingsDep, executor: PlanExecutorDep) -> Response:
    """Trajectory from the ego every `options.dt` [s]; a planning failure is a 200 with status `fallback`."""
    return await compute(request, "plan", settings, executor)
