"""Candidate lateral paths of a planning request (Algorithm 4 or Algorithm 5 of TransF-κ), computed in a
plan process (:func:`app.jobs.candidates_job`)."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from app.compute import compute
from app.deps import PlanExecutorDep, SettingsDep
from app.errors import COMPUTE_RESPONSES
from app.models.candidates import CandidatesResponse
from app.routes.examples import PLANNING_BODY

router = APIRouter(prefix="/v1", tags=["candidates"], responses=COMPUTE_RESPONSES)


@router.post(
    "/candidates",
    operation_id="generate_candidates",
    summary="Candidate paths of a planning request",
    response_model=CandidatesResponse,
    openapi_extra=PLANNING_BODY,
)
async def candidates(request: Request, settings: SettingsDep, executor: PlanExecutorDep) -> Response:
    """`options.num_candidates` lateral paths from the ego (the points each keeps) + diagnostics."""
    return await compute(request, "candidates", settings, executor)
