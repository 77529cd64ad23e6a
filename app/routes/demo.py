"""The built-in demo problem, ready to post to the planning endpoints."""

from __future__ import annotations

from fastapi import APIRouter

from app.conversions import demo_request
from app.errors import ACCESS_RESPONSES
from app.models.planning import PlanningRequest

router = APIRouter(tags=["demo"], responses=ACCESS_RESPONSES)


@router.get(
    "/v1/demo",
    operation_id="get_demo_request",
    summary="The demo planning request (a U-turn with a wide inner side)",
)
def get_demo() -> PlanningRequest:
    """A planning request to post as is to `/v1/plan` or `/v1/candidates`."""
    return demo_request()
