"""`python -m app`: granian run with the settings of the environment, one metrics directory for every
worker, the open-files limit raised."""

from __future__ import annotations

import importlib
import os
import resource
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from app.logs import server_log_config
from app.settings import Settings


@pytest.fixture
def served(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[dict[str, Any]]]:
    """granian's ``Server`` replaced by a recorder (with the metrics directory seen while it 'serves')."""
    calls: list[dict[str, Any]] = []

    class Recorder:
        def __init__(self, **options: Any) -> None:
            self.options = options

        def serve(self) -> None:
            calls.append({"multiproc_dir": os.environ.get("PROMETHEUS_MULTIPROC_DIR"), **self.options})

    monkeypatch.setattr("granian.server.Server", Recorder)
    monkeypatch.setattr("multiprocessing.set_start_method", lambda *a, **k: None)
    monkeypatch.setenv("PROMETHEUS_MULTIPROC_DIR", "")  # restored (unset) afterwards
    yield calls


def test_python_m_app_reads_the_environment(
    served: list[dict[str, Any]], monkeypatch: pytest.MonkeyPatch
) -> None:
    main = importlib.import_module("app.__main__").main
    for name, value in {
        "KAPPA_PORT": "9123",
        "KAPPA_WORKERS": "3",
        "KAPPA_LOG_LEVEL": "debug",
        "KAPPA_HEADER_TIMEOUT": "2.5",
        "KAPPA_MAX_HEADER_BYTES": "16384",
        "KAPPA_MAX_CONNECTIONS": "77",
        "KAPPA_SHUTDOWN_TIMEOUT": "6.5",
        "KAPPA_MAX_PROCESS_RSS_MB": "400",
    }.items():
        monkeypatch.setenv(name, value)
    main()
    (call,) = served
    assert (call["target"], call["port"], call["workers"]) == ("app.main:app", 9123, 3)
    assert call["interface"] == "asgi" and call["http"] == "1" and call["websockets"] is False
    assert call["log_level"] == "debug" and call["log_dictconfig"] == server_log_config("debug")
    assert call["log_access"] is False
    http1 = call["http1_settings"]
    assert (http1.header_read_timeout, http1.max_buffer_size, http1.keep_alive) == (2500, 16384, True)
    assert call["backpressure"] == 77 and call["workers_kill_timeout"] == 4  # 2 s before the 6.5 s
    assert call["workers_max_rss"] == 400 and call["respawn_failed_workers"] is True
    # one metrics directory for every worker, made before they start, removed after
    assert call["multiproc_dir"] and not Path(call["multiproc_dir"]).exists()


def test_a_given_metrics_directory_is_emptied(
    served: list[dict[str, Any]], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    (tmp_path / "counter_123.db").write_bytes(b"stale")
    (tmp_path / "keep.txt").write_text("mine")
    monkeypatch.setenv("PROMETHEUS_MULTIPROC_DIR", str(tmp_path))
    importlib.import_module("app.__main__").main()
    assert served[0]["multiproc_dir"] == str(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


def test_the_open_files_limit_is_raised_to_the_hard_one(monkeypatch: pytest.MonkeyPatch) -> None:
    limits = {"now": (1024, 4096)}
    monkeypatch.setattr(resource, "getrlimit", lambda which: limits["now"])
    monkeypatch.setattr(resource, "setrlimit", lambda which, value: limits.update(now=value))
    module = importlib.import_module("app.__main__")
    assert module.raise_open_files_limit() == 4096
    assert limits["now"] == (4096, 4096)
    # connections past the open files would fail to be accepted: the cap keeps them in the backlog
    settings = Settings(max_connections=10_000)
    assert module.server_options(settings, 4096)["backpressure"] == 4096 - module.RESERVED_FILES
    assert module.server_options(settings, 1 << 20)["backpressure"] == 10_000


def test_the_metrics_port_moves_metrics_off_the_service_port() -> None:
    from fastapi.testclient import TestClient

    from app.main import create_app

    assert TestClient(create_app(Settings())).get("/metrics").status_code == 200
    for port in (9464, 0):
        moved = TestClient(create_app(Settings(metrics_port=port)))
        assert moved.get("/metrics").status_code == 404
        assert "/metrics" not in moved.get("/openapi.json").json()["paths"]
