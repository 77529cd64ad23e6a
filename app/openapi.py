"""The OpenAPI document the service serves (``/openapi.json``) and ``openapi/export.py`` writes.

FastAPI's own, plus the schemas of the request bodies: the computing routes read their bodies as bytes
(they are parsed and validated in a plan process, :mod:`app.jobs`), so FastAPI does not see their
models; :data:`app.routes.examples.REQUEST_MODELS` lists them and their schemas are generated here the
way FastAPI generates the others (validation mode, refs into ``#/components/schemas``).
"""

from __future__ import annotations

from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from pydantic.json_schema import models_json_schema

from app.routes.examples import REQUEST_MODELS

REF_TEMPLATE = "#/components/schemas/{model}"


def document(app: FastAPI) -> dict[str, Any]:
    """The OpenAPI document of ``app`` (made once, then cached on it)."""
    if app.openapi_schema:
        return app.openapi_schema
    spec = get_openapi(
        title=app.title,
        version=app.version,
        openapi_version=app.openapi_version,
        summary=app.summary,
        description=app.description,
        routes=app.routes,
        separate_input_output_schemas=app.separate_input_output_schemas,
    )
    _, extra = models_json_schema([(m, "validation") for m in REQUEST_MODELS], ref_template=REF_TEMPLATE)
    schemas = spec.setdefault("components", {}).setdefault("schemas", {})
    for name, schema in extra.get("$defs", {}).items():
        schemas.setdefault(name, schema)
    spec["components"]["schemas"] = dict(sorted(schemas.items()))
    app.openapi_schema = spec
    return spec
