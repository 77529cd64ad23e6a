"""The request bodies of the routes with the examples the OpenAPI document shows (all from the demo)."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Body

from app.conversions import demo_request
from app.models.planning import PlanningRequest

#: the body of ``/v1/candidates`` and ``/v1/plan``, with the demo request as its example
PlanningBody = Annotated[
    PlanningRequest,
    Body(
        openapi_examples={
            "demo": {
                "summary": "The demo U-turn (GET /v1/demo)",
                "value": demo_request().model_dump(mode="json"),
            }
        }
    ),
]


def on_the_demo_road(key: str, values: list[list[float]], summary: str) -> dict[str, Any]:
    """The ``openapi_examples`` of a coordinates request: ``values`` under ``key`` on the demo's road."""
    road = [list(p) for p in demo_request().reference_line]
    return {"demo": {"summary": summary, "value": {"reference_line": road, key: values}}}
