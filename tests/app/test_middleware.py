"""app.middleware: request ids, one JSON log line per request labelled by its route; bodies are JSON
(415 otherwise), bounded in size (413), in time (408) and in memory over the requests in flight (503);
API keys (401), a rate limit (429), CORS only for the listed origins."""

from __future__ import annotations

import asyncio
import json
import logging
import uuid
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from pydantic import SecretStr

from app.logs import JSONFormatter
from app.main import create_app
from app.middleware import TokenBuckets
from app.models.plan import STAGES
from app.settings import Settings
from tests.app.helpers import fail_candidates

JSON = {"content-type": "application/json"}


def _uuid4(value: str) -> bool:
    try:
        return uuid.UUID(value).version == 4
    except ValueError:
        return False


def test_a_valid_request_id_is_echoed(client: TestClient) -> None:
    for rid in ("abc-123", "trace 7/x:y", "a" * 128):
        r = client.get("/healthz", headers={"X-Request-ID": rid})
        assert r.status_code == 200 and r.headers["X-Request-ID"] == rid


def test_a_request_id_is_generated_when_missing_or_invalid(client: TestClient) -> None:
    seen = set()
    invalid: list[dict[str, str | bytes]] = [
        {},
        {"X-Request-ID": "a" * 129},
        {"X-Request-ID": b"caf\xe9"},
        {"X-Request-ID": "a\x7fb"},
    ]
    for headers in invalid:
        r = client.get("/healthz", headers=headers)
        rid = r.headers["X-Request-ID"]
        assert _uuid4(rid), (headers, rid)
        seen.add(rid)
    assert len(seen) == 4  # a new one each time


def test_every_error_answer_has_a_request_id(
    client: TestClient, demo: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    answers = [
        client.get("/v1/nowhere", headers={"X-Request-ID": "r404"}),
        client.put("/v1/plan", headers={"X-Request-ID": "r405"}),
        client.post("/v1/plan", content=b"{", headers={"X-Request-ID": "r422", **JSON}),
    ]
    small = TestClient(create_app(Settings(max_body_bytes=2048)))
    answers.append(small.post("/v1/plan", content=b" " * 4096, headers={"X-Request-ID": "r413", **JSON}))

    fail_candidates(monkeypatch, ZeroDivisionError("internals"))
    answers.append(client.post("/v1/candidates", json=demo, headers={"X-Request-ID": "r500"}))
    assert [(r.status_code, r.headers.get("X-Request-ID")) for r in answers] == [
        (404, "r404"),
        (405, "r405"),
        (422, "r422"),
        (413, "r413"),
        (500, "r500"),
    ]
    assert all(set(r.json()) == {"error"} for r in answers)


def _lines(caplog: pytest.LogCaptureFixture, name: str) -> list[dict[str, Any]]:
    formatter = JSONFormatter()
    return [json.loads(formatter.format(rec)) for rec in caplog.records if rec.name == name]


def test_one_json_line_per_request(client: TestClient, caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.INFO, logger="app.access"):
        r = client.get("/healthz?probe=1", headers={"X-Request-ID": "line-1"})
        client.get("/v1/nowhere")
    first, second = _lines(caplog, "app.access")
    assert r.headers["X-Request-ID"] == "line-1"
    assert first["request_id"] == "line-1"
    assert (first["method"], first["path"], first["route"]) == ("GET", "/healthz", "/healthz")
    assert first["status"] == 200
    assert first["level"] == "info" and first["logger"] == "app.access" and first["message"] == "request"
    assert isinstance(first["duration_ms"], float) and first["duration_ms"] >= 0.0
    assert "plan_status" not in first
    assert (second["path"], second["route"], second["status"]) == ("/v1/nowhere", "unmatched", 404)
    assert _uuid4(second["request_id"])


def test_a_request_refused_before_routing_is_labelled_by_its_route(caplog: pytest.LogCaptureFixture) -> None:
    small = TestClient(create_app(Settings(max_body_bytes=2048)))
    with caplog.at_level(logging.INFO, logger="app.access"):
        assert small.post("/v1/plan", content=b" " * 4096, headers=JSON).status_code == 413
        assert small.post("/v1/nowhere", content=b" " * 4096, headers=JSON).status_code == 413
    first, second = _lines(caplog, "app.access")
    assert (first["route"], first["status"]) == ("/v1/plan", 413)
    assert (second["route"], second["status"]) == ("unmatched", 413)


def test_a_plan_line_has_its_status_and_stage_timings(
    client: TestClient, demo: dict[str, Any], caplog: pytest.LogCaptureFixture
) -> None:
    with caplog.at_level(logging.INFO, logger="app.access"):
        r = client.post("/v1/plan", json=demo)
    assert r.status_code == 200
    (line,) = _lines(caplog, "app.access")
    assert (line["method"], line["path"], line["status"]) == ("POST", "/v1/plan", 200)
    assert line["request_id"] == r.headers["X-Request-ID"]
    assert line["plan_status"] == r.json()["status"] == "ok"
    assert set(line["timing_ms"]) == set(STAGES) - {"fallback"}  # the stages that ran, and the total
    total = r.json()["diagnostics"]["timing_ms"]["total"]
    assert line["timing_ms"]["total"] == pytest.approx(total, abs=1e-3)


def test_an_unexpected_error_is_logged_with_its_request_id(
    client: TestClient,
    demo: dict[str, Any],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    fail_candidates(monkeypatch, ZeroDivisionError("internals"))
    with caplog.at_level(logging.INFO, logger="app"):
        client.post("/v1/candidates", json=demo, headers={"X-Request-ID": "boom"})
    (error,) = _lines(caplog, "app.errors")
    assert error["request_id"] == "boom" and error["level"] == "error"
    assert "ZeroDivisionError" in error["exc_info"]
    (line,) = _lines(caplog, "app.access")
    assert (line["status"], line["level"], line["request_id"]) == (500, "error", "boom")


@pytest.mark.parametrize(
    "headers",
    [
        {"content-type": "application/x-www-form-urlencoded"},  # a form of any web page, or `curl -d`
        {"content-type": "text/plain"},
        {"content-type": "multipart/form-data; boundary=x"},
        {},  # a browser's Blob without a type
        {"content-type": "application/json", "content-encoding": "gzip"},
    ],
)
def test_a_body_that_is_not_plain_json_is_415(client: TestClient, headers: dict[str, str]) -> None:
    raw = client.get("/v1/demo").content
    r = client.post("/v1/candidates", content=raw, headers=headers)
    assert r.status_code == 415 and r.json()["error"]["code"] == "unsupported_media_type"
    assert set(r.json()) == {"error"}


def test_a_json_body_with_parameters_is_read(client: TestClient) -> None:
    raw = client.get("/v1/demo").content
    for content_type in ("application/json", "Application/JSON; charset=utf-8"):
        r = client.post("/v1/candidates", content=raw, headers={"content-type": content_type})
        assert r.status_code == 200, (content_type, r.text)
    r = client.post("/v1/candidates", content=raw, headers={**JSON, "content-encoding": "identity"})
    assert r.status_code == 200


def test_body_too_large() -> None:
    small = TestClient(create_app(Settings(max_body_bytes=2048)))
    body = json.dumps({"reference_line": [[i, 0] for i in range(400)], "points": [[0, 0]]})
    r = small.post("/v1/frenet", content=body, headers=JSON)  # declared Content-Length
    assert r.status_code == 413 and r.json()["error"]["code"] == "payload_too_large"

    def chunks() -> Any:
        yield body[:1500].encode()
        yield body[1500:].encode()

    r = small.post("/v1/frenet", content=chunks(), headers=JSON)  # streamed, no Content-Length
    assert r.status_code == 413 and r.json()["error"]["code"] == "payload_too_large"
    assert (
        small.post("/v1/frenet", json={"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]]}).status_code
        == 200
    )


def _stalling_body(first: bytes, release: asyncio.Event) -> Any:
    async def chunks() -> Any:
        yield first
        await release.wait()
        yield b"]}"

    return chunks()


@pytest.mark.anyio
async def test_a_body_that_does_not_arrive_in_time_is_408() -> None:
    app = create_app(Settings(plan_processes=0, body_timeout=0.3))
    release = asyncio.Event()
    transport = httpx.ASGITransport(app=app)
    async with httpx.AsyncClient(transport=transport, base_url="http://test") as client:
        r = await client.post("/v1/frenet", content=_stalling_body(b'{"points": [', release), headers=JSON)
    release.set()
    assert r.status_code == 408 and r.json()["error"]["code"] == "request_timeout"
    assert r.headers["connection"] == "close"


@pytest.mark.anyio
async def test_bodies_in_flight_share_a_memory_budget() -> None:
    app = create_app(Settings(plan_processes=0, max_body_bytes=2048, max_inflight_body_bytes=3000))
    release = asyncio.Event()
    transport = httpx.ASGITransport(app=app)
    async with httpx.AsyncClient(transport=transport, base_url="http://test") as client:
        declared = {**JSON, "content-length": "2000"}
        held = asyncio.ensure_future(
            client.post("/v1/frenet", content=_stalling_body(b" " * 1998, release), headers=declared)
        )
        await asyncio.sleep(0.2)  # the first body holds 2000 of the 3000 bytes
        refused = await client.post("/v1/frenet", content=b" " * 2000, headers=JSON)
        assert refused.status_code == 503 and refused.headers["Retry-After"] == "1"
        assert refused.json()["error"]["code"] == "unavailable"
        small = await client.post("/v1/frenet", json={"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]]})
        assert small.status_code == 200  # what fits still passes
        release.set()
        assert (await held).status_code == 422  # a body of spaces and "]}"
        again = await client.post("/v1/frenet", content=b" " * 2000, headers=JSON)
        assert again.status_code == 422  # the budget was given back


def _keyed(**kw: Any) -> TestClient:
    return TestClient(create_app(Settings(plan_processes=0, api_keys=SecretStr("k-1, k-2"), **kw)))


def test_api_keys_guard_the_api_and_the_metrics_only() -> None:
    client = _keyed()
    for path in ("/v1/demo", "/metrics"):
        for headers in ({}, {"Authorization": "Bearer nope"}, {"Authorization": "Basic k-1"}):
            r = client.get(path, headers=headers)
            assert r.status_code == 401 and r.json()["error"]["code"] == "unauthorized", (path, headers)
            assert r.headers["WWW-Authenticate"].startswith("Bearer")
        assert client.get(path, headers={"Authorization": "Bearer k-2"}).status_code == 200
    r = client.post("/v1/frenet", json={"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]]})
    assert r.status_code == 401
    for path in ("/healthz", "/readyz", "/docs", "/openapi.json"):  # liveness, readiness, documentation
        assert client.get(path).status_code == 200, path


def test_the_rate_limit_answers_429_with_retry_after() -> None:
    client = _keyed(rate_limit=0.5, rate_burst=2)
    one, two = {"Authorization": "Bearer k-1"}, {"Authorization": "Bearer k-2"}
    assert [client.get("/v1/demo", headers=one).status_code for _ in range(2)] == [200, 200]
    r = client.get("/v1/demo", headers=one)
    assert r.status_code == 429 and r.json()["error"]["code"] == "rate_limited"
    assert r.headers["Retry-After"] == "2"  # 0.5 requests/s: the next token in 2 s
    assert client.get("/v1/demo", headers=two).status_code == 200  # each key its own bucket
    assert client.get("/healthz", headers=one).status_code == 200  # not limited


def test_token_buckets_refill_at_the_rate_up_to_the_burst() -> None:
    buckets = TokenBuckets(rate=2.0, burst=3, max_clients=2)
    assert [buckets.take("a", 0.0) for _ in range(3)] == [0.0, 0.0, 0.0]
    assert buckets.take("a", 0.0) == pytest.approx(0.5)
    assert buckets.take("a", 0.5) == 0.0  # one token back after 0.5 s
    assert buckets.take("a", 100.0) == 0.0 and buckets.take("a", 100.0) == 0.0
    assert buckets.take("a", 100.0) == 0.0 and buckets.take("a", 100.0) > 0  # never more than the burst
    buckets.take("b", 100.0)
    buckets.take("c", 100.0)  # a third client: the least recently seen ("a") is forgotten
    assert buckets.take("a", 100.0) == 0.0


def test_cors_is_off_unless_origins_are_listed(client: TestClient) -> None:
    preflight = {"Origin": "https://viewer.example", "Access-Control-Request-Method": "POST"}
    r = client.options("/v1/plan", headers=preflight)
    assert "access-control-allow-origin" not in r.headers
    r = client.get("/v1/demo", headers={"Origin": "https://viewer.example"})
    assert r.status_code == 200 and "access-control-allow-origin" not in r.headers

    listed = _keyed(cors_origins="https://viewer.example")
    r = listed.options("/v1/plan", headers={**preflight, "Access-Control-Request-Headers": "authorization"})
    assert r.status_code == 200  # answered before the key is asked for
    assert r.headers["access-control-allow-origin"] == "https://viewer.example"
    assert "authorization" in r.headers["access-control-allow-headers"].lower()
    other = listed.options("/v1/plan", headers={**preflight, "Origin": "https://evil.example"})
    assert other.headers.get("access-control-allow-origin") != "https://evil.example"
