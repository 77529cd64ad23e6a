"""The viewer: ``GET /viewer`` serves a self-contained page (plain JavaScript and SVG, no library, no
build step) that plans a request through ``/v1/plan`` and draws it, or plays back a simulator run.

Its files are package data under ``app/static/viewer/`` (``index.html`` is the page; the scripts,
style sheet and the run file's JSON Schema are served beside it as ``/viewer/NAME``). Only the files
found there at start-up are served, by exact name. None of this is part of the API: the routes are
left out of the OpenAPI document.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter
from fastapi.responses import FileResponse, Response

from app.errors import error_response

#: where the viewer's files are (installed with the package, see pyproject's package-data)
STATIC = Path(__file__).resolve().parent.parent / "static" / "viewer"
#: media types of the files served, by suffix
MEDIA_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".json": "application/json",
    ".svg": "image/svg+xml",
    ".png": "image/png",
}
#: the page's scripts, styles and images come from here only; it may fetch anything the user names
#: (``?request=URL``, ``?run=URL``) and loads dropped files as blobs
CONTENT_SECURITY_POLICY = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
    "connect-src *; object-src 'none'; base-uri 'none'; frame-ancestors 'self'; form-action 'none'"
)
HEADERS = {
    "Cache-Control": "no-cache",  # revalidate (ETag): a new version of the service shows at once
    "X-Content-Type-Options": "nosniff",
    "Content-Security-Policy": CONTENT_SECURITY_POLICY,
}


def _assets() -> dict[str, Path]:
    """The files served under ``/viewer/``, by name."""
    if not STATIC.is_dir():
        return {}
    return {p.name: p for p in sorted(STATIC.iterdir()) if p.is_file() and p.suffix in MEDIA_TYPES}


ASSETS = _assets()

router = APIRouter(tags=["viewer"], include_in_schema=False)


def _file(name: str) -> Response:
    path = ASSETS.get(name)
    if path is None:
        return error_response(404, "not_found", f"The viewer has no file {name!r}.")
    return FileResponse(path, media_type=MEDIA_TYPES[path.suffix], headers=HEADERS)


@router.get("/viewer")
def viewer_page() -> Response:
    """The viewer's page (``?demo``, ``?request=URL``, ``?run=URL``: see the README)."""
    return _file("index.html")


@router.get("/viewer/{name}")
def viewer_file(name: str) -> Response:
    """One of the viewer's files (scripts, style sheet, icon, the run file's JSON Schema)."""
    return _file(name)
