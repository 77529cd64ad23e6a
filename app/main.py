"""The application factory: ``uvicorn app.main:app`` serves :data:`app`.

Routes live in :mod:`app.routes` (one module per resource), error answers in :mod:`app.errors`,
request and response models in :mod:`app.models` (their limits in :mod:`app.limits`, conversions to
the planner in :mod:`app.conversions`), settings in :mod:`app.settings`, where plans run in
:mod:`app.executor` (both reach the routes through :mod:`app.deps`), logs and metrics in
:mod:`app.logs` and :mod:`app.metrics`.
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from contextlib import asynccontextmanager

from fastapi import FastAPI
from fastapi.routing import APIRoute
from starlette.routing import BaseRoute, Route

from app import __version__
from app.errors import install_error_handlers
from app.executor import PlanExecutor
from app.logs import configure_logging
from app.middleware import BodyLimitMiddleware, JSONBodyMiddleware, RequestContextMiddleware
from app.routes import routers
from app.routes.plan import warm_up
from app.settings import Settings

DESCRIPTION = """\
Trajectory planning on a Frenet frame that stays valid on hairpins and U-turns (TransF-κ).

Units: metres, seconds, radians; `d` is positive to the left of the reference line, `heading` is
counter-clockwise from +x. Every request body is read as JSON whatever its Content-Type, so

    curl -s localhost:8000/v1/demo | curl -s -X POST localhost:8000/v1/candidates -d @-

works as is. Every error answer has the shape
`{"error": {"code", "message", "details": [{"field", "message"}]}}`.
"""


def _every_route(app: FastAPI) -> list[BaseRoute]:
    """Every route of ``app``, once: FastAPI's own (``/openapi.json``, ``/docs``, …) and the routers'.

    ``app.routes`` alone does not serve: depending on FastAPI's version it lists an included router as
    one entry without a path, or a copy of each of its routes.
    """
    own = [r for r in app.routes if isinstance(r, Route) and not isinstance(r, APIRoute)]
    return [*own, *(route for router in routers for route in router.routes)]


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the application with ``settings`` (default: from the environment).

    Its lifespan starts the plan processes (each plans the demo once before it takes a request) and
    stops them; without the lifespan, plans run in a thread (:mod:`app.executor`).
    """
    settings = settings or Settings()
    configure_logging(settings.log_level)
    executor = PlanExecutor(settings.plan_pool_size(), settings.max_pending_plans, setup=warm_up)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        await executor.start()
        try:
            yield
        finally:
            executor.shutdown()

    app = FastAPI(
        title="kappa-planner",
        version=__version__,
        summary="Trajectory planning robust on hairpins and U-turns (TransF-κ Frenet frame).",
        description=DESCRIPTION,
        separate_input_output_schemas=False,
        lifespan=lifespan,
    )
    app.state.settings = settings  # app.deps hands these two to the routes
    app.state.plan_executor = executor
    # the last added is the outermost: ids, logs and metrics see every answer, 413s included
    app.add_middleware(JSONBodyMiddleware)
    app.add_middleware(BodyLimitMiddleware, max_bytes=settings.max_body_bytes)
    install_error_handlers(app)
    for router in routers:
        app.include_router(router)
    app.add_middleware(RequestContextMiddleware, routes=_every_route(app))
    return app


app = create_app()
