"""The interactive documentation, ``/docs`` (Swagger UI) and ``/redoc``, from this service alone.

FastAPI's own pages load their scripts, styles, fonts and icon from CDNs; these load the same Swagger UI
and ReDoc bundles from the service (the files of the ``fastapi-offline`` distribution, under
``/docs/static``), no font from elsewhere, and answer with a ``Content-Security-Policy`` that lets the
browser run nothing from any other origin. ``KAPPA_DOCS=false`` leaves out the pages and
``/openapi.json``.
"""

from __future__ import annotations

from pathlib import Path

import fastapi_offline
from fastapi import FastAPI
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.staticfiles import StaticFiles
from starlette.responses import HTMLResponse

#: where the assets are served
STATIC = "/docs/static"
#: the assets: Swagger UI's and ReDoc's bundles, their style sheet and an icon
ASSETS = Path(fastapi_offline.__file__).parent / "static"
#: what a documentation page may load: its own origin's scripts (and Swagger UI's inline start-up
#: script), styles, images and the spec; nothing else (ReDoc renders with workers from blob: URLs)
CONTENT_SECURITY_POLICY = (
    "default-src 'none'; script-src 'self' 'unsafe-inline'; style-src 'self' 'unsafe-inline'; "
    "img-src 'self' data:; connect-src 'self'; worker-src 'self' blob:; font-src 'self'; "
    "frame-ancestors 'none'; base-uri 'none'; form-action 'none'"
)


def _secured(page: HTMLResponse) -> HTMLResponse:
    page.headers["Content-Security-Policy"] = CONTENT_SECURITY_POLICY
    page.headers["X-Content-Type-Options"] = "nosniff"
    return page


def install_docs(app: FastAPI, openapi_url: str) -> None:
    """Serve ``/docs``, ``/redoc`` and their assets on ``app`` (created with ``docs_url=None`` and
    ``redoc_url=None``)."""
    title = app.title
    app.mount(STATIC, StaticFiles(directory=ASSETS), name="docs-static")

    @app.get("/docs", include_in_schema=False)
    async def swagger_ui() -> HTMLResponse:
        return _secured(
            get_swagger_ui_html(
                openapi_url=openapi_url,
                title=f"{title} - Swagger UI",
                swagger_js_url=f"{STATIC}/swagger-ui-bundle.js",
                swagger_css_url=f"{STATIC}/swagger-ui.css",
                swagger_favicon_url=f"{STATIC}/favicon.png",
            )
        )

    @app.get("/redoc", include_in_schema=False)
    async def redoc() -> HTMLResponse:
        return _secured(
            get_redoc_html(
                openapi_url=openapi_url,
                title=f"{title} - ReDoc",
                redoc_js_url=f"{STATIC}/redoc.standalone.js",
                redoc_favicon_url=f"{STATIC}/favicon.png",
                with_google_fonts=False,
            )
        )
