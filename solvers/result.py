"""The result type shared by every solver in `solvers`: a status and how the solve went.

A solver that does not converge returns a status here; it never raises for that. Misuse (wrong
shapes, non-finite input, contradictory bounds) is a ``ValueError`` raised before solving.

Two sets of statuses matter to callers, the same for every solver:

* :data:`USABLE` — the solver returned an iterate the caller may use after its own checks (a converged
  solution, the best iterate when the iteration or time budget ran out, or — ``relaxed`` — the solution
  with some bounds relaxed as little as possible where the problem has none);
* :data:`CONVERGED` — the solver converged, to the requested accuracy (``solved``) or to a looser one or
  with a violation left (``solved_inaccurate``).

Anything else (``infeasible``, ``failed``) comes with a fallback the solver's result describes (not a
solution).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from types import MappingProxyType

#: a value of :attr:`SolveInfo.extras`
Extra = float | int | bool | str


class SolverStatus(StrEnum):
    """How a solve ended, independent of the backend that ran it."""

    #: converged to the requested accuracy
    SOLVED = "solved"
    #: converged to a looser accuracy than requested, or with a constraint violation left
    SOLVED_INACCURATE = "solved_inaccurate"
    #: the constraints admit no solution (primal infeasibility certificate)
    INFEASIBLE = "infeasible"
    #: the constraints admit no solution; the returned values solve the problem with its soft-able bounds
    #: relaxed as little as possible (an elastic formulation: usable after the caller's own checks)
    RELAXED = "relaxed"
    #: the iteration limit ran out before convergence (the best iterate is returned)
    MAX_ITERATIONS = "max_iterations"
    #: the time limit ran out before convergence (the best iterate is returned)
    TIME_LIMIT = "time_limit"
    #: anything else: numerical trouble, non-convexity detected, interrupted, unbounded, …
    FAILED = "failed"

    @property
    def usable(self) -> bool:
        """True when the solver returned an iterate the caller may use (status in :data:`USABLE`)."""
        return self in USABLE

    @property
    def converged(self) -> bool:
        """True when the solver converged (status in :data:`CONVERGED`)."""
        return self in CONVERGED


#: statuses whose returned iterate the caller may use after its own checks
USABLE: frozenset[SolverStatus] = frozenset(
    {
        SolverStatus.SOLVED,
        SolverStatus.SOLVED_INACCURATE,
        SolverStatus.MAX_ITERATIONS,
        SolverStatus.TIME_LIMIT,
        SolverStatus.RELAXED,
    }
)
#: statuses of a converged solve (a subset of :data:`USABLE`)
CONVERGED: frozenset[SolverStatus] = frozenset({SolverStatus.SOLVED, SolverStatus.SOLVED_INACCURATE})


def _no_extras() -> Mapping[str, Extra]:
    return MappingProxyType({})


@dataclass(frozen=True)
class SolveInfo:
    """How one solve went.

    Attributes:
        status: how the solve ended.
        iterations: iterations the backend ran (ADMM iterations for OSQP, interior-point iterations
            summed over the QPs for the speed SQP).
        solve_time_ms: wall-clock time of the solve call [ms] apart from ``setup_time_ms``: input checks,
            vector updates, the backend's solve and the checks of its answer.
        objective: the cost of the returned solution as the solver's docstring defines it, or ``None``
            when the returned values are not a usable solution.
        message: a short human-readable account (backend status, fallbacks taken); for people, not for
            deciding anything — decide on the other fields.
        max_violation: the largest constraint violation of the returned values, in the solver's units
            (each constraint in its own; the solver's result says which constraints); 0 for an info made
            without a solve.
        setup_time_ms: wall-clock time of building and setting up the backend's problem [ms] (matrices,
            factorisation, code generation); 0 when a set-up built before was reused.
        extras: solver-specific facts, each solver's result docstring lists its keys (e.g. ``polished``,
            ``restarted``, ``qp_solves``); read-only.
    """

    status: SolverStatus
    iterations: int
    solve_time_ms: float
    objective: float | None
    message: str
    max_violation: float = 0.0
    setup_time_ms: float = 0.0
    extras: Mapping[str, Extra] = field(default_factory=_no_extras)

    def __post_init__(self) -> None:
        object.__setattr__(self, "extras", MappingProxyType(dict(self.extras)))

    @property
    def usable(self) -> bool:
        """True when the returned iterate may be used (status in :data:`USABLE`)."""
        return self.status.usable

    @property
    def converged(self) -> bool:
        """True when the solver converged (status in :data:`CONVERGED`)."""
        return self.status.converged
