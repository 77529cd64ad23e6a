"""app.middleware: request ids, one JSON log line per request labelled by its route, bodies read as
JSON whatever their Content-Type, and bounded in size."""

from __future__ import annotations

import json
import logging
import uuid
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.logs import JSONFormatter
from app.main import create_app
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
    assert set(line["timing_ms"]) >= set(STAGES)
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
        small.post(
            "/v1/frenet", json={"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]]}
        ).status_code
        == 200
    )
