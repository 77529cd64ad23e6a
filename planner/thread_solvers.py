"""The solvers a plan runs, one set per thread and per solver configuration, reused between plans.

Reuse matters beyond speed: the solvers keep their built problems and warm-start from the plan before,
so the same sequence of requests gets bit-identical answers. The solvers are not thread-safe, hence one
set per thread.

With ``PlannerConfig.speculate`` a set has a spare thread (:class:`Spare`): a stage starts there a solve
it may need next while it finds out whether it does (the lateral QP's elastic problem beside the proof
that the QP is infeasible, :class:`~solvers.lateral_qp.LateralQPSolver`; the speed profile with the
emergency jerk beside the first, :func:`planner.speed.speed_stage`). Those solves depend on their
problem only, so the answers are those of the plan's thread alone; on a second free core they come at
the cost of the longer solve instead of the sum, and a solve not needed is work spent for nothing.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import ParamSpec, TypeVar

from planner.config import DEFAULT_CONFIG, PlannerConfig
from solvers.lateral_qp import LateralQPSolver
from solvers.speed_sqp import SpeedSolver

#: solver sets kept per thread (one per solver configuration), the least recently used dropped first
MAX_SETS = 4

_P = ParamSpec("_P")
_T = TypeVar("_T")


class Spare(Executor):
    """One worker thread beside a plan's thread, and the speed solver only that worker uses. Work runs
    in the order it was submitted; a solve not needed keeps the worker busy until it ends. The worker
    starts with the first work, and again in a process forked from one that had it (a fork copies the
    thread's objects, not the thread)."""

    def __init__(self, config: PlannerConfig = DEFAULT_CONFIG) -> None:
        self.speed = _speed_solver(config)
        self._pool: ThreadPoolExecutor | None = None
        self._pid = 0

    def submit(self, fn: Callable[_P, _T], /, *args: _P.args, **kwargs: _P.kwargs) -> Future[_T]:
        """Run ``fn(*args, **kwargs)`` on the spare thread."""
        if self._pool is None or self._pid != os.getpid():
            self._pool, self._pid = ThreadPoolExecutor(1, thread_name_prefix="kappa-spare"), os.getpid()
        return self._pool.submit(fn, *args, **kwargs)

    def wait(self) -> None:
        """Return once the work submitted so far has run."""
        if self._pool is not None and self._pid == os.getpid():
            self._pool.submit(lambda: None).result()

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        """Stop the worker (after its work, unless cancelled); it starts again with new work."""
        if self._pool is not None and self._pid == os.getpid():
            self._pool.shutdown(wait=wait, cancel_futures=cancel_futures)
        self._pool = None


@dataclass(frozen=True)
class Solvers:
    """The lateral QP and speed SQP solvers of one thread, and its spare thread (None: none)."""

    lateral: LateralQPSolver
    speed: SpeedSolver
    spare: Spare | None = None


def _speed_solver(config: PlannerConfig) -> SpeedSolver:
    speed = config.speed
    return SpeedSolver(
        max_iterations=speed.sqp_iterations,
        tolerance=speed.sqp_tolerance,
        restore_violation=speed.slack,
        qp_residual=speed.qp_residual,
    )


def new_solvers(config: PlannerConfig = DEFAULT_CONFIG) -> Solvers:
    """Solvers configured as :func:`planner.pipeline.plan` uses them under ``config`` (with a spare
    thread where ``config.speculate``)."""
    spare = Spare(config) if config.speculate else None
    lateral = LateralQPSolver(spare=spare)
    return Solvers(lateral=lateral, speed=_speed_solver(config), spare=spare)


_THREAD = threading.local()


def thread_solvers(config: PlannerConfig = DEFAULT_CONFIG) -> Solvers:
    """This thread's solvers for ``config`` (made on first use, then reused)."""
    speed = config.speed
    key = (speed.sqp_iterations, speed.sqp_tolerance, speed.slack, speed.qp_residual, config.speculate)
    sets: dict[tuple[int, float, float, float, bool], Solvers] = _THREAD.__dict__.setdefault("sets", {})
    solvers = sets.pop(key, None) or new_solvers(config)
    sets[key] = solvers  # the most recently used last
    while len(sets) > MAX_SETS:
        dropped = sets.pop(next(iter(sets)))
        if dropped.spare is not None:
            dropped.spare.shutdown(wait=False, cancel_futures=True)
    return solvers
