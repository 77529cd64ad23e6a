"""The worker's side of a computing request (``/v1/plan``, ``/v1/candidates``, ``/v1/frenet``,
``/v1/cartesian``): read the body, admit it, hand it to a plan process as bytes, answer.

Every computing endpoint goes through the same bounded admission (:class:`app.executor.PlanExecutor`):
a request that finds the queue full, no plan process free before its deadline, its process dead or the
service stopping is answered 503 with ``Retry-After``. The deadline of the wait is the request's budget
from its arrival: ``options.time_budget_ms`` where the body has one (found without parsing it, a plain
search of the bytes; the plan process checks it again on the parsed request), else the server's
``KAPPA_TIME_BUDGET_MS``.

Every answer carries ``Server-Timing``: ``wait`` (from the request's arrival until a plan process took
it up: reading the body, queueing, the hand-over), ``run`` (in the plan process: parsing, validating,
computing, writing the answer) and ``total`` [ms]; a refusal only ``total``.
"""

from __future__ import annotations

import re
import time

from fastapi import Request, Response

from app import metrics
from app.errors import error_response
from app.executor import DeadlineExceeded, Overloaded, PlanExecutor, ProcessDied, ShuttingDown
from app.jobs import Job, Kind, Outcome, run_job
from app.limits import MAX_TIME_BUDGET_MS, MIN_TIME_BUDGET_MS
from app.settings import Settings

#: seconds a client is asked to wait after a 503
RETRY_AFTER_S = 1
#: the key of a request's own budget, as it appears in a JSON body
_BUDGET_KEY = b'"time_budget_ms"'
_NUMBER_AFTER_COLON = re.compile(rb"\s*:\s*(-?[0-9]+(?:\.[0-9]+)?(?:[eE][-+]?[0-9]+)?)")

#: refusals of the executor → (error code, message)
_REFUSALS: dict[type[Exception], str] = {
    Overloaded: "overloaded",
    DeadlineExceeded: "deadline_exceeded",
    ProcessDied: "plan_process_died",
    ShuttingDown: "shutting_down",
}


def arrival(request: Request) -> float:
    """When the request arrived (``time.monotonic()`` [s], noted by
    :class:`app.middleware.RequestContextMiddleware`; now if it did not)."""
    arrived = getattr(request.state, "arrived", None)
    return float(arrived) if arrived is not None else time.monotonic()


def requested_budget_ms(body: bytes, default_ms: float) -> float:
    """``options.time_budget_ms`` of a JSON body, read without parsing it, when it is a number in the
    accepted range; else ``default_ms``. (A body with the key elsewhere, or twice, is refused by its
    validation anyway.)"""
    at = body.find(_BUDGET_KEY)
    if at < 0:
        return default_ms
    match = _NUMBER_AFTER_COLON.match(body, at + len(_BUDGET_KEY))
    if match is None:
        return default_ms
    value = float(match.group(1))
    return value if MIN_TIME_BUDGET_MS <= value <= MAX_TIME_BUDGET_MS else default_ms


def _unavailable(code: str, message: str) -> Response:
    response = error_response(503, code, message)
    response.headers["Retry-After"] = str(RETRY_AFTER_S)
    return response


def _timing(response: Response, arrived: float, started: float | None = None) -> Response:
    """``response`` with its ``Server-Timing`` header (times ``time.monotonic()`` [s])."""
    now = time.monotonic()
    parts = (
        []
        if started is None
        else [f"wait;dur={1e3 * (started - arrived):.1f}", f"run;dur={1e3 * (now - started):.1f}"]
    )
    response.headers["Server-Timing"] = ", ".join([*parts, f"total;dur={1e3 * (now - arrived):.1f}"])
    return response


async def compute(request: Request, kind: Kind, settings: Settings, executor: PlanExecutor) -> Response:
    """Answer a computing request of ``kind`` (see the module's docstring)."""
    arrived = arrival(request)
    body = await request.body()
    budget_ms = settings.time_budget_ms
    if kind in ("plan", "candidates"):
        budget_ms = requested_budget_ms(body, settings.time_budget_ms)
    job = Job(kind, body, arrived, settings.time_budget_ms, settings.speculate)
    try:
        outcome: Outcome = await executor.run(run_job, job, deadline=arrived + budget_ms / 1e3)
    except (Overloaded, DeadlineExceeded, ProcessDied, ShuttingDown) as exc:
        refusal = ShuttingDown if executor.closing else type(exc)  # a process cut at shutdown
        response = _unavailable(_REFUSALS[refusal], f"{exc}; retry later.")
        if executor.closing:
            response.headers["Connection"] = "close"
        return _timing(response, arrived)
    if outcome.plan_status is not None:
        metrics.observe_plan(outcome.plan_status, outcome.timing_ms or {})
        request.state.plan_status = outcome.plan_status
        request.state.plan_timing_ms = outcome.timing_ms
    return _timing(Response(outcome.body, media_type="application/json"), arrived, outcome.started)
