"""The request bodies of the computing routes, for the OpenAPI document: their schema and the examples
it shows (all from the demo; ``/v1/plan`` also with a goal).

The routes read their bodies as bytes and have them parsed and validated in a plan process
(:mod:`app.jobs`), so FastAPI does not see the models: :func:`json_body` declares them, and
:func:`app.openapi.document` puts their schemas in the document's components.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from app.conversions import demo_goal, demo_request
from app.models.planning import PlanningRequest

#: the models of the request bodies (their schemas go in the document's components)
REQUEST_MODELS: list[type[BaseModel]] = []


def json_body(model: type[BaseModel], examples: dict[str, Any]) -> dict[str, Any]:
    """The ``openapi_extra`` of a route whose JSON body is a ``model``, with ``examples``."""
    if model not in REQUEST_MODELS:
        REQUEST_MODELS.append(model)
    schema = {"$ref": f"#/components/schemas/{model.__name__}"}
    content = {"application/json": {"schema": schema, "examples": examples}}
    return {"requestBody": {"content": content, "required": True}}


#: the demo request as an example
DEMO_EXAMPLE = {
    "summary": "The demo U-turn (GET /v1/demo)",
    "value": demo_request().model_dump(mode="json", exclude_none=True),
}

#: the body of ``/v1/candidates``, with the demo request as its example
PLANNING_BODY = json_body(PlanningRequest, {"demo": DEMO_EXAMPLE})
#: the body of ``/v1/plan``: the demo, and the demo with a goal
PLAN_BODY = json_body(
    PlanningRequest,
    {
        "demo": DEMO_EXAMPLE,
        "goal": {
            "summary": "The demo with a goal: stop past the U-turn between 5 and 9 s from now",
            "value": demo_request()
            .model_copy(update={"goal": demo_goal()})
            .model_dump(mode="json", exclude_none=True),
        },
    },
)


def on_the_demo_road(key: str, values: list[list[float]], summary: str) -> dict[str, Any]:
    """The examples of a coordinates request: ``values`` under ``key`` on the demo's road."""
    road = [list(p) for p in demo_request().reference_line]
    return {"demo": {"summary": summary, "value": {"reference_line": road, key: values}}}
