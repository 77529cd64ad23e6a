"""The application factory: ``uvicorn app.main:app`` serves :data:`app`.

Routes live in :mod:`app.routes` (one module per resource), error answers in :mod:`app.errors`,
request and response models in :mod:`app.schemas`, settings in :mod:`app.settings`.
"""

from __future__ import annotations

import logging

from fastapi import FastAPI

from app import __version__
from app.errors import install_error_handlers
from app.middleware import BodyLimitMiddleware, JSONBodyMiddleware
from app.routes import routers
from app.settings import Settings

DESCRIPTION = """\
Trajectory planning on a Frenet frame that stays valid on hairpins and U-turns (TransF-κ).

Units: metres, seconds, radians; `d` is positive to the left of the reference line, `heading` is
counter-clockwise from +x. Every request body is read as JSON whatever its Content-Type, so

    curl -s localhost:8000/v1/demo | curl -s -X POST localhost:8000/v1/candidates -d @-

works as is. Every error answer has the shape
`{"error": {"code", "message", "details": [{"field", "message"}]}}`.
"""


def create_app(settings: Settings | None = None) -> FastAPI:
    """Build the application with ``settings`` (default: from the environment)."""
    settings = settings or Settings()
    logging.getLogger("app").setLevel(settings.log_level.upper())
    app = FastAPI(
        title="kappa-planner",
        version=__version__,
        summary="Trajectory planning robust on hairpins and U-turns (TransF-κ Frenet frame).",
        description=DESCRIPTION,
        separate_input_output_schemas=False,
    )
    app.add_middleware(JSONBodyMiddleware)
    app.add_middleware(BodyLimitMiddleware, max_bytes=settings.max_body_bytes)
    install_error_handlers(app)
    for router in routers:
        app.include_router(router)
    return app


app = create_app()
