"""ASGI middleware of the service: every request has an id, a log line and metrics; request bodies
are JSON and bounded in size."""

from __future__ import annotations

import logging
import time
import uuid
from collections.abc import Sequence

from fastapi import HTTPException
from starlette.datastructures import Headers, MutableHeaders
from starlette.requests import Request
from starlette.routing import BaseRoute, Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app import metrics
from app.errors import error_response, unexpected_error_handler
from app.logs import REQUEST_ID

#: header that carries the request id, both ways
REQUEST_ID_HEADER = "X-Request-ID"
#: longest request id taken from a client
MAX_REQUEST_ID = 128
#: route label of a path no route matches
UNMATCHED = "unmatched"
#: method labels of the metrics; any other method is counted as ``other`` (bounded label values)
METHODS = frozenset({"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"})

access_logger = logging.getLogger("app.access")


def valid_request_id(value: str | None) -> str | None:
    """``value`` if it can serve as a request id — 1 to 128 printable ASCII characters — else None."""
    if value and len(value) <= MAX_REQUEST_ID and value.isascii() and value.isprintable():
        return value
    return None


class RequestContextMiddleware:
    """The outermost layer: a request id, one JSON log line and the HTTP metrics per request.

    The id is the client's ``X-Request-ID`` when valid (:func:`valid_request_id`), else a new UUID4;
    it is in :data:`app.logs.REQUEST_ID` (so in every log line) while the request is served and in the
    ``X-Request-ID`` header of every answer, errors and 413 included. An exception no handler took is
    answered here (by :func:`app.errors.unexpected_error_handler`, which logs it) so that its 500 has
    the header as well. The route of the metrics and the log line is the path template of the route
    that served the request (so the scope must not be copied further in: the router notes the route
    in it). The log line (logger ``app.access``) carries method, path, route, status, duration_ms,
    request_id and, for a plan, ``plan_status`` and the stages' ``timing_ms`` (which the
    route leaves in ``request.state``).
    """

    def __init__(self, app: ASGIApp, routes: Sequence[BaseRoute]) -> None:
        """``routes``: the app's routes (``app.routes``), which label a request that never reached the
        router (a 413)."""
        self.app = app
        self.routes = routes

    def route_of(self, scope: Scope) -> str:
        """The path template of the route that served ``scope`` (also on a 405), or of the route that
        would have (a 413), else ``unmatched``."""
        route = scope.get("route")
        if route is None:
            route = next((r for r in self.routes if r.matches(scope)[0] is not Match.NONE), None)
        path = getattr(route, "path", None)
        return path if isinstance(path, str) else UNMATCHED

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start = time.perf_counter()
        request_id = valid_request_id(Headers(scope=scope).get(REQUEST_ID_HEADER)) or str(uuid.uuid4())
        state = scope.setdefault("state", {})  # request.state of the route (plan status and timings)
        token = REQUEST_ID.set(request_id)
        status = 500
        started = False

        async def send_with_id(message: Message) -> None:
            nonlocal status, started
            if message["type"] == "http.response.start":
                started = True
                status = message["status"]
                MutableHeaders(scope=message)[REQUEST_ID_HEADER] = request_id
            await send(message)

        try:
            try:
                await self.app(scope, receive, send_with_id)
            except Exception as exc:
                if started:
                    raise
                response = await unexpected_error_handler(Request(scope), exc)
                await response(scope, receive, send_with_id)
        finally:
            seconds = time.perf_counter() - start
            route = self.route_of(scope)
            method = scope["method"] if scope["method"] in METHODS else "other"
            metrics.observe_request(route, method, status, seconds)
            fields: dict[str, object] = {
                "method": scope["method"],
                "path": scope["path"],
                "route": route,
                "status": status,
                "duration_ms": round(1e3 * seconds, 3),
            }
            if "plan_status" in state:
                fields["plan_status"] = state["plan_status"]
                fields["timing_ms"] = state.get("plan_timing_ms")
            access_logger.log(logging.ERROR if status >= 500 else logging.INFO, "request", extra=fields)
            REQUEST_ID.reset(token)


class JSONBodyMiddleware:
    """Read every request body as JSON: a missing, form or text Content-Type becomes JSON.

    The API takes nothing but JSON, so this only spares clients such as ``curl -d`` a header. It
    weakens nothing: the endpoints are pure computations without cookies or state.
    """

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and scope["method"] in ("POST", "PUT", "PATCH"):
            content_type = Headers(scope=scope).get("content-type", "").lower()
            if "json" not in content_type:
                headers = [(k, v) for k, v in scope["headers"] if k.lower() != b"content-type"]
                headers.append((b"content-type", b"application/json"))
                scope["headers"] = headers  # in place: the outer layers read the route from the scope
        await self.app(scope, receive, send)


class BodyLimitMiddleware:
    """Refuse a request body larger than ``max_bytes`` with 413 in the API's error shape.

    A declared Content-Length over the limit is refused before anything is read; a streamed body is
    counted as it arrives and refused once it passes the limit.
    """

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    def _refusal(self) -> HTTPException:
        return HTTPException(413, f"The request body exceeds {self.max_bytes} bytes.")

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = Headers(scope=scope).get("content-length", "")
        if declared.isdigit() and int(declared) > self.max_bytes:
            refusal = self._refusal()
            response = error_response(413, "payload_too_large", str(refusal.detail))
            await response(scope, receive, send)
            return
        received = 0

        async def limited_receive() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    # fastapi's HTTPException passes through its body parsing to app.errors
                    raise self._refusal()
            return message

        await self.app(scope, limited_receive, send)
