"""GET /viewer and its files: served from the package, by exact name, with the page's security
headers, and outside the API's OpenAPI document."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from app.routes.viewer import ASSETS, CONTENT_SECURITY_POLICY, STATIC

ROOT = Path(__file__).resolve().parents[3]


def test_the_page_is_served(client: TestClient) -> None:
    r = client.get("/viewer")
    assert r.status_code == 200
    assert r.headers["content-type"] == "text/html; charset=utf-8"
    assert r.headers["content-security-policy"] == CONTENT_SECURITY_POLICY
    assert r.headers["x-content-type-options"] == "nosniff"
    # no inline script or style (the CSP forbids them), no other origin
    assert "<script>" not in r.text and "style=" not in r.text and "<style" not in r.text
    assert not re.search(r"(src|href)=\"(https?:)?//", r.text)
    assert client.get("/viewer?demo").status_code == 200


def test_every_file_the_page_uses_is_served(client: TestClient) -> None:
    page = client.get("/viewer").text
    linked = re.findall(r"(?:src|href)=\"viewer/([^\"]+)\"", page)
    imported = [
        name
        for script in STATIC.glob("*.js")
        for name in re.findall(r"from \"\./([^\"]+)\"", script.read_text(encoding="utf-8"))
    ]
    assert {"viewer.js", "viewer.css", "icon.svg", "geometry.js", "api.js", "map.js", "plots.js"} <= {
        *linked,
        *imported,
    }
    for name in {*linked, *imported, "run.schema.json"}:
        r = client.get(f"/viewer/{name}")
        assert r.status_code == 200, name
        assert r.content == (STATIC / name).read_bytes()
    assert client.get("/viewer/viewer.js").headers["content-type"] == "text/javascript; charset=utf-8"
    assert client.get("/viewer/run.schema.json").json()["title"].startswith("kappa-planner run file")


@pytest.mark.parametrize("name", ["nope.js", "..%2Fviewer.py", "%2E%2E%2Froutes%2Fviewer.py", ".env"])
def test_only_the_viewers_own_files_are_served(client: TestClient, name: str) -> None:
    r = client.get(f"/viewer/{name}")
    assert r.status_code == 404
    assert r.json()["error"]["code"] == "not_found"


def test_the_viewer_is_not_part_of_the_api(client: TestClient) -> None:
    paths = client.get("/openapi.json").json()["paths"]
    assert not [p for p in paths if p.startswith("/viewer")]


def test_the_files_are_package_data() -> None:
    """A non-editable install (the container's) holds them: pyproject names them as package data."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert "static/viewer/*" in data["app"]
    assert set(ASSETS) == {p.name for p in STATIC.iterdir() if p.is_file()}
    assert {"index.html", "viewer.js", "run.schema.json"} <= set(ASSETS)
