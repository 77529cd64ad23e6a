"""Every error answer of the API, in one shape, decided in one place.

Body of every 4xx and 5xx answer::

    {"error": {"code": "invalid_request", "message": "…",
               "details": [{"field": "reference_line.3", "message": "…"}]}}

``field`` is a dotted path into the request body (``""`` is the body as a whole). Status codes:

* request the API cannot read or that breaks the schema (malformed JSON, a key twice, NaN, wrong
  types, limits) → 422 ``malformed_json`` / ``duplicate_key`` / ``invalid_request``
  (:class:`RequestError`, raised by :mod:`app.intake` in a plan process);
* :class:`planner.errors.PlannerError` → the status and code of :data:`PLANNER_ERRORS`
  (most specific class first): a geometrically unusable input is 422;
* HTTP-level refusals (unknown path or method, no or a wrong API key, a body too large, too slow,
  not JSON or compressed, too many requests, no capacity) → their status;
* anything else is a bug of the server: logged with its traceback, answered 500 ``internal_error``.
"""

from __future__ import annotations

import json
import logging
from collections.abc import Iterable, Mapping, Sequence
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
    401: "unauthorized",
    404: "not_found",
    405: "method_not_allowed",
    408: "request_timeout",
    413: "payload_too_large",
    415: "unsupported_media_type",
    429: "rate_limited",
    503: "unavailable",
}
#: most details listed in one answer
MAX_DETAILS = 50


def _documented(description: str) -> dict[str, Any]:
    return {"model": ErrorResponse, "description": description}


#: OpenAPI ``responses`` of every ``/v1`` endpoint and ``/metrics`` (refusals before any work)
ACCESS_RESPONSES: dict[int | str, dict[str, Any]] = {
    401: _documented("An API key is required (`KAPPA_API_KEYS`): `Authorization: Bearer <key>`."),
    429: _documented("Too many requests from this client (`KAPPA_RATE_LIMIT`); retry after `Retry-After` s."),
}
#: OpenAPI ``responses`` of an endpoint that takes a JSON body and computes in a plan process
COMPUTE_RESPONSES: dict[int | str, dict[str, Any]] = {
    **ACCESS_RESPONSES,
    408: _documented("The body did not arrive within `KAPPA_BODY_TIMEOUT` seconds."),
    413: _documented("The request body is too large."),
    415: _documented("The body is not `application/json`, or is compressed (`Content-Encoding`)."),
    422: _documented("The request is malformed, breaks the schema, or is geometrically unusable."),
    503: _documented(
        "No capacity: the queue is full, no plan process was free before the request's budget ran "
        "out, its plan process died, or the service is stopping; retry after `Retry-After` seconds."
    ),
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


def validation_message(error: Mapping[str, Any]) -> str:
    """The message of one pydantic/FastAPI validation error as the answer shows it."""
    if error["type"] == "missing" and tuple(error["loc"]) == ("body",):
        return "a JSON object is required"
    if error["type"] == "extra_forbidden":
        return "unknown field"
    return str(error["msg"])


class RequestError(Exception):
    """A request the service cannot use, as the answer says it: status, code, message and
    ``(field, message)`` details. Picklable: it crosses from a plan process to the worker."""

    def __init__(self, status: int, code: str, message: str, details: Sequence[tuple[str, str]] = ()) -> None:
        super().__init__(status, code, message, list(details))
        self.status, self.code, self.message = status, code, message
        self.details: list[tuple[str, str]] = list(details)


def invalid_request(errors: Sequence[Mapping[str, Any]]) -> RequestError:
    """The 422 ``invalid_request`` of failed validation ``errors`` (pydantic's), the first
    :data:`MAX_DETAILS` listed."""
    shown = errors[:MAX_DETAILS]
    more = f" ({len(errors)} problems, the first {len(shown)} listed)" if len(errors) > len(shown) else ""
    return RequestError(
        422,
        "invalid_request",
        f"The request does not match the schema{more}.",
        [(field_path(e["loc"]), validation_message(e)) for e in shown],
    )


async def request_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """The answer a :class:`RequestError` describes."""
    exc = cast(RequestError, exc)
    return error_response(exc.status, exc.code, exc.message, exc.details)


async def request_validation_handler(request: Request, exc: Exception) -> JSONResponse:
    """422 for parameters FastAPI validated (the API's bodies are validated by :mod:`app.intake`)."""
    return await request_error_handler(request, invalid_request(cast(RequestValidationError, exc).errors()))


async def planner_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """The status and code of :data:`PLANNER_ERRORS` for a domain error."""
    exc = cast(PlannerError, exc)
    status, code = next(PLANNER_ERRORS[c] for c in type(exc).__mro__ if c in PLANNER_ERRORS)
    return error_response(status, code, str(exc), [(exc.field or "", exc.message)])


async def http_error_handler(request: Request, exc: Exception) -> JSONResponse:
    """HTTP-level refusals (404, 405, 413, an unreadable body …) in the one shape."""
    exc = cast(StarletteHTTPException, exc)
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
    app.add_exception_handler(RequestError, request_error_handler)
    app.add_exception_handler(RequestValidationError, request_validation_handler)
    app.add_exception_handler(PlannerError, planner_error_handler)
    app.add_exception_handler(StarletteHTTPException, http_error_handler)
    app.add_exception_handler(Exception, unexpected_error_handler)
