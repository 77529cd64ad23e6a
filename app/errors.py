"""Every error answer of the API, in one shape, decided in one place.

Body of every 4xx and 5xx answer::

    {"error": {"code": "invalid_request", "message": "…",
               "details": [{"field": "reference_line.3", "message": "…"}]}}

``field`` is a dotted path into the request body (``""`` is the body as a whole). Status codes:

* request the API cannot read or that breaks the schema (malformed JSON, NaN, wrong types, limits)
  → 422 ``malformed_json`` / ``invalid_request``;
* :class:`planner.errors.PlannerError` → the status and code of :data:`PLANNER_ERRORS`
  (most specific class first): a geometrically unusable input is 422;
* HTTP-level refusals (unknown path, method, body too large) → their status;
* anything else is a bug of the server: logged with its traceback, answered 500 ``internal_error``.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterable, Sequence
from typing import Any, cast

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from app.models.common import UNION_TAGS
from app.models.errors import ErrorDetail, ErrorInfo, ErrorResponse
from planner.errors import InvalidInputError, InvalidReferenceError, PlannerError

logger = logging.getLogger(__name__)

#: planner error class → (HTTP status, error code); the first class in the error's MRO wins
PLANNER_ERRORS: dict[type[PlannerError], tuple[int, str]] = {
    InvalidReferenceError: (422, "invalid_reference"),
    InvalidInputError: (422, "invalid_input"),
    PlannerError: (422, "planner_error"),
}
#: codes of HTTP-level refusals; other statuses get ``http_<status>``
HTTP_CODES: dict[int, str] = {
    400: "bad_request",
    404: "not_found",
    405: "method_not_allowed",
    413: "payload_too_large",
    415: "unsupported_media_type",
}
#: most details listed in one answer
MAX_DETAILS = 50


#: OpenAPI ``responses`` of an endpoint that takes a JSON body
ERROR_RESPONSES: dict[int | str, dict[str, Any]] = {
    413: {"model": ErrorResponse, "description": "The request body is too large."},
    422: {
        "model": ErrorResponse,
        "description": "The request is malformed, breaks the schema, or is geometrically unusable.",
    },
}


def error_response(
    status: int, code: str, message: str, details: Iterable[tuple[str, str]] = ()
) -> JSONResponse:
    """An answer in the one error shape."""
    body = ErrorResponse(
        error=ErrorInfo(
            code=code,
            message=message,
            details=[ErrorDetail(field=f, message=m) for f, m in details],
        )
    )
    return JSONResponse(status_code=status, content=body.model_dump())


def field_path(loc: Sequence[Any]) -> str:
    """Dotted body-relative path of a pydantic/FastAPI error location, union labels dropped."""
    parts = list(loc)
    if parts and parts[0] == "body":
        parts = parts[1:]
    return ".".join(str(p) for p in parts if p not in UNION_TAGS)


def _json_error(exc: RequestValidationError, error: dict[str, Any]) -> JSONResponse:
    pos = error["loc"][-1] if isinstance(error["loc"][-1], int) else 0
    doc = exc.body if isinstance(exc.body, str) else ""
    line = doc.count("\n", 0, pos) + 1
    column = pos - (doc.rfind("\n", 0, pos) + 1) + 1
    reason = error.get("ctx", {}).get("error", "invalid JSON")
    message = f"{reason} at line {line}, column {column}"
    return error_response(
        422, "malformed_json", "The request body is not valid JSON.", [("", message)]
    )


def _message(error: dict[str, Any]) -> str:
    if error["type"] == "missing" and tuple(error["loc"]) == ("body",):
        return "a JSON object is required"
    if error["type"] == "extra_forbidden":
        return "unknown field"
    return str(error["msg"])


async def request_validation_handler(request: Request, exc: Exception) -> JSONResponse:
    """422 for a body that is not JSON or breaks the schema."""
    exc = cast(RequestValidationError, exc)
    errors = list(exc.errors())
    for error in errors:
        if error["type"] == "json_invalid":
            return _json_error(exc, error)
    shown = errors[:MAX_DETAILS]
    more = (
        f" ({len(errors)} problems, the first {len(shown)} listed)"
        if len(errors) > len(shown)
        else ""
    )
    return error_response(
        422,
        "invalid_request",
        f"The request does not match the schema{more}.",
        [(field_path(e["loc"]), _message(e)) for e in shown],
    )


async def planner_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """The status and code of :data:`PLANNER_ERRORS` for a domain error."""
    exc = cast(PlannerError, exc)
    status, code = next(PLANNER_ERRORS[c] for c in type(exc).__mro__ if c in PLANNER_ERRORS)
    return error_response(status, code, str(exc), [(exc.field or "", exc.message)])


async def http_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """HTTP-level refusals (404, 405, 413, an unreadable body …) in the one shape."""
    exc = cast(StarletteHTTPException, exc)
    cause = exc.__cause__
    if exc.status_code == 400 and isinstance(cause, ValueError | RecursionError):
        # FastAPI answers 400 for a body json.loads refused without a JSONDecodeError.
        reason = "nested too deeply" if isinstance(cause, RecursionError) else str(cause)
        reason = reason.split(":")[0]  # the cause's first clause, without advice on Python
        return error_response(
            422, "malformed_json", "The request body is not valid JSON.", [("", reason)]
        )
    code = HTTP_CODES.get(exc.status_code, f"http_{exc.status_code}")
    message = exc.detail if isinstance(exc.detail, str) else json.dumps(exc.detail)
    response = error_response(exc.status_code, code, message)
    if exc.headers:
        response.headers.update(exc.headers)
    return response


async def unexpected_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """A bug of the server: log it with its traceback, answer 500 without internals."""
    logger.error("unhandled error on %s %s", request.method, request.url.path, exc_info=exc)
    return error_response(500, "internal_error", "Internal server error; it has been logged.")


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers above on ``app``."""
    app.add_exception_handler(RequestValidationError, request_validation_handler)
    app.add_exception_handler(PlannerError, planner_error_handler)
    app.add_exception_handler(StarletteHTTPException, http_error_handler)
    app.add_exception_handler(Exception, unexpected_error_handler)
