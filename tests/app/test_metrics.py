"""app.metrics: plans counted by status, their stages and the HTTP answers observed."""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient
from prometheus_client.parser import text_string_to_metric_families

from app.models.plan import STAGES

JSON = {"content-type": "application/json"}


def _samples(client: TestClient) -> dict[tuple[str, frozenset[tuple[str, str]]], float]:
    r = client.get("/metrics")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/plain")
    return {
        (s.name, frozenset(s.labels.items())): s.value
        for family in text_string_to_metric_families(r.text)
        for s in family.samples
    }


def test_metrics_count_plans_and_requests(client: TestClient, demo: dict[str, Any]) -> None:
    def key(name: str, **labels: str) -> tuple[str, frozenset[tuple[str, str]]]:
        return name, frozenset(labels.items())

    before = _samples(client)
    answer = client.post("/v1/plan", json=demo).json()
    assert answer["status"] == "ok"
    assert client.post("/v1/plan", content=b"[", headers=JSON).status_code == 422
    after = _samples(client)

    def delta(name: str, **labels: str) -> float:
        return after.get(key(name, **labels), 0.0) - before.get(key(name, **labels), 0.0)

    assert delta("kappa_plans_total", status="ok") == 1
    assert delta("kappa_plans_total", status="fallback") == 0
    assert key("kappa_plans_total", status="stopped") in after  # every status is there from the start
    ran = {stage for stage, ms in answer["diagnostics"]["timing_ms"].items() if ms > 0}
    assert ran == set(STAGES) - {"fallback"}  # an ok plan has no fallback stage, it has every other
    assert delta("kappa_plan_stage_duration_seconds_count", stage="fallback") == 0
    for stage in ran:
        assert delta("kappa_plan_stage_duration_seconds_count", stage=stage) == 1
        assert delta("kappa_plan_stage_duration_seconds_bucket", stage=stage, le="+Inf") == 1
        assert delta("kappa_plan_stage_duration_seconds_sum", stage=stage) > 0
    # the total lands in exactly the buckets from its own upwards
    buckets = sorted(
        (float(dict(labels)["le"]), after[(name, labels)] - before.get((name, labels), 0.0))
        for name, labels in after
        if name == "kappa_plan_stage_duration_seconds_bucket" and ("stage", "total") in labels
    )
    steps = [d for _, d in buckets]
    assert steps == sorted(steps) and set(steps) <= {0, 1} and steps[-1] == 1
    assert delta("kappa_http_requests_total", route="/v1/plan", method="POST", status="200") == 1
    assert delta("kappa_http_requests_total", route="/v1/plan", method="POST", status="422") == 1
    assert delta("kappa_http_request_duration_seconds_count", route="/v1/plan") == 2
    assert delta("kappa_http_requests_total", route="/metrics", method="GET", status="200") == 1
