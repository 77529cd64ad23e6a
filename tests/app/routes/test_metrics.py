"""GET /metrics: Prometheus text, or OpenMetrics on request, documented in the OpenAPI document."""

from __future__ import annotations

from fastapi.testclient import TestClient


def test_metrics_in_openmetrics_on_request(client: TestClient) -> None:
    r = client.get("/metrics", headers={"Accept": "application/openmetrics-text; version=1.0.0"})
    assert r.headers["content-type"].startswith("application/openmetrics-text")
    assert r.text.rstrip().endswith("# EOF")


def test_metrics_in_the_openapi_document(client: TestClient) -> None:
    op = client.get("/openapi.json").json()["paths"]["/metrics"]["get"]
    assert op["operationId"] == "metrics" and op["tags"] == ["operations"]
    assert set(op["responses"]["200"]["content"]) == {"text/plain", "application/openmetrics-text"}
