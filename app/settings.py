"""Service settings from the environment (prefix ``KAPPA_``), e.g. ``KAPPA_PORT=9000``.

``python -m app`` reads every field (host, port, workers, log level go to uvicorn); every worker
process's :func:`app.main.create_app` reads them again, from the same environment. The README's
"Configuration" section lists them.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from app.limits import MAX_TIME_BUDGET_MS, MIN_TIME_BUDGET_MS

LogLevel = Literal["critical", "error", "warning", "info", "debug"]


#: cgroup files with the CPU quota and period of this process's container [µs]: v2, then v1
CGROUP_CPU_MAX = Path("/sys/fs/cgroup/cpu.max")
CGROUP_V1_QUOTA = Path("/sys/fs/cgroup/cpu/cpu.cfs_quota_us")
CGROUP_V1_PERIOD = Path("/sys/fs/cgroup/cpu/cpu.cfs_period_us")


def cgroup_cpu_limit() -> float | None:
    """CPUs the container's cgroup quota allows (``docker run --cpus``, a Kubernetes CPU limit), or None
    without a quota or outside a cgroup that has one."""
    try:
        quota, period = CGROUP_CPU_MAX.read_text().split()[:2]
    except (OSError, ValueError):
        try:
            quota, period = CGROUP_V1_QUOTA.read_text().strip(), CGROUP_V1_PERIOD.read_text().strip()
        except OSError:
            return None
    try:
        q, p = int(quota), int(period)
    except ValueError:  # "max": no quota
        return None
    return q / p if q > 0 and p > 0 else None


def available_cpus() -> int:
    """CPUs this process may use, at least 1: its affinity mask (where the OS has one), capped by the
    cgroup's CPU quota rounded up."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    limit = cgroup_cpu_limit()
    if limit is not None:
        cpus = min(cpus, math.ceil(limit))
    return max(1, cpus)


class Settings(BaseSettings):
    """Where and how the service runs (read by ``python -m app`` and ``app.main.create_app``)."""

    model_config = SettingsConfigDict(env_prefix="KAPPA_", extra="ignore")

    host: str = Field("127.0.0.1", description="Interface to listen on.")
    port: int = Field(8000, ge=1, le=65535, description="TCP port.")
    workers: int = Field(1, ge=1, le=256, description="Worker processes of uvicorn (HTTP).")
    log_level: LogLevel = Field("info", description="Log level of the service and of uvicorn.")
    max_body_bytes: int = Field(
        16 * 1024 * 1024, ge=1024, description="Largest request body accepted [bytes]; else 413."
    )
    plan_processes: int | None = Field(
        None,
        ge=0,
        le=256,
        description="Processes per worker that run plans; unset: CPUs (affinity, cgroup quota) ÷ workers "
        "(at least 1); 0: one thread of the worker itself (no process pool).",
    )
    time_budget_ms: float = Field(
        1000.0,
        ge=MIN_TIME_BUDGET_MS,
        le=MAX_TIME_BUDGET_MS,
        description="Compute budget of a plan whose request sets no options.time_budget_ms [ms]: a stage "
        "that ends past it makes the answer a braking fallback.",
    )
    max_pending_plans: int = Field(
        256, ge=1, le=100_000, description="Plans queued or running per worker; one more is a 503."
    )

    @field_validator("log_level", mode="before")
    @classmethod
    def _lower(cls, value: object) -> object:
        return value.lower() if isinstance(value, str) else value

    @field_validator("plan_processes", mode="before")
    @classmethod
    def _empty_is_unset(cls, value: object) -> object:
        return None if isinstance(value, str) and not value.strip() else value

    def plan_pool_size(self) -> int:
        """Processes of the plan pool of one worker: :attr:`plan_processes`, or CPUs ÷ workers."""
        if self.plan_processes is not None:
            return self.plan_processes
        return max(1, available_cpus() // self.workers)
