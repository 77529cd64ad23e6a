"""The planner's configuration: frozen, honoured by the plan, and the solvers kept per thread and setting."""

from __future__ import annotations

import multiprocessing
import os
import threading
from dataclasses import FrozenInstanceError, replace

import numpy as np
import pytest

from planner.config import DEFAULT_CONFIG, LateralConfig, PlannerConfig, SpeedConfig
from planner.pipeline import plan
from planner.roads import demo_problem
from planner.thread_solvers import thread_solvers


def test_the_config_is_frozen_and_the_default_is_the_plans() -> None:
    with pytest.raises(FrozenInstanceError):
        DEFAULT_CONFIG.stop_gap = 2.0  # type: ignore[misc]
    with pytest.raises(FrozenInstanceError):
        DEFAULT_CONFIG.lateral.knot_spacing = 1.0  # type: ignore[misc]
    assert PlannerConfig() == DEFAULT_CONFIG
    default, explicit = plan(demo_problem()), plan(demo_problem(), DEFAULT_CONFIG)
    # (up to the warm start from the plan before, as twice the same request)
    np.testing.assert_allclose(default.trajectory.x, explicit.trajectory.x, atol=1e-6)
    np.testing.assert_allclose(default.trajectory.v, explicit.trajectory.v, atol=1e-6)


def test_the_plan_follows_its_config() -> None:
    default = plan(demo_problem())
    assert default.diagnostics.knots > 60
    few = replace(DEFAULT_CONFIG, lateral=replace(DEFAULT_CONFIG.lateral, max_knots=60))
    assert plan(demo_problem(), few).diagnostics.knots == 60
    slow = replace(DEFAULT_CONFIG, limit_margin=0.3)  # a third of the lateral acceleration
    curve = plan(demo_problem(), slow)
    assert curve.status == default.status == "ok"
    lateral = curve.trajectory.v**2 * np.abs(curve.trajectory.curvature)
    assert lateral.max() <= 0.3 * demo_problem().vehicle.max_lateral_acceleration + 0.05
    assert (default.trajectory.v**2 * np.abs(default.trajectory.curvature)).max() > lateral.max() + 0.5


def test_solvers_are_kept_per_thread_and_per_solver_setting() -> None:
    first = thread_solvers(DEFAULT_CONFIG)
    assert thread_solvers(DEFAULT_CONFIG) is first  # reused: warm starts between plans
    assert thread_solvers(replace(DEFAULT_CONFIG, stop_gap=2.0)) is first  # not a solver setting
    other = thread_solvers(replace(DEFAULT_CONFIG, speed=SpeedConfig(sqp_iterations=3)))
    assert other is not first and other.speed is not first.speed
    assert thread_solvers(DEFAULT_CONFIG) is first
    elsewhere: list[object] = []
    thread = threading.Thread(target=lambda: elsewhere.append(thread_solvers(DEFAULT_CONFIG)))
    thread.start()
    thread.join()
    assert elsewhere[0] is not first


def test_a_spare_thread_per_solver_set_where_the_config_speculates_and_in_a_forked_process_too() -> None:
    """``speculate`` gives each solver set a spare thread (and none without); it runs what it is given,
    in order, also in a process forked from one whose spare thread had started (a fork copies the
    thread's objects, not the thread: the work would wait for ever on a worker that is not there)."""
    assert thread_solvers(replace(DEFAULT_CONFIG, speculate=False)).spare is None
    spare = thread_solvers(DEFAULT_CONFIG).spare
    assert spare is not None
    assert spare.submit(lambda: threading.current_thread().name).result().startswith("kappa-spare")
    order: list[int] = []
    for k in range(3):
        spare.submit(order.append, k)
    spare.wait()
    assert order == [0, 1, 2]
    fork = multiprocessing.get_context("fork")
    answers = fork.Queue()
    child = fork.Process(target=lambda: answers.put(spare.submit(lambda: os.getpid()).result()))
    child.start()
    child.join(timeout=60)
    assert child.exitcode == 0
    assert answers.get(timeout=1) == child.pid


def test_lateral_config_defaults_are_the_documented_ones() -> None:
    lateral = LateralConfig()
    assert (lateral.knot_spacing, lateral.max_knots, lateral.max_iter) == (0.5, 240, 200)
    assert (lateral.curvature_share, lateral.retry_curvature_share, lateral.min_stretch) == (0.9, 0.99, 0.05)
