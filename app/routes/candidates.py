"""Candidate lateral paths of a planning request (Algorithm 4 or Algorithm 5 of TransF-κ)."""

from __future__ import annotations

from fastapi import APIRouter

from app.conversions import candidates_response, to_problem
from app.errors import ERROR_RESPONSES
from app.models.candidates import CandidatesResponse
from app.routes.examples import PlanningBody
from planner.candidates import generate_candidates
from planner.ego import start_state
from planner.reference import build_reference

router = APIRouter(prefix="/v1", tags=["candidates"], responses=ERROR_RESPONSES)


@router.post(
    "/candidates",
    operation_id="generate_candidates",
    summary="Candidate paths of a planning request",
)
def candidates(
    body: PlanningBody,
) -> CandidatesResponse:
    """`options.num_candidates` lateral paths from the ego (the points each keeps) + diagnostics."""
    problem = to_problem(body)
    ref = build_reference(problem.reference_line)
    start = start_state(ref, problem)  # the start /v1/plan uses, so the candidates are the plan's
    cs = generate_candidates(
        ref, problem.lane, problem.ego, problem.vehicle, problem.options, start=start
    )
    return candidates_response(cs, ref, start)
