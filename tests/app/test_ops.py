"""Operations: request ids, JSON log lines, /metrics, settings from the environment, `python -m app`,
and plans in a process pool (the event loop answers /healthz meanwhile; overload is a 503).

No timing here: the latency of /healthz under load is measured by ``bench/load.py``.
"""

from __future__ import annotations

import asyncio
import importlib
import json
import logging
import os
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from fastapi.testclient import TestClient
from prometheus_client.parser import text_string_to_metric_families

from app import settings as settings_module
from app.deps import get_plan_executor
from app.executor import Overloaded, PlanExecutor
from app.logs import REQUEST_ID, JSONFormatter, uvicorn_log_config
from app.main import create_app
from app.routes import candidates as candidates_route
from app.settings import Settings, available_cpus, cgroup_cpu_limit

STAGES = {"total", "reference", "candidates", "lateral", "speed"}


def _uuid4(value: str) -> bool:
    try:
        return uuid.UUID(value).version == 4
    except ValueError:
        return False


# -- request ids -------------------------------------------------------------------------------


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
        client.post("/v1/plan", content=b"{", headers={"X-Request-ID": "r422"}),
    ]
    small = TestClient(create_app(Settings(max_body_bytes=2048)))
    answers.append(small.post("/v1/plan", content=b" " * 4096, headers={"X-Request-ID": "r413"}))

    def crash(*args: Any, **kwargs: Any) -> Any:
        raise ZeroDivisionError("internals")

    monkeypatch.setattr(candidates_route, "generate_candidates", crash)
    answers.append(client.post("/v1/candidates", json=demo, headers={"X-Request-ID": "r500"}))
    assert [(r.status_code, r.headers.get("X-Request-ID")) for r in answers] == [
        (404, "r404"),
        (405, "r405"),
        (422, "r422"),
        (413, "r413"),
        (500, "r500"),
    ]
    assert all(set(r.json()) == {"error"} for r in answers)


# -- log lines ---------------------------------------------------------------------------------


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
        assert small.post("/v1/plan", content=b" " * 4096).status_code == 413
        assert small.post("/v1/nowhere", content=b" " * 4096).status_code == 413
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
    assert set(line["timing_ms"]) >= STAGES
    total = r.json()["diagnostics"]["timing_ms"]["total"]
    assert line["timing_ms"]["total"] == pytest.approx(total, abs=1e-3)


def test_an_unexpected_error_is_logged_with_its_request_id(
    client: TestClient,
    demo: dict[str, Any],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    def crash(*args: Any, **kwargs: Any) -> Any:
        raise ZeroDivisionError("internals")

    monkeypatch.setattr(candidates_route, "generate_candidates", crash)
    with caplog.at_level(logging.INFO, logger="app"):
        client.post("/v1/candidates", json=demo, headers={"X-Request-ID": "boom"})
    (error,) = _lines(caplog, "app.errors")
    assert error["request_id"] == "boom" and error["level"] == "error"
    assert "ZeroDivisionError" in error["exc_info"]
    (line,) = _lines(caplog, "app.access")
    assert (line["status"], line["level"], line["request_id"]) == (500, "error", "boom")


def test_the_json_formatter() -> None:
    make = logging.getLogRecordFactory()  # notes the request id (app.logs)
    token = REQUEST_ID.set("rid-9")
    try:
        record = make("app.x", logging.WARNING, __file__, 1, "%d things", (3,), None)
    finally:
        REQUEST_ID.reset(token)
    record.__dict__.update(count=3, where=Path("/tmp"))
    line = JSONFormatter().format(record)
    assert "\n" not in line
    entry = json.loads(line)
    assert entry["message"] == "3 things" and entry["level"] == "warning" and entry["logger"] == "app.x"
    assert (entry["request_id"], entry["count"], entry["where"]) == ("rid-9", 3, "/tmp")
    assert entry["ts"].endswith("+00:00")
    outside = make("app.x", logging.WARNING, __file__, 1, "%d things", (3,), None)
    assert "request_id" not in json.loads(JSONFormatter().format(outside))


def test_uvicorn_logs_are_json_too() -> None:
    config = uvicorn_log_config("debug")
    assert config["formatters"]["json"]["()"] == "app.logs.JSONFormatter"
    assert config["loggers"]["app"]["level"] == config["loggers"]["uvicorn"]["level"] == "DEBUG"


# -- metrics -----------------------------------------------------------------------------------


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
    assert client.post("/v1/plan", json=demo).json()["status"] == "ok"
    assert client.post("/v1/plan", content=b"[").status_code == 422
    after = _samples(client)

    def delta(name: str, **labels: str) -> float:
        return after.get(key(name, **labels), 0.0) - before.get(key(name, **labels), 0.0)

    assert delta("kappa_plans_total", status="ok") == 1
    assert delta("kappa_plans_total", status="fallback") == 0
    assert key("kappa_plans_total", status="stopped") in after  # every status is there from the start
    for stage in STAGES:
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


def test_metrics_in_openmetrics_on_request(client: TestClient) -> None:
    r = client.get("/metrics", headers={"Accept": "application/openmetrics-text; version=1.0.0"})
    assert r.headers["content-type"].startswith("application/openmetrics-text")
    assert r.text.rstrip().endswith("# EOF")


def test_metrics_in_the_openapi_document(client: TestClient) -> None:
    op = client.get("/openapi.json").json()["paths"]["/metrics"]["get"]
    assert op["operationId"] == "metrics" and op["tags"] == ["operations"]
    assert set(op["responses"]["200"]["content"]) == {"text/plain", "application/openmetrics-text"}


# -- settings and `python -m app` --------------------------------------------------------------


def test_settings_from_the_environment(monkeypatch: pytest.MonkeyPatch) -> None:
    env = {
        "KAPPA_HOST": "0.0.0.0",
        "KAPPA_PORT": "8080",
        "KAPPA_WORKERS": "3",
        "KAPPA_LOG_LEVEL": "WARNING",
        "KAPPA_MAX_BODY_BYTES": "65536",
        "KAPPA_PLAN_PROCESSES": "5",
        "KAPPA_MAX_PENDING_PLANS": "17",
    }
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    s = Settings()
    assert (s.host, s.port, s.workers, s.log_level) == ("0.0.0.0", 8080, 3, "warning")
    assert (s.max_body_bytes, s.plan_processes, s.max_pending_plans, s.plan_pool_size()) == (65536, 5, 17, 5)

    monkeypatch.setenv("KAPPA_PLAN_PROCESSES", "")  # unset: CPUs ÷ workers, at least 1
    assert Settings().plan_pool_size() == max(1, available_cpus() // 3)
    monkeypatch.setenv("KAPPA_PLAN_PROCESSES", "0")
    assert Settings().plan_pool_size() == 0
    for name, bad in (("KAPPA_WORKERS", "0"), ("KAPPA_PLAN_PROCESSES", "-1"), ("KAPPA_LOG_LEVEL", "loud")):
        monkeypatch.setenv(name, bad)
        with pytest.raises(ValueError, match=name.removeprefix("KAPPA_").lower()):
            Settings()
        monkeypatch.setenv(name, env[name])


def test_the_cpu_count_follows_the_cgroup_quota(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    v2, quota, period = tmp_path / "cpu.max", tmp_path / "quota", tmp_path / "period"
    monkeypatch.setattr(settings_module, "CGROUP_CPU_MAX", v2)
    monkeypatch.setattr(settings_module, "CGROUP_V1_QUOTA", quota)
    monkeypatch.setattr(settings_module, "CGROUP_V1_PERIOD", period)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: set(range(64)))
    assert (cgroup_cpu_limit(), available_cpus()) == (None, 64)  # no cgroup files
    v2.write_text("150000 100000\n")  # docker run --cpus 1.5
    assert (cgroup_cpu_limit(), available_cpus()) == (1.5, 2)
    v2.write_text("max 100000\n")
    assert (cgroup_cpu_limit(), available_cpus()) == (None, 64)
    v2.unlink()
    quota.write_text("50000\n")  # cgroup v1, half a CPU
    period.write_text("100000\n")
    assert (cgroup_cpu_limit(), available_cpus()) == (0.5, 1)
    quota.write_text("-1\n")
    assert (cgroup_cpu_limit(), available_cpus()) == (None, 64)
    monkeypatch.setenv("KAPPA_WORKERS", "4")
    monkeypatch.delenv("KAPPA_PLAN_PROCESSES", raising=False)
    assert Settings().plan_pool_size() == 16


@pytest.fixture
def uvicorn_calls(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[dict[str, Any]]]:
    """`uvicorn.run` replaced by a recorder (with the metrics directory seen while it 'runs')."""
    calls: list[dict[str, Any]] = []

    def run(app: str, **kwargs: Any) -> None:
        calls.append({"app": app, "multiproc_dir": os.environ.get("PROMETHEUS_MULTIPROC_DIR"), **kwargs})

    monkeypatch.setattr("uvicorn.run", run)
    monkeypatch.setenv("PROMETHEUS_MULTIPROC_DIR", "")  # restored (unset) afterwards
    yield calls


def test_python_m_app_reads_the_environment(
    uvicorn_calls: list[dict[str, Any]], monkeypatch: pytest.MonkeyPatch
) -> None:
    main = importlib.import_module("app.__main__").main
    monkeypatch.setenv("KAPPA_PORT", "9123")
    monkeypatch.setenv("KAPPA_WORKERS", "3")
    monkeypatch.setenv("KAPPA_LOG_LEVEL", "debug")
    main()
    (call,) = uvicorn_calls
    assert (call["app"], call["port"], call["workers"]) == ("app.main:app", 9123, 3)
    assert call["log_level"] == "debug"
    assert call["access_log"] is False and call["log_config"] == uvicorn_log_config("debug")
    # several workers: one metrics directory for all of them, made before they start, removed after
    assert call["multiproc_dir"] and not Path(call["multiproc_dir"]).exists()

    monkeypatch.setenv("KAPPA_WORKERS", "1")
    monkeypatch.setenv("PROMETHEUS_MULTIPROC_DIR", "")
    main()
    assert uvicorn_calls[1]["workers"] == 1 and not uvicorn_calls[1]["multiproc_dir"]


def test_a_given_metrics_directory_is_emptied(
    uvicorn_calls: list[dict[str, Any]], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    (tmp_path / "counter_123.db").write_bytes(b"stale")
    (tmp_path / "keep.txt").write_text("mine")
    monkeypatch.setenv("PROMETHEUS_MULTIPROC_DIR", str(tmp_path))
    monkeypatch.setenv("KAPPA_WORKERS", "2")
    importlib.import_module("app.__main__").main()
    assert uvicorn_calls[0]["multiproc_dir"] == str(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


# -- where plans run ---------------------------------------------------------------------------


@pytest.mark.anyio
async def test_plans_run_in_a_process_pool_while_the_loop_answers(demo: dict[str, Any]) -> None:
    app = create_app(Settings(plan_processes=1))
    async with app.router.lifespan_context(app):
        executor: PlanExecutor = app.state.plan_executor
        assert executor.uses_processes
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as client:
            plans = [asyncio.create_task(client.post("/v1/plan", json=demo)) for _ in range(4)]
            while executor.pending < 4:  # all four queued for the one process
                await asyncio.sleep(0.001)
            health = await client.get("/healthz")
            assert health.status_code == 200 and health.json() == {"status": "ok"}
            assert executor.pending > 0  # answered while plans were queued or running
            answers = await asyncio.gather(*plans)
            assert [r.json()["status"] for r in answers] == ["ok"] * 4
            # a planner error raised in the pool process keeps its type, status and field
            demo["ego"]["heading"] = 3.0
            r = await client.post("/v1/plan", json=demo)
            assert r.status_code == 422 and r.json()["error"]["code"] == "invalid_input"
            assert r.json()["error"]["details"][0]["field"] == "ego.heading"
    assert not executor.uses_processes  # the lifespan's end stopped the pool


@pytest.mark.anyio
async def test_a_dead_pool_process_fails_its_call_and_the_pool_is_renewed() -> None:
    executor = PlanExecutor(processes=1, max_pending=4)
    await executor.start()
    try:
        with pytest.raises(Exception, match="terminated abruptly"):
            await executor.run(os._exit, 3)
        assert await executor.run(abs, -2) == 2
    finally:
        executor.shutdown()


@pytest.mark.anyio
async def test_the_executor_refuses_more_than_max_pending() -> None:
    executor = PlanExecutor(processes=0, max_pending=1)
    started, release = asyncio.Event(), asyncio.Event()
    loop = asyncio.get_running_loop()

    def blocking(_: None) -> str:
        loop.call_soon_threadsafe(started.set)
        asyncio.run_coroutine_threadsafe(release.wait(), loop).result()
        return "done"

    first = asyncio.create_task(executor.run(blocking, None))
    await started.wait()
    with pytest.raises(Overloaded):
        await executor.run(blocking, None)
    release.set()
    assert await first == "done" and executor.pending == 0


class _FullExecutor(PlanExecutor):
    async def run(self, fn: Any, arg: Any) -> Any:
        raise Overloaded("256 plans are queued or running")


def test_overload_is_a_503_to_retry(demo: dict[str, Any]) -> None:
    app = create_app(Settings(plan_processes=0))
    app.dependency_overrides[get_plan_executor] = lambda: _FullExecutor(processes=0, max_pending=1)
    r = TestClient(app).post("/v1/plan", json=demo, headers={"X-Request-ID": "busy"})
    assert r.status_code == 503 and r.headers["Retry-After"] == "1" and r.headers["X-Request-ID"] == "busy"
    assert r.json()["error"]["code"] == "overloaded" and "256 plans" in r.json()["error"]["message"]
