"""app.settings: from the environment (prefix KAPPA_), and the plan pool sized by the CPUs this process may
use."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from app import settings as settings_module
from app.settings import Settings, available_cpus, cgroup_cpu_limit


def test_settings_from_the_environment_and_the_defaults(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("KAPPA_PORT", "9001")
    monkeypatch.setenv("KAPPA_LOG_LEVEL", "DEBUG")
    monkeypatch.setenv("KAPPA_MAX_BODY_BYTES", "4096")
    settings = Settings()
    assert (settings.port, settings.log_level, settings.max_body_bytes) == (9001, "debug", 4096)
    assert (settings.host, settings.workers) == ("127.0.0.1", 1)


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


def test_the_bodies_in_flight_hold_at_least_the_largest_body() -> None:
    with pytest.raises(ValueError, match="max_inflight_body_bytes"):
        Settings(max_body_bytes=4096, max_inflight_body_bytes=2048)
    assert Settings(max_body_bytes=4096, max_inflight_body_bytes=4096).max_inflight_body_bytes == 4096


def test_speculation_is_on_unless_the_environment_turns_it_off(monkeypatch: pytest.MonkeyPatch) -> None:
    assert Settings().speculate is True
    monkeypatch.setenv("KAPPA_SPECULATE", "false")
    assert Settings().speculate is False
