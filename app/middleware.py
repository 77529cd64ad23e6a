"""ASGI middleware of the service: every request has an id, a log line and metrics; API keys, a rate
limit; request bodies are JSON, uncompressed, and bounded in size, time and memory.

The HTTP server (granian, see :mod:`app.__main__`) bounds what comes before the application: the time
to send a request's headers, their size, the connections handled at once.
"""

from __future__ import annotations

import asyncio
import hashlib
import hmac
import logging
import math
import time
import uuid
from collections import OrderedDict
from collections.abc import Sequence

from fastapi import HTTPException
from starlette.datastructures import Headers, MutableHeaders
from starlette.requests import Request
from starlette.responses import Response
from starlette.routing import BaseRoute, Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app import metrics
from app.errors import HTTP_CODES, error_response, unexpected_error_handler
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
        scope.setdefault("state", {})["arrived"] = time.monotonic()  # the deadline counts from here
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
            level = logging.INFO if status < 500 else logging.WARNING if status == 503 else logging.ERROR
            access_logger.log(level, "request", extra=fields)
            REQUEST_ID.reset(token)


#: media type of every request body
JSON = "application/json"
#: methods whose bodies the service reads (any other method is answered without reading a body)
BODY_METHODS = frozenset({"POST"})


def _refuse(status: int, message: str, headers: dict[str, str] | None = None) -> Response:
    """An answer in the one error shape (code from :data:`app.errors.HTTP_CODES`)."""
    response = error_response(status, HTTP_CODES.get(status, f"http_{status}"), message)
    response.headers.update(headers or {})
    return response


def media_type(content_type: str) -> str:
    """The media type of a ``Content-Type`` value, parameters dropped, lower case."""
    return content_type.split(";", 1)[0].strip().lower()


class InflightBudget:
    """Bytes of request bodies a worker holds at once (being received or computed on), at most
    ``limit``."""

    def __init__(self, limit: int) -> None:
        self.limit = limit
        self.used = 0

    def take(self, amount: int) -> bool:
        """Reserve ``amount`` bytes if they fit."""
        if self.used + amount > self.limit:
            return False
        self.used += amount
        return True

    def give(self, amount: int) -> None:
        self.used -= amount


class BodyGuardMiddleware:
    """Every request body is JSON, uncompressed, bounded in size, in time and, summed over the
    requests in flight, in memory.

    For a request with a body (POST, the only method whose body the service reads):

    * a ``Content-Encoding`` other than ``identity``, or a media type other than ``application/json``
      (none at all included: a browser page of another site can send a form or text without asking,
      never JSON) → 415;
    * a declared ``Content-Length`` over ``max_bytes`` → 413 before anything is read; a streamed body
      is counted as it arrives and refused once it passes the limit;
    * the body must have arrived ``timeout`` seconds after the request did → else 408 (and the
      connection closes);
    * the worker holds at most ``inflight.limit`` bytes of bodies at once, from the first byte read
      until the answer is sent: the declared length is reserved up front (a streamed body as it
      arrives) → 503 with ``Retry-After`` when it does not fit.
    """

    def __init__(self, app: ASGIApp, max_bytes: int, timeout: float, inflight: InflightBudget) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self.timeout = timeout
        self.inflight = inflight

    def _too_large(self) -> HTTPException:
        return HTTPException(413, f"The request body exceeds {self.max_bytes} bytes.")

    def _busy(self) -> HTTPException:
        return HTTPException(
            503,
            "The service holds too many request bodies at once; retry later.",
            headers={"Retry-After": "1"},
        )

    def _check_headers(self, headers: Headers) -> Response | None:
        encoding = headers.get("content-encoding", "identity").strip().lower()
        if encoding not in ("", "identity"):
            return _refuse(
                415, f"Content-Encoding {encoding!r} is not supported: send the body uncompressed."
            )
        kind = media_type(headers.get("content-type", ""))
        if kind != JSON:
            given = f"Content-Type {kind!r}" if kind else "no Content-Type"
            return _refuse(415, f"The body must be {JSON}; the request has {given}.")
        declared = headers.get("content-length", "")
        if declared.isdigit() and int(declared) > self.max_bytes:
            return _refuse(413, f"The request body exceeds {self.max_bytes} bytes.")
        return None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] not in BODY_METHODS:
            await self.app(scope, receive, send)
            return
        headers = Headers(scope=scope)
        refusal = self._check_headers(headers)
        if refusal is not None:
            await refusal(scope, receive, send)
            return
        declared = headers.get("content-length", "")
        held = int(declared) if declared.isdigit() else 0
        if not self.inflight.take(held):
            await _refuse(503, str(self._busy().detail), {"Retry-After": "1"})(scope, receive, send)
            return
        arrived = scope.get("state", {}).get("arrived", time.monotonic())
        deadline = arrived + self.timeout
        received = 0

        async def guarded_receive() -> Message:
            nonlocal received, held
            try:
                message = await asyncio.wait_for(receive(), max(deadline - time.monotonic(), 0.0))
            except TimeoutError:
                raise HTTPException(
                    408,
                    f"The request body did not arrive within {self.timeout:g} s.",
                    headers={"Connection": "close"},
                ) from None
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > self.max_bytes:
                    # fastapi's HTTPException passes through its body reading to app.errors
                    raise self._too_large()
                if received > held:
                    if not self.inflight.take(received - held):
                        raise self._busy()
                    held = received
            return message

        try:
            await self.app(scope, guarded_receive, send)
        finally:
            self.inflight.give(held)


def _digest(key: str) -> bytes:
    return hashlib.sha256(key.encode()).digest()


def guarded(path: str) -> bool:
    """Whether ``path`` is behind the API keys and the rate limit: the API (``/v1/…``) and
    ``/metrics``; health, readiness, documentation and static pages are open."""
    return path.startswith("/v1/") or path == "/metrics"


class APIKeyMiddleware:
    """With API keys configured, ``/v1/…`` and ``/metrics`` need ``Authorization: Bearer <key>``: 401
    otherwise. The key is compared by its SHA-256 digest with :func:`hmac.compare_digest` against every
    configured key (no early exit: the time does not tell which key or how much of it matched). The
    request's client, for the rate limit, is then its key."""

    def __init__(self, app: ASGIApp, keys: Sequence[str]) -> None:
        self.app = app
        self.digests = [_digest(k) for k in keys]

    def _known(self, key: str) -> bool:
        given = _digest(key)
        return sum(hmac.compare_digest(given, d) for d in self.digests) > 0

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or not self.digests or not guarded(scope["path"]):
            await self.app(scope, receive, send)
            return
        scheme, _, key = Headers(scope=scope).get("authorization", "").partition(" ")
        key = key.strip()
        if scheme.lower() != "bearer" or not key or not self._known(key):
            message = (
                "An API key is required: Authorization: Bearer <key>." if not key else "Unknown API key."
            )
            response = _refuse(401, message, {"WWW-Authenticate": 'Bearer realm="kappa-planner"'})
            await response(scope, receive, send)
            return
        scope.setdefault("state", {})["client"] = "key:" + _digest(key).hex()[:16]
        await self.app(scope, receive, send)


class TokenBuckets:
    """A token bucket per client: ``rate`` tokens per second, at most ``burst``; the least recently
    seen clients beyond ``max_clients`` are forgotten (a forgotten client starts with a full bucket)."""

    def __init__(self, rate: float, burst: int, max_clients: int = 10_000) -> None:
        self.rate, self.burst, self.max_clients = rate, burst, max_clients
        self._buckets: OrderedDict[str, tuple[float, float]] = OrderedDict()

    def take(self, client: str, now: float) -> float:
        """Take a token for ``client`` at ``now`` [s]: 0 if it had one, else the seconds until it
        will."""
        tokens, then = self._buckets.pop(client, (float(self.burst), now))
        tokens = min(float(self.burst), tokens + (now - then) * self.rate)
        wait = 0.0
        if tokens >= 1.0:
            tokens -= 1.0
        else:
            wait = (1.0 - tokens) / self.rate
        self._buckets[client] = (tokens, now)
        while len(self._buckets) > self.max_clients:
            self._buckets.popitem(last=False)
        return wait


class RateLimitMiddleware:
    """At most ``rate`` requests per second per client to ``/v1/…`` and ``/metrics``, ``burst`` at
    once (:class:`TokenBuckets`, per worker process); beyond, 429 with ``Retry-After``. The client is
    its API key when keys are on, else its address as the connection shows it."""

    def __init__(self, app: ASGIApp, buckets: TokenBuckets) -> None:
        self.app = app
        self.buckets = buckets

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or not guarded(scope["path"]):
            await self.app(scope, receive, send)
            return
        peer = scope.get("client") or ("unknown", 0)
        client = scope.get("state", {}).get("client") or f"addr:{peer[0]}"
        wait = self.buckets.take(client, time.monotonic())
        if wait > 0:
            response = _refuse(
                429,
                f"More than {self.buckets.rate:g} requests per second; retry after {wait:.2f} s.",
                {"Retry-After": str(max(1, math.ceil(wait)))},
            )
            await response(scope, receive, send)
            return
        await self.app(scope, receive, send)
