"""What a plan process does before its first request: the warm-up builds the speed problems a plan with
and without a goal, and with and without a car from behind, needs."""

from __future__ import annotations

import gc
import json
import threading
import time

import pytest

from app.conversions import demo_goal, demo_request, demo_with_follower
from app.jobs import Job, plan_job, warm_up
from planner.thread_solvers import thread_solvers
from tests.planner.spies import started_work


def test_the_warm_up_builds_the_speed_problems_with_and_without_a_goal_and_a_follower(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    built: list[tuple[int, int]] = []
    frozen: list[tuple[int, int]] = []  # the heap is frozen out of the cyclic GC once the warm-up has planned

    def counts() -> tuple[int, int]:
        """QPs built by the plan thread's speed solver and by its spare thread's (idle first)."""
        solvers = thread_solvers()
        assert solvers.spare is not None  # the default configuration speculates
        solvers.spare.wait()
        return solvers.speed.build_count, solvers.spare.speed.build_count

    monkeypatch.setattr(gc, "freeze", lambda: frozen.append(counts()))

    def process() -> None:  # the solvers are kept per thread: a thread of its own is a fresh process here
        warm_up()
        built.append(counts())
        goal = demo_request().model_copy(update={"goal": demo_goal()})
        for request in (goal, demo_with_follower(goal), demo_with_follower(demo_request())):
            plan_job(Job("plan", request.model_dump_json().encode(), time.monotonic(), 60_000.0))
            built.append(counts())

    thread = threading.Thread(target=process)
    thread.start()
    thread.join()
    # the goal's and the follower's QPs built by the warm-up, not by the first requests that need them;
    # the spare thread's solver solves with a follower only (with and without a goal)
    assert built == [(4, 2), (4, 2), (4, 2), (4, 2)]
    assert frozen == [(4, 2)]  # frozen after the warm-up built them all


def test_a_job_without_speculation_plans_on_one_thread_and_answers_the_same(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``KAPPA_SPECULATE=false`` reaches the plan as the job's ``speculate``: nothing starts on a spare
    thread, and the trajectory, status and message are those of a plan that speculates (a car closing
    from behind: the emergency profile is solved after the first, or beside it)."""
    started = started_work(monkeypatch)
    body = demo_with_follower(demo_request(), faster=8.0).model_dump_json().encode()
    serial = json.loads(plan_job(Job("plan", body, time.monotonic(), 60_000.0, speculate=False)).body)
    assert started == []
    spared = json.loads(plan_job(Job("plan", body, time.monotonic(), 60_000.0)).body)
    assert "emergency" in started
    assert (serial["status"], serial["message"]) == (spared["status"], spared["message"])
    assert serial["trajectory"] == spared["trajectory"]
