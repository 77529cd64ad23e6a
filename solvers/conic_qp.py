r"""A convex QP in OSQP's form solved by an interior-point method, Clarabel, through qpsolvers::

    min ½ xᵀPx + qᵀx   s.t.   l ≤ Ax ≤ u

with ``P`` symmetric positive semidefinite (its upper triangle, as OSQP takes it) and ``l``, ``u`` possibly
±∞. In qpsolvers' form ``min ½ xᵀPx + qᵀx  s.t.  Gx ≤ h, A_eq x = b``: a row with ``l_i = u_i`` is an
equality; every other row gives ``A_i x ≤ u_i`` and ``−A_i x ≤ −l_i`` for each finite side (a row free on
both sides is dropped).

Why a second backend. ADMM (OSQP) needs many iterations where the problem is badly conditioned or
infeasible (it proves infeasibility only once its iterates have diverged far enough); an interior-point
method solves the same QP to high accuracy, or proves it infeasible, in tens of iterations whatever its
conditioning, each a sparse factorisation. Clarabel (Rust, one thread, a direct LDLᵀ solver) stops on an
iteration count, so the same problem gets the same answer; ``time_limit_s`` is only a safety net for the
caller's time budget. ProxQP, the other sparse backend qpsolvers offers, was measured slower and less
accurate on the lateral QP (``bench/lateral_backends.py``).

Statuses (:class:`~solvers.result.SolverStatus`): ``solved`` (Clarabel's *Solved* and every constraint
held to ``feasibility_tol``), ``solved_inaccurate`` (*AlmostSolved*, or a violation above
``feasibility_tol`` left), ``infeasible`` (a primal infeasibility certificate, *AlmostPrimalInfeasible*
included), ``max_iterations``, ``time_limit``, ``failed`` (anything else). ``x`` is a solution only when
the status is converged; otherwise it is the backend's last iterate, which need not meet the constraints
(``info.max_violation`` says by how much), or zeros when there is none.
"""

from __future__ import annotations

import math
import threading
import time
import warnings
from dataclasses import dataclass
from typing import Any

import clarabel
import numpy as np
import qpsolvers
import scipy.sparse as sp
from numpy.typing import NDArray

from solvers.result import SolveInfo, SolverStatus
from solvers.validation import integer

FloatArray = NDArray[np.float64]

__all__ = ["BACKEND", "SETTINGS", "ConicQPResult", "qpsolvers_problem", "solve_conic_qp"]

#: the qpsolvers backend
BACKEND = "clarabel"

#: Clarabel's settings beside the limits: no iterative refinement of its KKT solves. On the lateral QPs
#: (hundreds to a thousand variables, banded) refinement took half of each solve (the elastic QP of
#: DEU_Flensburg-58's slowest cycle: 11 ms CPU with it, 5 ms without, 18 iterations either way); without
#: it the answers move by about 1e-6 m and meet the constraints to about 1e-10, and every answer is
#: still checked against ``feasibility_tol`` (``solved_inaccurate`` beyond it).
SETTINGS: dict[str, Any] = {"iterative_refinement_enable": False}

#: Clarabel's statuses (qpsolvers hands Clarabel's own status over) as ours; the others are ``failed``
_STATUS_MAP: dict[Any, SolverStatus] = {
    clarabel.SolverStatus.Solved: SolverStatus.SOLVED,
    clarabel.SolverStatus.AlmostSolved: SolverStatus.SOLVED_INACCURATE,
    clarabel.SolverStatus.PrimalInfeasible: SolverStatus.INFEASIBLE,
    clarabel.SolverStatus.AlmostPrimalInfeasible: SolverStatus.INFEASIBLE,
    clarabel.SolverStatus.MaxIterations: SolverStatus.MAX_ITERATIONS,
    clarabel.SolverStatus.MaxTime: SolverStatus.TIME_LIMIT,
}


@dataclass(frozen=True, eq=False)
class ConicQPResult:
    """The solve's info and ``x`` (see the module docstring for what ``x`` is when not converged).

    ``info.extras``: ``backend`` (``"clarabel"``) and ``backend_status`` (Clarabel's status). The
    backend's iteration count is not reported through qpsolvers: ``info.iterations`` is 0.
    """

    info: SolveInfo
    x: FloatArray


#: per thread, the matrices :func:`qpsolvers_problem` built, by what they were built from:
#: ``("P", id(P))`` → ``(P, full)`` and ``("A", id(A), masks)`` → ``(A, G, A_eq)``, the source kept beside
#: them (an identity is only reused once its object is gone). The lateral QP's and the elastic QP's
#: matrices are shared per knot grid (``functools.lru_cache``), and a plan hands the same grid over several
#: times; building them again was a third of the conversion's cost. Never written to; the oldest dropped
#: first. One cache per thread: a plan's spare thread (:mod:`planner.thread_solvers`) solves beside it.
_BUILT = threading.local()
#: entries of each thread's cache kept
_BUILT_SIZE = 16


def _built(key: tuple[Any, ...], source: sp.csc_matrix, build: Any) -> tuple[Any, ...]:
    """``build()``'s matrices for ``key``, built once per thread while ``source`` is alive."""
    built: dict[tuple[Any, ...], tuple[Any, ...]] = _BUILT.__dict__.setdefault("entries", {})
    found = built.get(key)
    if found is not None and found[0] is source:
        return found[1:]
    made = build()
    while len(built) >= _BUILT_SIZE:
        built.pop(next(iter(built)), None)
    built[key] = (source, *made)
    return tuple(made)


def qpsolvers_problem(
    P: sp.csc_matrix, q: FloatArray, A: sp.csc_matrix, lower: FloatArray, upper: FloatArray
) -> qpsolvers.Problem:
    """``l ≤ Ax ≤ u`` as equalities and one-sided inequalities (see the module docstring); the matrices
    of a ``P`` and of an ``A`` with the same equal and finite rows as before are those built then."""
    (full,) = _built(("P", id(P)), P, lambda: ((P + sp.triu(P, 1).T).tocsc(),))
    equal = lower == upper
    ranged = ~equal
    has_upper, has_lower = np.isfinite(upper[ranged]), np.isfinite(lower[ranged])

    def build() -> tuple[sp.csc_matrix, sp.csc_matrix]:
        rows = A[ranged]
        return sp.vstack([rows[has_upper], -rows[has_lower]]).tocsc(), A[equal].tocsc()

    masks = np.packbits(np.concatenate([equal, has_upper, has_lower])).tobytes()
    G, A_eq = _built(("A", id(A), A.shape, masks), A, build)
    h = np.concatenate([upper[ranged][has_upper], -lower[ranged][has_lower]])
    return qpsolvers.Problem(full, q, G, h, A_eq, lower[equal])


def solve_conic_qp(
    P: sp.csc_matrix,
    q: FloatArray,
    A: sp.csc_matrix,
    lower: FloatArray,
    upper: FloatArray,
    *,
    max_iter: int = 50,
    time_limit_s: float | None = None,
    feasibility_tol: float = 1e-6,
) -> ConicQPResult:
    """Solve ``min ½ xᵀPx + qᵀx  s.t.  l ≤ Ax ≤ u`` (``P`` its upper triangle, CSC); a status, never an
    exception, for a problem it cannot solve.

    Args:
        max_iter: Clarabel's iteration limit (≥ 1).
        time_limit_s: Clarabel's time limit [s]; None: none.
        feasibility_tol: largest constraint violation of a ``solved`` answer (in each row's unit).

    Raises:
        ValueError: shapes that do not agree, or a limit that is not positive.
    """
    start = time.perf_counter()
    n = P.shape[0]
    if P.shape != (n, n) or q.shape != (n,) or A.shape[1] != n or lower.shape != upper.shape != (A.shape[0],):
        raise ValueError("P, q, A, lower and upper do not agree in shape")
    max_iter = integer("max_iter", max_iter, low=1)
    settings: dict[str, Any] = {**SETTINGS, "max_iter": max_iter}
    if time_limit_s is not None:
        if not time_limit_s > 0 or math.isnan(time_limit_s):
            raise ValueError(f"time_limit_s: must be > 0, got {time_limit_s!r}")
        settings["time_limit"] = float(time_limit_s)
    with warnings.catch_warnings():  # qpsolvers warns of every unsolved problem: the status says it
        warnings.simplefilter("ignore")
        try:
            solution = qpsolvers.solve_problem(
                qpsolvers_problem(P, q, A, lower, upper), solver=BACKEND, **settings
            )
        except (qpsolvers.QPError, ValueError, ArithmeticError) as exc:
            return _failed(n, start, f"{BACKEND} raised {type(exc).__name__}: {exc}")
    raw = solution.extras.get("status")
    backend_status = str(raw) if raw is not None else ""
    status = _STATUS_MAP.get(raw, SolverStatus.FAILED)
    x = np.asarray(solution.x, dtype=np.float64) if solution.x is not None else np.zeros(n)
    if x.shape != (n,) or not np.all(np.isfinite(x)):
        x, status = np.zeros(n), SolverStatus.FAILED if status.converged else status
    Ax = A @ x
    violation = float(max(np.max(lower - Ax, initial=0.0), np.max(Ax - upper, initial=0.0)))
    if status is SolverStatus.SOLVED and violation > feasibility_tol:
        status = SolverStatus.SOLVED_INACCURATE
    objective = float(0.5 * x @ (P @ x + sp.triu(P, 1).T @ x) + q @ x) if status.converged else None
    info = SolveInfo(
        status=status,
        iterations=0,
        solve_time_ms=(time.perf_counter() - start) * 1e3,
        objective=objective,
        message=f"{BACKEND}: {backend_status or 'no status'}",
        max_violation=violation,
        extras={"backend": BACKEND, "backend_status": backend_status},
    )
    return ConicQPResult(info=info, x=x)


def _failed(n: int, start: float, message: str) -> ConicQPResult:
    info = SolveInfo(
        status=SolverStatus.FAILED,
        iterations=0,
        solve_time_ms=(time.perf_counter() - start) * 1e3,
        objective=None,
        message=message,
        extras={"backend": BACKEND, "backend_status": ""},
    )
    return ConicQPResult(info=info, x=np.zeros(n))
