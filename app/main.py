"""The application factory: ``python -m app`` (granian, :mod:`app.__main__`) serves :data:`app`.

Routes live in :mod:`app.routes` (one module per resource), error answers in :mod:`app.errors`,
request and response models in :mod:`app.models` (their limits in :mod:`app.limits`, conversions to
the planner in :mod:`app.conversions`), settings in :mod:`app.settings`, where plans run in
:mod:`app.executor` (both reach the routes through :mod:`app.deps`), logs and metrics in
:mod:`app.logs` and :mod:`app.metrics`.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import os
import signal
from collections.abc import AsyncIterator, Callable
from contextlib import asynccontextmanager
from types import FrameType
from typing import Any

from fastapi import FastAPI
from fastapi.routing import APIRoute
from starlette.middleware.cors import CORSMiddleware
from starlette.routing import BaseRoute, Route

from app import __version__, metrics
from app.docs import install_docs
from app.errors import install_error_handlers
from app.executor import PlanExecutor, die_with_parent
from app.jobs import warm_up
from app.logs import configure_logging
from app.middleware import (
    APIKeyMiddleware,
    BodyGuardMiddleware,
    InflightBudget,
    RateLimitMiddleware,
    RequestContextMiddleware,
    TokenBuckets,
)
from app.openapi import document
from app.routes import metrics as metrics_route
from app.routes import routers
from app.settings import SUPERVISOR_ENV, Settings

#: of ``KAPPA_SHUTDOWN_TIMEOUT``, what is left after the plans still running are cut: answering them,
#: the worker's exit (granian kills it ``WORKER_EXIT_MARGIN_S`` before the end) and the supervisor's [s]
SHUTDOWN_MARGIN_S = 3.0


def _on_sigterm(callback: Callable[[], object]) -> None:
    """Call ``callback`` (in the event loop's thread) when the process gets SIGTERM, then whatever
    handled SIGTERM before (the server's graceful stop): the Python-level handler is chained; an
    event loop's own handler, which wakes through its wakeup fd, runs as well."""
    previous = signal.getsignal(signal.SIGTERM)

    def handler(signum: int, frame: FrameType | None) -> None:
        callback()
        if callable(previous):
            previous(signum, frame)

    with contextlib.suppress(ValueError):  # not the main thread: no signal handling here
        signal.signal(signal.SIGTERM, handler)


OPENAPI_URL = "/openapi.json"

DESCRIPTION = """\
Trajectory planning on a Frenet frame that stays valid on hairpins and U-turns (TransF-κ).

Units: metres, seconds, radians; `d` is positive to the left of the reference line, `heading` is
counter-clockwise from +x. Every request body is JSON (`Content-Type: application/json`, not
compressed), so

    curl -s localhost:8000/v1/demo |
      curl -s -X POST localhost:8000/v1/candidates -H 'Content-Type: application/json' -d @-

works as is. Every error answer has the shape
`{"error": {"code", "message", "details": [{"field", "message"}]}}`.
"""


def _every_route(app: FastAPI) -> list[BaseRoute]:
    """Every route of ``app``, once: FastAPI's own (``/openapi.json``, ``/docs``, …) and the routers'.

    ``app.routes`` alone does not serve: depending on FastAPI's version it lists an included router as
    one entry without a path, or a copy of each of its routes.
    """
    own = [r for r in app.routes if isinstance(r, Route) and not isinstance(r, APIRoute)]
    return [*own, *(route for router in app_routers(app) for route in router.routes)]


def app_routers(app: FastAPI) -> list[Any]:
    """The routers ``app`` includes (``/metrics`` only where it is served on the service's port)."""
    settings: Settings = app.state.settings
    return [r for r in routers if settings.metrics_on_service_port or r is not metrics_route.router]


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the application with ``settings`` (default: from the environment).

    Its lifespan starts the plan processes (each plans the demo once before it takes a request) and
    stops them: from SIGTERM, new work is refused (503) and plans still running
    ``KAPPA_SHUTDOWN_TIMEOUT`` − :data:`SHUTDOWN_MARGIN_S` later are cut (503), so that every request
    is answered before the server kills a worker that has not stopped (:mod:`app.__main__`). Without
    the lifespan, the work runs in a thread (:mod:`app.executor`). A worker of ``python -m app`` dies
    with it.
    """
    settings = settings or Settings()
    configure_logging(settings.log_level)
    supervisor = os.environ.get(SUPERVISOR_ENV, "")
    if supervisor.isdigit() and int(supervisor) == os.getppid():  # a worker of `python -m app`
        die_with_parent(int(supervisor))
    executor = PlanExecutor(
        settings.plan_pool_size(),
        settings.max_pending_plans,
        setup=functools.partial(warm_up, settings.speculate),
        max_calls=settings.max_process_calls,
        max_rss_bytes=settings.max_process_rss_mb * 1024 * 1024,
        on_replace=metrics.observe_recycle,
    )

    drain_after = max(0.0, settings.shutdown_timeout - SHUTDOWN_MARGIN_S)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        await executor.start()
        loop = asyncio.get_running_loop()
        _on_sigterm(lambda: loop.call_soon_threadsafe(executor.drain, drain_after))
        try:
            yield
        finally:
            await executor.shutdown(drain_after)

    app = FastAPI(
        title="kappa-planner",
        version=__version__,
        summary="Trajectory planning robust on hairpins and U-turns (TransF-κ Frenet frame).",
        description=DESCRIPTION,
        separate_input_output_schemas=False,
        lifespan=lifespan,
        openapi_url=OPENAPI_URL if settings.docs else None,
        docs_url=None,
        redoc_url=None,
    )
    app.state.settings = settings  # app.deps hands these two to the routes
    app.state.plan_executor = executor
    app.openapi = lambda: document(app)  # type: ignore[method-assign]
    if settings.docs:
        install_docs(app, OPENAPI_URL)
    # the last added is the outermost: ids, logs and metrics see every answer, 401s and 413s included;
    # CORS answers preflights before the keys are asked for
    app.add_middleware(
        BodyGuardMiddleware,
        max_bytes=settings.max_body_bytes,
        timeout=settings.body_timeout,
        inflight=InflightBudget(settings.max_inflight_body_bytes),
    )
    if settings.rate_limit > 0:
        app.add_middleware(RateLimitMiddleware, buckets=TokenBuckets(settings.rate_limit, settings.burst))
    if settings.api_key_list:
        app.add_middleware(APIKeyMiddleware, keys=settings.api_key_list)
    if settings.cors_origin_list:
        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origin_list,
            allow_methods=["GET", "POST"],
            allow_headers=["Authorization", "Content-Type", "X-Request-ID"],
            expose_headers=["X-Request-ID", "Retry-After", "Server-Timing"],
            max_age=600,
        )
    install_error_handlers(app)
    for router in app_routers(app):
        app.include_router(router)
    app.add_middleware(RequestContextMiddleware, routes=_every_route(app))
    return app


app = create_app()
