"""The work of the computing endpoints, as it runs in a plan process (:mod:`app.executor`).

The worker hands over a :class:`Job` — the request body as bytes, the time it arrived and the server's
default budget — and gets an :class:`Outcome` back — the answer's JSON as bytes and what the logs and
metrics need: no pydantic model crosses between the processes, only bytes and a few numbers. All the
CPU work happens here: parsing and validating the body (:mod:`app.intake`, at a cost bounded by its
size), the computation, and writing the answer.

**The deadline of a plan.** Its budget (``options.time_budget_ms``, else the server's) counts from the
request's arrival (``time.monotonic()`` is the same clock in every process of the machine): what
reading the body, waiting for a plan process and parsing took is gone from it, and the planner gets
what remains (at least :data:`app.limits.MIN_TIME_BUDGET_MS`: a plan that starts with its budget spent
ends at once as a braking ``fallback``). A request that finds no plan process free before its budget
is gone is not started at all (503, :mod:`app.compute`). The answer says how long the request waited
and ran (``diagnostics.request``).

Refusals raise :class:`app.errors.RequestError` (422) or :class:`planner.errors.PlannerError`; the
worker's handlers answer them.
"""

from __future__ import annotations

import dataclasses
import gc
import time
from collections.abc import Callable
from typing import Literal

import numpy as np
import pydantic_core

from app.conversions import (
    candidates_data,
    cartesian_data,
    demo_goal,
    demo_request,
    demo_with_follower,
    frenet_data,
    plan_data,
    to_problem,
)
from app.intake import Structure, parse
from app.limits import (
    MAX_ID_LENGTH,
    MAX_OBSTACLE_POINTS,
    MAX_OBSTACLES,
    MAX_POLYGON_POINTS,
    MAX_QUERY_POINTS,
    MAX_REFERENCE_POINTS,
    MIN_TIME_BUDGET_MS,
)
from app.models.coordinates import CartesianRequest, FrenetRequest
from app.models.planning import PlanningRequest
from planner.candidates import generate_candidates
from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.ego import start_state
from planner.frenet import to_cartesian, to_frenet
from planner.pipeline import plan
from planner.reference import build_reference
from planner.speed import reach_speed
from planner.thread_solvers import thread_solvers

#: the planner's configuration without its spare thread (``KAPPA_SPECULATE=false``)
SERIAL_CONFIG = dataclasses.replace(DEFAULT_CONFIG, speculate=False)


def planner_config(speculate: bool) -> PlannerConfig:
    """The planner's configuration of a job: with its spare thread or without (``KAPPA_SPECULATE``)."""
    return DEFAULT_CONFIG if speculate else SERIAL_CONFIG

#: the most arrays and objects of a planning request: the reference line and its points, four width
#: lists (lane and road), the obstacles and each one's polygon, centre or prediction, every vertex,
#: the goal's polygon and its vertices (or its centre), time and speed; the root, lane, road, ego,
#: vehicle, options, goal and its position and circle, each obstacle and its circle, every predicted
#: state; ids may hold either
PLANNING_STRUCTURE = Structure(
    arrays=6 + MAX_REFERENCE_POINTS + MAX_OBSTACLES + MAX_OBSTACLE_POINTS + 3 + MAX_POLYGON_POINTS,
    objects=9 + 2 * MAX_OBSTACLES + MAX_OBSTACLE_POINTS,
    in_strings=MAX_OBSTACLES * MAX_ID_LENGTH,
)
#: the most arrays and objects of a /v1/frenet or /v1/cartesian request
COORDINATES_STRUCTURE = Structure(arrays=2 + MAX_REFERENCE_POINTS + MAX_QUERY_POINTS, objects=1, in_strings=0)

Kind = Literal["plan", "candidates", "frenet", "cartesian"]


@dataclasses.dataclass(frozen=True)
class Job:
    """What a plan process gets: the endpoint, the raw body, when the request arrived
    (``time.monotonic()`` [s]), the server's default budget [ms] and whether a plan runs the solves it
    will likely need next on a second thread (``PlannerConfig.speculate``)."""

    kind: Kind
    body: bytes
    arrived: float
    default_budget_ms: float
    speculate: bool = True


@dataclasses.dataclass(frozen=True)
class Outcome:
    """What a plan process sends back: the answer's JSON, when the process took the job up
    (``time.monotonic()`` [s]) and, for a plan, its status and the planner's stage times [ms]."""

    body: bytes
    started: float = 0.0
    plan_status: str | None = None
    timing_ms: dict[str, float] | None = None


def _elapsed_ms(since: float) -> float:
    return 1e3 * (time.monotonic() - since)


def _remaining_budget(job: Job, budget_ms: float) -> float:
    """What remains of ``budget_ms`` since the request arrived [ms], at least the smallest budget."""
    return max(MIN_TIME_BUDGET_MS, budget_ms - _elapsed_ms(job.arrived))


def plan_job(job: Job) -> Outcome:
    """``/v1/plan``: the planned trajectory, the planner given what remains of the budget."""
    request = parse(job.body, PlanningRequest, PLANNING_STRUCTURE)
    budget = request.options.time_budget_ms or job.default_budget_ms
    remaining = _remaining_budget(job, budget)
    started = time.monotonic()
    waited = 1e3 * (started - job.arrived)
    result = plan(to_problem(request, time_budget_ms=remaining), planner_config(job.speculate))
    spent = {"budget_ms": budget, "waited_ms": round(waited, 3), "ran_ms": round(_elapsed_ms(started), 3)}
    data = plan_data(result, spent)
    timing = {stage: round(float(ms), 3) for stage, ms in result.diagnostics.timing_ms.items()}
    return Outcome(pydantic_core.to_json(data), plan_status=result.status, timing_ms=timing)


def candidates_job(job: Job) -> Outcome:
    """``/v1/candidates``: the candidate paths of a planning request (no plan: its budget bounds only
    the wait for a plan process)."""
    request = parse(job.body, PlanningRequest, PLANNING_STRUCTURE)
    problem = to_problem(request)
    ref = build_reference(problem.reference_line)
    start = start_state(ref, problem)  # the start /v1/plan uses, so the candidates are the plan's
    fastest = reach_speed(ref, problem, start.s)  # as long as the plan's
    cs = generate_candidates(
        ref, problem.lane, problem.ego, problem.vehicle, problem.options, start=start, reach_speed=fastest
    )
    return Outcome(pydantic_core.to_json(candidates_data(cs, ref, start)))


def frenet_job(job: Job) -> Outcome:
    """``/v1/frenet``: TransF-κ of each point."""
    request = parse(job.body, FrenetRequest, COORDINATES_STRUCTURE)
    ref = build_reference(request.reference_line)
    fr = to_frenet(ref, np.asarray(request.points, dtype=float))
    return Outcome(pydantic_core.to_json(frenet_data(fr)))


def cartesian_job(job: Job) -> Outcome:
    """``/v1/cartesian``: the Cartesian point of each (s, d)."""
    request = parse(job.body, CartesianRequest, COORDINATES_STRUCTURE)
    ref = build_reference(request.reference_line)
    frenet = np.asarray(request.frenet, dtype=float)
    xy = to_cartesian(ref, frenet[:, 0], frenet[:, 1])
    return Outcome(pydantic_core.to_json(cartesian_data(xy)))


JOBS: dict[Kind, Callable[[Job], Outcome]] = {
    "plan": plan_job,
    "candidates": candidates_job,
    "frenet": frenet_job,
    "cartesian": cartesian_job,
}


def run_job(job: Job) -> Outcome:
    """The job's endpoint's work (the function a plan process runs), noting when it began."""
    started = time.monotonic()
    return dataclasses.replace(JOBS[job.kind](job), started=started)


def warm_up(speculate: bool = True) -> None:
    """Build what the first plans would (:func:`plan_demos`, with or without the spare thread as the
    server's jobs ask: ``speculate``); then everything alive (modules, the built QPs) leaves the cyclic
    garbage collector's care: a full collection, which otherwise walks all of it (tens of ms, inside
    whichever plan triggers it), then walks only what the plans leave behind."""
    plan_demos(speculate)
    gc.collect()
    gc.freeze()


def plan_demos(speculate: bool = True) -> None:
    """Plan the demo, with and without a goal, with and without a car from behind, so that this thread's
    first plans do not build the speed problem (a goal's and a follower's bounds each have a QP of their
    own: 25–50 ms to build, inside the first request that needs it), nor the spare thread's solver its
    follower's ones (:mod:`planner.thread_solvers`); returns once the spare thread is idle."""
    demo = demo_request()
    with_goal = demo.model_copy(update={"goal": demo_goal()})
    # the last two with a car from behind closing fast: the spare thread solves their second profile
    requests = (demo, with_goal, demo_with_follower(demo), demo_with_follower(with_goal))
    closing = (demo_with_follower(demo, faster=8.0), demo_with_follower(with_goal, faster=8.0))
    for request in (*requests, *closing):
        plan_job(Job("plan", request.model_dump_json().encode(), time.monotonic(), 60_000.0, speculate))
    spare = thread_solvers(planner_config(speculate)).spare
    if spare is not None:
        spare.wait()
