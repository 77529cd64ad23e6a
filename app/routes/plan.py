"""A planned trajectory for a planning request: the whole pipeline of :func:`planner.pipeline.plan`.

The plan runs in the worker's plan pool (:class:`app.executor.PlanExecutor`, a
:data:`app.deps.PlanExecutorDep`) so that the event loop stays free: :func:`compute_plan` does all the
CPU work there — the problem, the plan, and the answer's JSON — and sends back the bytes with the plan's
status and stage timings (for the metrics and the request's log line).

The answer is written straight from the planner's arrays (:func:`app.conversions.plan_data`, finiteness
checked on the arrays) rather than through pydantic objects, which would cost a validation or an object
per point; :class:`app.models.plan.PlanResponse` documents the answer, and the tests check that every
answer is exactly its JSON.
"""

from __future__ import annotations

from dataclasses import dataclass

import pydantic_core
from fastapi import APIRouter, Request, Response

from app import metrics
from app.conversions import demo_request, plan_data, to_problem
from app.deps import PlanExecutorDep, SettingsDep
from app.errors import ERROR_RESPONSES, error_response
from app.executor import Overloaded
from app.models.errors import ErrorResponse
from app.models.plan import PlanResponse
from app.models.planning import PlanningRequest
from app.routes.examples import PlanningBody
from planner.pipeline import plan

router = APIRouter(prefix="/v1", tags=["planning"], responses=ERROR_RESPONSES)

#: seconds a client is asked to wait after a 503
RETRY_AFTER_S = 1


@dataclass(frozen=True)
class PlanOutcome:
    """What :func:`compute_plan` sends back: the answer's JSON, the plan's status and stage times [ms]."""

    body: bytes
    status: str
    timing_ms: dict[str, float]


def compute_plan(job: tuple[PlanningRequest, float | None]) -> PlanOutcome:
    """Plan a request with the server's default compute budget [ms] and write the answer (runs in a
    plan process; planner errors propagate)."""
    body, time_budget_ms = job
    result = plan(to_problem(body, time_budget_ms=time_budget_ms))
    data = plan_data(result)
    timing = {stage: round(float(ms), 3) for stage, ms in result.diagnostics.timing_ms.items()}
    return PlanOutcome(pydantic_core.to_json(data), result.status, timing)


def warm_up() -> None:
    """Plan the demo once, so that a process's first plan does not build the speed problem."""
    compute_plan((demo_request(), None))


@router.post(
    "/plan",
    operation_id="plan_trajectory",
    summary="Plan a trajectory: candidate paths, lateral QP, speed profile",
    response_model=PlanResponse,
    responses={
        503: {
            "model": ErrorResponse,
            "description": "Too many plans are queued; retry after `Retry-After` seconds.",
        }
    },
)
async def plan_trajectory(
    request: Request,
    body: PlanningBody,
    settings: SettingsDep,
    executor: PlanExecutorDep,
) -> Response:
    """Trajectory from the ego every `options.dt` [s]; a planning failure is a 200 with status `fallback`."""
    try:
        outcome = await executor.run(compute_plan, (body, settings.time_budget_ms))
    except Overloaded as exc:
        response = error_response(503, "overloaded", f"The service is busy: {exc}; retry later.")
        response.headers["Retry-After"] = str(RETRY_AFTER_S)
        return response
    metrics.observe_plan(outcome.status, outcome.timing_ms)
    request.state.plan_status = outcome.status
    request.state.plan_timing_ms = outcome.timing_ms
    return Response(outcome.body, media_type="application/json")
