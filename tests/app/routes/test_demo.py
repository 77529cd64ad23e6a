"""GET /v1/demo: a planning request to post back as is."""

from __future__ import annotations

from fastapi.testclient import TestClient


def test_demo_posts_back(client: TestClient) -> None:
    r = client.get("/v1/demo")
    assert r.status_code == 200
    request = r.json()
    assert {"reference_line", "lane", "obstacles", "ego", "vehicle", "options"} <= set(request)
    r = client.post("/v1/candidates", json=request)
    assert r.status_code == 200, r.text
    assert len(r.json()["candidates"]) == request["options"]["num_candidates"]
