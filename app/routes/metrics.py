"""Operations: the service's metrics for Prometheus."""

from __future__ import annotations

from fastapi import APIRouter, Request, Response

from app.errors import ACCESS_RESPONSES
from app.metrics import exposition

router = APIRouter(tags=["operations"], responses=ACCESS_RESPONSES)

_TEXT = {"schema": {"type": "string"}}


@router.get(
    "/metrics",
    operation_id="metrics",
    summary="Metrics in the Prometheus text format",
    response_class=Response,
    responses={
        200: {
            "description": "Prometheus text exposition format 0.0.4 (OpenMetrics when the `Accept` "
            "header asks for `application/openmetrics-text`).",
            "content": {"text/plain": _TEXT, "application/openmetrics-text": _TEXT},
        }
    },
)
async def metrics(request: Request) -> Response:
    """Request counts and durations by route, plan counts by status and plan stage durations."""
    body, content_type = exposition(request.headers.get("accept"))
    return Response(body, media_type=content_type)
