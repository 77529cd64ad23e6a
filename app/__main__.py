"""``python -m app``: serve the API with granian as configured by :class:`app.settings.Settings`.

**Why granian.** The service needs, from its HTTP server, what no ASGI middleware can do because it
happens before a request exists: a deadline on reading a request's headers (a slow or idle client
holds a connection, a file descriptor and memory), a bound on their size (431), a keep-alive bound, and
a cap on the requests handled at once. uvicorn (h11/httptools) has no header read timeout and no header
size cap with httptools; gunicorn's limits apply to its own sync parser, not to uvicorn workers;
hypercorn bounds idle connections but not their count and parses in Python. granian (Rust, hyper) has
them all as settings, answers an oversize head 431 itself, supervises its workers (respawns one that
died, replaces one above an RSS limit, kills one that does not stop in time) and runs the ASGI app
unchanged. What it does not do — a body read deadline (408), a memory budget for bodies in flight,
415/413, keys, rate limits — :mod:`app.middleware` does.

This process is granian's supervisor: it raises its soft limit of open files to the hard one (the
workers inherit it), keeps the metrics of every worker in one ``PROMETHEUS_MULTIPROC_DIR`` (a fresh
temporary directory removed at exit, unless the variable is set; then its ``*.db`` files of an earlier
run are removed), serves ``/metrics`` itself when ``KAPPA_METRICS_PORT`` is set, and spawns (not forks)
the workers.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
import resource
import shutil
import tempfile
from pathlib import Path
from typing import Any

from app.logs import server_log_config
from app.settings import SUPERVISOR_ENV, Settings

#: prometheus-client's multiprocess directory (see app.metrics; not imported here, so that the
#: variable is set before prometheus-client is imported anywhere)
MULTIPROC_ENV = "PROMETHEUS_MULTIPROC_DIR"
#: how often granian samples the workers' resident memory [s]
RSS_SAMPLE_INTERVAL_S = 5
#: connections waiting to be accepted (the kernel's listen backlog)
BACKLOG = 2048
#: open files a worker keeps for itself beyond its connections (plan processes' pipes, logs, libraries)
RESERVED_FILES = 128
#: of ``KAPPA_SHUTDOWN_TIMEOUT``, what is left for the supervisor's own exit once it killed a worker that
#: did not stop in time (granian's takes about 1.5 s here) [s]
SUPERVISOR_EXIT_S = 2.0


def prepare_multiprocess_metrics() -> Path | None:
    """Point ``PROMETHEUS_MULTIPROC_DIR`` at an empty directory; return it if it was made here."""
    given = os.environ.get(MULTIPROC_ENV)
    if given:
        path = Path(given)
        path.mkdir(parents=True, exist_ok=True)
        for stale in path.glob("*.db"):
            stale.unlink()
        return None
    made = Path(tempfile.mkdtemp(prefix="kappa-metrics-"))
    os.environ[MULTIPROC_ENV] = str(made)
    return made


def raise_open_files_limit() -> int:
    """Raise the soft limit of open files to the hard one (each connection is a file); the new limit."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if hard != resource.RLIM_INFINITY and soft < hard:
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
            soft = hard
    return soft


def connection_cap(settings: Settings, open_files: int) -> int:
    """Connections a worker serves at once: ``KAPPA_MAX_CONNECTIONS``, but no more than the open-files
    limit allows (a connection past it would fail to be accepted rather than wait in the backlog)."""
    return max(1, min(settings.max_connections, open_files - RESERVED_FILES))


def server_options(settings: Settings, open_files: int = 1 << 20) -> dict[str, Any]:
    """The options of granian's ``Server`` for ``settings`` and a limit of ``open_files``."""
    from granian.constants import HTTPModes, Interfaces
    from granian.http import HTTP1Settings

    return {
        "target": "app.main:app",
        "address": settings.host,
        "port": settings.port,
        "interface": Interfaces.ASGI,
        "workers": settings.workers,
        "http": HTTPModes.http1,
        "websockets": False,
        "backlog": BACKLOG,
        "backpressure": connection_cap(settings, open_files),
        "http1_settings": HTTP1Settings(
            header_read_timeout=max(1, round(1e3 * settings.header_timeout)),
            keep_alive=True,
            max_buffer_size=settings.max_header_bytes,
        ),
        "log_enabled": True,
        "log_level": settings.log_level,
        "log_dictconfig": server_log_config(settings.log_level),
        "log_access": False,  # the service logs one JSON line per request (app.access)
        "respawn_failed_workers": True,
        "workers_max_rss": settings.max_process_rss_mb,
        "rss_sample_interval": RSS_SAMPLE_INTERVAL_S,
        "workers_kill_timeout": max(1, math.floor(settings.shutdown_timeout - SUPERVISOR_EXIT_S)),
    }


def serve_metrics(settings: Settings) -> None:
    """Serve ``/metrics`` of every worker on ``KAPPA_METRICS_PORT`` from this process (a thread)."""
    from prometheus_client import CollectorRegistry, start_http_server
    from prometheus_client.multiprocess import MultiProcessCollector

    registry = CollectorRegistry()
    MultiProcessCollector(registry)
    start_http_server(settings.metrics_port or 0, addr=settings.host, registry=registry)


def main() -> None:
    """Run granian with the settings of the environment (``KAPPA_*``)."""
    from granian.server import Server

    settings = Settings()
    os.environ[SUPERVISOR_ENV] = str(os.getpid())  # the workers die with this process
    open_files = raise_open_files_limit()
    made = prepare_multiprocess_metrics()
    multiprocessing.set_start_method("spawn", force=True)
    try:
        if settings.metrics_port:
            serve_metrics(settings)
        Server(**server_options(settings, open_files)).serve()
    finally:
        if made is not None:
            shutil.rmtree(made, ignore_errors=True)


if __name__ == "__main__":
    main()
