"""Service settings from the environment (prefix ``KAPPA_``), e.g. ``KAPPA_PORT=9000``.

``python -m app`` reads every field (host, port, workers, the HTTP limits go to granian); every worker
process's :func:`app.main.create_app` reads them again, from the same environment. The README's
"Configuration" section lists them.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Literal

from pydantic import Field, SecretStr, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from app.limits import MAX_BODY_BYTES, MAX_TIME_BUDGET_MS, MIN_TIME_BUDGET_MS

#: set by ``python -m app`` to its own pid, for its workers: a worker it supervises dies with it
SUPERVISOR_ENV = "KAPPA_SUPERVISOR_PID"

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
    workers: int = Field(1, ge=1, le=256, description="HTTP worker processes (granian).")
    log_level: LogLevel = Field("info", description="Log level of the service and of its HTTP server.")
    max_body_bytes: int = Field(
        MAX_BODY_BYTES, ge=1024, description="Largest request body accepted [bytes]; else 413."
    )
    max_inflight_body_bytes: int = Field(
        4 * MAX_BODY_BYTES,
        ge=1024,
        description="Request bodies being received or computed on at once per worker [bytes]; a body "
        "that would pass it is refused 503 (Retry-After).",
    )
    body_timeout: float = Field(
        15.0,
        gt=0,
        le=3600,
        description="Time to receive a whole body from its request's arrival [s]; else 408.",
    )
    header_timeout: float = Field(
        10.0,
        ge=0.001,
        le=60,
        description="Time a connection has to deliver a request's headers, its first or the next one on a "
        "kept-alive connection [s]; else it is closed (granian's HTTP/1 header read timeout).",
    )
    max_header_bytes: int = Field(
        65536, ge=8192, le=16 * 1024 * 1024, description="Largest request head [bytes]; else 431."
    )
    max_connections: int = Field(
        4096,
        ge=1,
        le=1_000_000,
        description="Connections served at once per worker (granian's backpressure; at most the open-files "
        "limit less a reserve); more wait in the listen backlog.",
    )
    shutdown_timeout: float = Field(
        8.0,
        ge=4.0,
        le=3600,
        description="Longest stop from SIGTERM [s]: new work is refused at once (503), plans still running "
        "3 s before it are cut (503), a worker still alive 2 s before it is killed.",
    )
    max_process_rss_mb: int = Field(
        500,
        ge=64,
        le=1_000_000,
        description="A plan process above it after a request, or a worker above it, is replaced [MiB].",
    )
    max_process_calls: int = Field(
        10_000, ge=1, le=100_000_000, description="Requests a plan process serves before it is replaced."
    )
    api_keys: SecretStr = Field(
        SecretStr(""),
        description="Comma-separated API keys; set, /v1/* and /metrics need Authorization: Bearer <key>.",
    )
    rate_limit: float = Field(
        0.0, ge=0, le=1e6, description="Requests per second per client to /v1/* (per worker); 0: no limit."
    )
    rate_burst: int | None = Field(
        None, ge=1, le=1_000_000, description="Requests a client may send at once; unset: twice the rate."
    )
    cors_origins: str = Field(
        "", description="Comma-separated origins allowed to call the API from a browser (CORS); empty: none."
    )
    docs: bool = Field(True, description="Serve /docs, /redoc and /openapi.json.")
    metrics_port: int | None = Field(
        None,
        ge=0,
        le=65535,
        description="Port of /metrics; unset: the service's own port; 0: no metrics endpoint.",
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
    speculate: bool = Field(
        True,
        description="A plan also runs, on a second thread of its plan process, the solves it will likely "
        "need next (the same answers, sooner where a core is free; about 7 % more CPU). false: one thread "
        "per plan.",
    )

    @model_validator(mode="after")
    def _bodies_fit_the_budget(self) -> Settings:
        if self.max_inflight_body_bytes < self.max_body_bytes:
            raise ValueError(
                f"max_inflight_body_bytes ({self.max_inflight_body_bytes}) must be at least max_body_bytes "
                f"({self.max_body_bytes}): the largest body would never fit"
            )
        return self

    @field_validator("log_level", mode="before")
    @classmethod
    def _lower(cls, value: object) -> object:
        return value.lower() if isinstance(value, str) else value

    @field_validator("plan_processes", "metrics_port", "rate_burst", mode="before")
    @classmethod
    def _empty_is_unset(cls, value: object) -> object:
        return None if isinstance(value, str) and not value.strip() else value

    @property
    def api_key_list(self) -> list[str]:
        """The API keys (empty: no key needed)."""
        return [k.strip() for k in self.api_keys.get_secret_value().split(",") if k.strip()]

    @property
    def cors_origin_list(self) -> list[str]:
        """The origins allowed by CORS (empty: CORS off)."""
        return [o.strip() for o in self.cors_origins.split(",") if o.strip()]

    @property
    def burst(self) -> int:
        """Requests a client may send at once under the rate limit."""
        return self.rate_burst if self.rate_burst is not None else max(1, math.ceil(2 * self.rate_limit))

    @property
    def metrics_on_service_port(self) -> bool:
        """Whether ``/metrics`` is served on the service's port."""
        return self.metrics_port is None

    def plan_pool_size(self) -> int:
        """Processes of the plan pool of one worker: :attr:`plan_processes`, or CPUs ÷ workers."""
        if self.plan_processes is not None:
            return self.plan_processes
        return max(1, available_cpus() // self.workers)
