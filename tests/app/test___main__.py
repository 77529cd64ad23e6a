"""`python -m app`: uvicorn run with the settings of the environment, one metrics directory for several
workers."""

from __future__ import annotations

import importlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from app.logs import uvicorn_log_config


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
