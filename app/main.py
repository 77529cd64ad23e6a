"""The application factory: ``python -m app`` (granian, :mod:`app.__main__`) serves :data:`app`.

Routes live in :mod:`app.routes` (one module per resource), error answers in :mod:`app.errors`,
request and response models in :mod:`app.models` (their limits in :mod:`app.limits`, conversions to
the planner in :mod:`app.conversions`), settings in :mod:`app.settings`, where plans run in
:mod:`app.executor` (both reach the routes through :mod:`app.deps`), logs and metrics in
:mod:`app.logs` and :mod:`app.metrics`.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from typing import Any

from fastapi import FastAPI
from fastapi.routing import APIRoute
from starlette.middleware.cors import CORSMiddleware
from starlette.routing import BaseRoute, Route

from app import __version__
from app.docs import install_docs
from app.errors import install_error_handlers
from app.executor import PlanExecutor
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
from app.settings import Settings

#: of ``KAPPA_SHUTDOWN_TIMEOUT``, what is kept for cutting the plans still running and answering them [s]
SHUTDOWN_MARGIN_S = 1.0
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
    stops them within ``KAPPA_SHUTDOWN_TIMEOUT``; without the lifespan, the work runs in a thread
    (:mod:`app.executor`).
    """
    settings = settings or Settings()
    configure_logging(settings.log_level)
    executor = PlanExecutor(
        settings.plan_pool_size(),
        settings.max_pending_plans,
        setup=warm_up,
        max_calls=settings.max_process_calls,
        max_rss_bytes=settings.max_process_rss_mb * 1024 * 1024,
    )

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        await executor.start()
        try:
            yield
        finally:
            await executor.shutdown(max(0.0, settings.shutdown_timeout - SHUTDOWN_MARGIN_S))

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
