"""The solvers a plan runs, one set per thread and per solver configuration, reused between plans.

Reuse matters beyond speed: the solvers keep their built problems and warm-start from the plan before,
so the same sequence of requests gets bit-identical answers. The solvers are not thread-safe, hence one
set per thread.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

from planner.config import DEFAULT_CONFIG, PlannerConfig
from solvers.lateral_qp import LateralQPSolver
from solvers.speed_sqp import SpeedSolver

#: solver sets kept per thread (one per solver configuration), the least recently used dropped first
MAX_SETS = 4


@dataclass(frozen=True)
class Solvers:
    """The lateral QP and speed SQP solvers of one thread."""

    lateral: LateralQPSolver
    speed: SpeedSolver


def new_solvers(config: PlannerConfig = DEFAULT_CONFIG) -> Solvers:
    """Solvers configured as :func:`planner.pipeline.plan` uses them under ``config``."""
    speed = config.speed
    return Solvers(
        lateral=LateralQPSolver(),
        speed=SpeedSolver(
            max_iterations=speed.sqp_iterations,
            tolerance=speed.sqp_tolerance,
            restore_violation=speed.slack,
            qp_residual=speed.qp_residual,
        ),
    )


_THREAD = threading.local()


def thread_solvers(config: PlannerConfig = DEFAULT_CONFIG) -> Solvers:
    """This thread's solvers for ``config`` (made on first use, then reused)."""
    speed = config.speed
    key = (speed.sqp_iterations, speed.sqp_tolerance, speed.slack, speed.qp_residual)
    sets: dict[tuple[int, float, float, float], Solvers] = _THREAD.__dict__.setdefault("sets", {})
    solvers = sets.pop(key, None) or new_solvers(config)
    sets[key] = solvers  # the most recently used last
    while len(sets) > MAX_SETS:
        del sets[next(iter(sets))]
    return solvers
