"""app.docs: /docs and /redoc load their scripts and styles from the service alone, under a CSP that
forbids any other origin; KAPPA_DOCS=false leaves out the pages and the spec."""

from __future__ import annotations

import re

from fastapi.testclient import TestClient

from app.main import create_app
from app.settings import Settings


def test_the_docs_pages_load_nothing_from_elsewhere(client: TestClient) -> None:
    for path in ("/docs", "/redoc"):
        page = client.get(path)
        assert page.status_code == 200 and page.headers["content-type"].startswith("text/html")
        urls = re.findall(r'(?:src|href)="([^"]+)"', page.text)
        assert urls and all(u.startswith("/") for u in urls), (path, urls)
        policy = page.headers["content-security-policy"]
        assert "default-src 'none'" in policy and "script-src 'self'" in policy
        for url in urls:
            asset = client.get(url)
            assert asset.status_code == 200 and asset.content, url
    assert client.get("/openapi.json").json()["info"]["title"] == "kappa-planner"


def test_the_docs_can_be_switched_off() -> None:
    client = TestClient(create_app(Settings(plan_processes=0, docs=False)))
    for path in ("/docs", "/redoc", "/openapi.json", "/docs/static/swagger-ui-bundle.js"):
        assert client.get(path).status_code == 404, path
    assert client.get("/healthz").status_code == 200
