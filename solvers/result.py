"""The result type shared by every solver in `solvers`: a status and how the solve went.

A solver that does not converge returns a status here; it never raises for that. Misuse (wrong
shapes, non-finite input, contradictory bounds) is a ``ValueError`` raised before solving.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class SolverStatus(StrEnum):
    """How a solve ended, independent of the backend that ran it."""

    #: converged to the requested accuracy
    SOLVED = "solved"
    #: stopped with a usable but less accurate solution (e.g. OSQP's ``solved inaccurate``)
    SOLVED_INACCURATE = "solved_inaccurate"
    #: the constraints admit no solution (primal infeasibility certificate)
    INFEASIBLE = "infeasible"
    #: the iteration limit ran out before convergence
    MAX_ITERATIONS = "max_iterations"
    #: the time limit ran out before convergence
    TIME_LIMIT = "time_limit"
    #: anything else: numerical trouble, non-convexity detected, interrupted, unbounded, …
    FAILED = "failed"

    @property
    def ok(self) -> bool:
        """True when the solution can be used (``solved`` or ``solved_inaccurate``)."""
        return self in (SolverStatus.SOLVED, SolverStatus.SOLVED_INACCURATE)


@dataclass(frozen=True)
class SolveInfo:
    """How one solve went.

    Attributes:
        status: how the solve ended.
        iterations: iterations the backend ran (ADMM iterations for OSQP).
        solve_time_ms: wall-clock time of the whole solve call [ms], including any matrix set-up and
            vector updates it had to do.
        objective: the cost of the returned solution as the solver's docstring defines it, or ``None``
            when there is no usable solution (``ok`` is false).
        message: a short human-readable account (backend status, polishing, fallbacks taken).
    """

    status: SolverStatus
    iterations: int
    solve_time_ms: float
    objective: float | None
    message: str

    @property
    def ok(self) -> bool:
        """True when the solution can be used (status ``solved`` or ``solved_inaccurate``)."""
        return self.status.ok
