"""Prometheus metrics of the service (``GET /metrics``), with ``prometheus-client``.

* ``kappa_http_requests_total{route, method, status}`` — answers by route template (``/v1/plan``;
  ``unmatched`` for an unknown path) and status code;
* ``kappa_http_request_duration_seconds{route}`` — time from the request to the end of its answer [s];
* ``kappa_plans_total{status}`` — plans by their status (``ok``, ``stopped``, ``fallback``);
* ``kappa_plan_process_replacements_total{reason}`` — plan processes replaced (``calls``, ``memory``,
  ``died``);
* ``kappa_plan_stage_duration_seconds{stage}`` — wall time of the planner's stages as the plan's
  ``diagnostics.timing_ms`` reports them (:data:`app.models.plan.STAGES`) [s]; a stage that did not
  run is not observed.

Several HTTP workers: with ``PROMETHEUS_MULTIPROC_DIR`` set before the workers start (``python -m
app`` does it when ``KAPPA_WORKERS`` > 1), every worker writes its values there and each scrape sums
all of them (prometheus-client's multiprocess mode, counters and histograms only). Without it each
worker answers its own figures.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import get_args

from prometheus_client import REGISTRY, CollectorRegistry, Counter, Histogram, disable_created_metrics
from prometheus_client.exposition import choose_encoder
from prometheus_client.multiprocess import MultiProcessCollector

from app.models.plan import STAGES
from planner.result import Status as PlanStatus

#: environment variable of prometheus-client's multiprocess mode
MULTIPROC_ENV = "PROMETHEUS_MULTIPROC_DIR"
#: histogram buckets of a stage of the planner [s]
STAGE_BUCKETS = (0.001, 0.0025, 0.005, 0.01, 0.015, 0.02, 0.03, 0.05, 0.075, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0)
#: histogram buckets of an HTTP request [s] (queueing included)
REQUEST_BUCKETS = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0, 30.0)

disable_created_metrics()  # no ``*_created`` series: they double the output and nobody reads them

HTTP_REQUESTS = Counter(
    "kappa_http_requests_total",
    "HTTP answers by route template, method and status code.",
    ("route", "method", "status"),
)
HTTP_DURATION = Histogram(
    "kappa_http_request_duration_seconds",
    "Time from a request to the end of its answer, by route template [s].",
    ("route",),
    buckets=REQUEST_BUCKETS,
)
PLANS = Counter("kappa_plans_total", "Plans by status (ok, stopped, fallback).", ("status",))
PLAN_STAGE_DURATION = Histogram(
    "kappa_plan_stage_duration_seconds",
    f"Wall time of a stage of the planner ({', '.join(STAGES)}) [s].",
    ("stage",),
    buckets=STAGE_BUCKETS,
)
PROCESS_REPLACEMENTS = Counter(
    "kappa_plan_process_replacements_total",
    "Plan processes replaced, by reason (calls: served KAPPA_MAX_PROCESS_CALLS; memory: above "
    "KAPPA_MAX_PROCESS_RSS_MB after a request; died).",
    ("reason",),
)
for _status in get_args(PlanStatus):
    PLANS.labels(_status)
for _stage in STAGES:
    PLAN_STAGE_DURATION.labels(_stage)


def observe_request(route: str, method: str, status: int, seconds: float) -> None:
    """Count one HTTP answer and its duration [s]."""
    HTTP_REQUESTS.labels(route, method, str(status)).inc()
    HTTP_DURATION.labels(route).observe(seconds)


def observe_recycle(reason: str) -> None:
    """Count one replaced plan process."""
    PROCESS_REPLACEMENTS.labels(reason).inc()


def observe_plan(status: str, timing_ms: Mapping[str, float]) -> None:
    """Count one plan by ``status`` and observe its stages' wall times ``timing_ms`` [ms]."""
    PLANS.labels(status).inc()
    for stage in STAGES:
        if stage in timing_ms:
            PLAN_STAGE_DURATION.labels(stage).observe(timing_ms[stage] / 1e3)


def exposition(accept: str | None) -> tuple[bytes, str]:
    """The metrics in the format ``accept`` asks for (Prometheus text unless OpenMetrics is asked
    for), and its content type; in multiprocess mode the sum over every process."""
    registry = REGISTRY
    if os.environ.get(MULTIPROC_ENV):
        registry = CollectorRegistry()
        MultiProcessCollector(registry)
    encoder, content_type = choose_encoder(accept or "")
    return encoder(registry), content_type
