"""ASGI middleware of the service: request bodies are JSON and bounded in size."""

from __future__ import annotations

from fastapi import HTTPException
from starlette.datastructures import Headers
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.errors import error_response


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
                scope = {**scope, "headers": headers}
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
