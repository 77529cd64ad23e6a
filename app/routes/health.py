"""Liveness and readiness: both open whatever the access control (``KAPPA_API_KEYS``)."""

from __future__ import annotations

from fastapi import APIRouter, Response

from app.deps import PlanExecutorDep
from app.errors import error_response
from app.models.errors import ErrorResponse
from app.models.health import Health, Ready

router = APIRouter(tags=["health"])

#: longest wait for an idle plan process to answer a readiness probe [s]
READY_TIMEOUT_S = 2.0


@router.get("/healthz", operation_id="healthz", summary="Liveness probe")
async def healthz() -> Health:
    """Answer `{"status": "ok"}` while the service runs (the event loop answers; nothing else is asked)."""
    return Health()


@router.get(
    "/readyz",
    operation_id="readyz",
    summary="Readiness probe",
    response_model=Ready,
    responses={
        503: {
            "model": ErrorResponse,
            "description": "The plan processes do not answer, or the service is stopping.",
        }
    },
)
async def readyz(executor: PlanExecutorDep) -> Response | Ready:
    """`{"status": "ready"}` while the plan processes are up and answer; else 503."""
    if await executor.ping(READY_TIMEOUT_S):
        return Ready()
    response = error_response(
        503, "not_ready", "The plan processes do not answer (starting, replaced or stopping)."
    )
    response.headers["Retry-After"] = "1"
    return response
