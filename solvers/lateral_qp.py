r"""The lateral QP (:mod:`solvers.lateral_qp_problem`) solved with OSQP, and through a second backend
(:mod:`solvers.conic_qp`, :mod:`solvers.lateral_qp_elastic`) where OSQP does not converge.

Solving: OSQP (ADMM, ``eps = 1e-3``) then its polishing, which solves the equality system of the active
set it guesses from the ADMM iterate: exact when the guess is right, the common case. Where a bound is
pressed over a stretch the optimum touches it at a few knots only and sags by less than the ADMM
tolerance in between; polishing then fails and the ADMM iterate, accurate to about ``eps``, is returned
(``solved_inaccurate`` when it breaks a constraint by more than ``feasibility_tol``; its largest
violation is ``info.max_violation``).
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from concurrent.futures import Executor, Future
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp

from solvers.conic_qp import BACKEND, ConicQPResult, solve_conic_qp
from solvers.lateral_qp_elastic import elastic_qp, split
from solvers.lateral_qp_problem import (
    FloatArray,
    LateralQPProblem,
    LateralQPResult,
    LateralWeights,
    build_qp_matrices,
    clipped_reference,
    integrate_profile,
    max_violation,
    objective,
    qp_matrices,
    qp_vectors,
    reach_gap,
)
from solvers.result import Extra, SolveInfo, SolverStatus
from solvers.validation import integer

__all__ = [
    "LateralQPProblem",
    "LateralQPResult",
    "LateralQPSolver",
    "LateralWeights",
    "build_qp_matrices",
    "integrate_profile",
    "objective",
]

#: OSQP's "no time limit" (its own default) [s]
_NO_TIME_LIMIT_S = 1e10

_MatrixKey = tuple[int, float, LateralWeights, bool]


# --------------------------------------------------------------------------------------------------------
# Solver


_STATUS_MAP: dict[int, SolverStatus] = {
    int(osqp.SolverStatus.OSQP_SOLVED): SolverStatus.SOLVED,
    int(osqp.SolverStatus.OSQP_SOLVED_INACCURATE): SolverStatus.SOLVED_INACCURATE,
    int(osqp.SolverStatus.OSQP_PRIMAL_INFEASIBLE): SolverStatus.INFEASIBLE,
    int(osqp.SolverStatus.OSQP_PRIMAL_INFEASIBLE_INACCURATE): SolverStatus.INFEASIBLE,
    int(osqp.SolverStatus.OSQP_MAX_ITER_REACHED): SolverStatus.MAX_ITERATIONS,
    int(osqp.SolverStatus.OSQP_TIME_LIMIT_REACHED): SolverStatus.TIME_LIMIT,
    # dual infeasible (unbounded: impossible here, P ⪰ 0 and x is bounded through the jerks),
    # non-convex, interrupted, unsolved: all "failed"
}

#: an iterate this far beyond the problem's scale is taken as divergence, not as a path
_DIVERGED = 1e6
#: what goes to the second backend: OSQP out of iterations or failed (diverged included), and an
#: inaccurate proof of infeasibility (not out of time: the budget is spent)
_HAND_OVER = frozenset({SolverStatus.MAX_ITERATIONS, SolverStatus.FAILED})
_INACCURATE_INFEASIBLE = int(osqp.SolverStatus.OSQP_PRIMAL_INFEASIBLE_INACCURATE)


@dataclass
class _Workspace:
    """One OSQP set-up (fixed ``P``, ``A``) and the last solution (for the next warm start)."""

    solver: Any
    P: sp.csc_matrix
    A: sp.csc_matrix
    max_iter: int
    time_limit_s: float
    last_x: FloatArray | None = None
    last_y: FloatArray | None = None
    #: OSQP adapted its step ``rho`` in an earlier solve (it keeps the adapted value for the next one)
    rho_adapted: bool = False


def _since(start: float) -> float:
    """Seconds since ``start`` (a ``time.perf_counter()``)."""
    return time.perf_counter() - start


class LateralQPSolver:
    """Solves :class:`LateralQPProblem` s with OSQP, reusing the set-up per ``(n, Δs, weights, end_d given)``.

    The first solve for a key builds ``P`` and ``A`` and sets OSQP up (factorisation included, reported as
    ``info.setup_time_ms``); later solves with the same key only update ``q, l, u`` and warm-start from the
    previous solution (or, after a failure, from the clipped reference with zero duals). Up to
    ``max_cached`` set-ups are kept, least recently used dropped first. Not thread-safe: use one solver per
    thread.

    Accuracy. OSQP's ADMM stops at ``eps_abs``/``eps_rel`` and polishing then solves the equality system
    of the guessed active set: when it succeeds (the common case) the solution is exact to about 1e-9 and
    the status ``solved``. Every returned solution is checked against the constraints: ``solved``
    guarantees that each holds to ``feasibility_tol`` (in the row's own unit); a converged solution that
    breaks one by more (polishing failed, the ADMM iterate is accurate to about ``eps``) is
    ``solved_inaccurate``, its largest violation ``info.max_violation``.

    Second backend. Where OSQP runs out of iterations, fails, returns a solution that breaks a
    constraint by more than ``feasibility_tol`` (``solved_inaccurate``), or finds the problem infeasible
    only inaccurately (not where its time ran out: the budget is spent), the same ``(P, q, A, l, u)``
    goes to Clarabel through qpsolvers (:mod:`solvers.conic_qp`), at most ``second_max_iter``
    interior-point iterations. Its converged answer is returned (``solved`` when every constraint holds
    to ``feasibility_tol``; after OSQP's ``solved_inaccurate`` only if it breaks the constraints less).
    Where it proves the QP infeasible and OSQP had no answer, or OSQP's own certificate proves it (then
    without a second opinion), the elastic problem (:mod:`solvers.lateral_qp_elastic`) gives the path
    breaking the offset and curvature bounds least (``relaxed``: usable, not converged): an infeasible QP
    gets the same path whether or not OSQP found out within its iterations (with ``relax=False`` the
    proof comes back as ``infeasible`` on OSQP's result, and :meth:`relax` solves the elastic problem
    later, for a caller that may not need it). Where the initial state cannot reach the box bounds within
    the jerk limit (:func:`~solvers.lateral_qp_problem.reach_gap`: the usual cause, an ego outside its
    bounds that cannot steer back in time), that is the proof: the elastic problem starts before OSQP's
    solve (on the spare thread, below) and the second backend is not asked (on the closed loops of
    ``bench/cycles.py``, 199 of its 252 proofs of infeasibility; the answers are the same). Otherwise
    OSQP's result is returned, with the second backend's verdict beside it. A result from Clarabel
    carries OSQP's own as ``first`` (its unfinished iterate, for a caller whose checks prefer it). Every
    solve stops on iteration counts: the same problem gets the same answer.

    A result's ``info.extras`` holds ``backend`` (``"osqp"`` or ``"clarabel"``: which one's answer this
    is), ``backend_status`` (that backend's status text), ``osqp_status``, ``second_status`` (the second
    backend's status, ``""`` when it did not run), ``polished`` (whether OSQP's polishing succeeded) and
    ``returned``: ``"solution"``, ``"relaxed"`` (the elastic problem's), ``"integrated_iterate"`` (out of
    iterations or time: OSQP's last iterate's ``d″`` integrated from the initial state, consistent but not
    a solution) or ``"clipped_reference"`` (infeasible or failed: the reference clipped to the bounds).
    ``info.iterations`` counts OSQP's iterations (qpsolvers does not report Clarabel's).

    Spare thread. Given an executor (``spare``: one worker, used by nothing else while a solve waits on
    it), the elastic problem of a QP handed to the second backend starts there beside the second
    backend's own solve (of a QP the start's reach proves infeasible, before OSQP's), where the caller
    relaxes an infeasible QP (``relax``, or ``relax_later`` for a later :meth:`relax`): an infeasible QP
    then costs the longer of the two solves, not their sum. The answers are the same (Clarabel's solves
    depend on their problem only); a feasible QP leaves the elastic solve's work unused on the spare
    thread.

    Args:
        eps_abs, eps_rel: OSQP's absolute and relative tolerances.
        polish: run OSQP's solution polishing.
        feasibility_tol: largest constraint violation accepted as ``solved``.
        max_cached: number of set-ups kept.
        second_backend: hand what OSQP does not converge on to Clarabel.
        second_max_iter: Clarabel's iteration limit.
        spare: an executor of one worker thread for the elastic problem beside the second backend's
            solve (see *Spare thread*); None: every solve in the caller's thread.
        spare_residual: the elastic problem starts on the spare thread only where OSQP's primal residual
            after its iterations is above this (in the rows' units: m, -, 1/m): an infeasible QP's stays
            large. On the closed loops of ``bench/cycles.py``: 223 of the 252 infeasible QPs handed over,
            56 of the 192 feasible ones (whose elastic solve is spent for nothing and slows the caller's
            thread, with which it shares the interpreter); started 279 times, relaxed 192.
    """

    def __init__(
        self,
        *,
        eps_abs: float = 1e-3,
        eps_rel: float = 1e-3,
        polish: bool = True,
        feasibility_tol: float = 1e-6,
        max_cached: int = 4,
        second_backend: bool = True,
        second_max_iter: int = 50,
        spare: Executor | None = None,
        spare_residual: float = 0.05,
    ) -> None:
        if not (eps_abs > 0 and eps_rel >= 0 and feasibility_tol > 0):
            raise ValueError("eps_abs and feasibility_tol must be > 0 and eps_rel ≥ 0")
        self._feasibility_tol = float(feasibility_tol)
        self._settings: dict[str, Any] = {
            "eps_abs": float(eps_abs),
            "eps_rel": float(eps_rel),
            "polishing": bool(polish),
            "verbose": False,
            "warm_starting": True,
        }
        self._max_cached = integer("max_cached", max_cached, low=1)
        self._second_backend = bool(second_backend)
        self._second_max_iter = integer("second_max_iter", second_max_iter, low=1)
        self._workspaces: OrderedDict[_MatrixKey, _Workspace] = OrderedDict()
        self._setup_count = 0
        #: OSQP's initial rho (its default), read from the first set-up
        self._rho = 0.1
        self._spare = spare
        self._spare_residual = float(spare_residual)
        #: elastic problems started on the spare thread for a later :meth:`relax`, by the problem's
        #: identity (the problem kept beside its solve, so that the identity is not reused)
        self._elastic: OrderedDict[int, tuple[LateralQPProblem, Future[ConicQPResult]]] = OrderedDict()

    @property
    def setup_count(self) -> int:
        """How many times OSQP was set up (matrices built and factorised) by this solver."""
        return self._setup_count

    def _workspace(
        self, problem: LateralQPProblem, q: FloatArray, lower: FloatArray, upper: FloatArray, *, fresh: bool
    ) -> tuple[_Workspace, float]:
        """The set-up for ``problem``'s key with ``q, l, u`` in it, and the time a new set-up took [ms].

        With ``fresh``, a set-up whose ``rho`` OSQP adapted in an earlier solve is made anew: OSQP keeps
        the adapted ``rho``, so the next solve would depend on the earlier ones."""
        key: _MatrixKey = (problem.n, problem.ds, problem.weights, problem.end_d is not None)
        workspace = self._workspaces.get(key)
        if workspace is not None:
            self._workspaces.move_to_end(key)
            if fresh and workspace.rho_adapted:
                # back to the set-up's rho (one refactorisation, not a new set-up: the scaling, computed
                # from the fixed P, A and q = 0, is the same)
                workspace.solver.update_settings(rho=self._rho)
                workspace.rho_adapted = False
            workspace.solver.update(q=q, l=lower, u=upper)
            return workspace, 0.0
        start = time.perf_counter()
        P, A = qp_matrices(*key)
        solver = osqp.OSQP()
        # Set up with q = 0, then q: OSQP's cost scaling is computed from the set-up's q, so a set-up made
        # with one problem's q would make every later solve depend on which problem came first.
        solver.setup(
            P, np.zeros_like(q), A, lower, upper, max_iter=4000, time_limit=_NO_TIME_LIMIT_S, **self._settings
        )
        self._rho = float(solver.settings.rho)
        solver.update(q=q)
        self._setup_count += 1
        workspace = _Workspace(solver=solver, P=P, A=A, max_iter=4000, time_limit_s=_NO_TIME_LIMIT_S)
        self._workspaces[key] = workspace
        while len(self._workspaces) > self._max_cached:
            self._workspaces.popitem(last=False)
        return workspace, (time.perf_counter() - start) * 1e3

    def solve(
        self,
        problem: LateralQPProblem,
        *,
        time_limit_s: float | None = None,
        max_iter: int = 4000,
        warm_start: bool = True,
        second_backend: bool = True,
        relax: bool = True,
        relax_later: bool = False,
    ) -> LateralQPResult:
        """Solve ``problem``; non-convergence is reported in ``result.info.status``, never raised.

        Args:
            problem: the QP data (validated on construction).
            time_limit_s: OSQP's run-time limit [s]; ``None``: none.
            max_iter: OSQP's iteration limit (≥ 1).
            warm_start: start from the previous solution of the same set-up. It pays when the knots sit
                at the same ``s`` as last time (a re-solve of a slightly changed problem); when the grid
                has moved by a fraction of a knot, a cold start can be faster. A cold start (False)
                starts from the clipped reference with zero duals and OSQP's initial ``rho`` (a set-up
                whose ``rho`` was adapted is made anew): its result does not depend on what the solver
                solved before.
            second_backend: hand what OSQP does not converge on to the second backend, when the solver
                has one (False: OSQP's answer as it is — for an optional solve not worth the second
                backend's time).
            relax: where the QP is proven infeasible (by OSQP's certificate, or by the second backend
                where OSQP had no answer), solve the elastic problem for the least-violating path
                (``relaxed``). False: return OSQP's result with the proof (its own, or beside it;
                ``infeasible`` set) — for a caller that takes converged answers only, which the elastic
                path never is, or that relaxes it later only where it needs it (:meth:`relax`). For the
                former (``relax_later`` False) a QP the start's reach proves infeasible is not solved at
                all: the reference clipped to the bounds comes back, ``infeasible``, ``osqp_status``
                "not run".
            relax_later: with ``relax=False``, the caller may call :meth:`relax` on the result: with a
                spare thread its elastic problem starts beside the second backend's solve (beside
                OSQP's, where the start's reach proves the QP infeasible).

        Raises:
            ValueError: ``problem`` is not a :class:`LateralQPProblem`, or a limit is not positive.
        """
        start = time.perf_counter()
        if not isinstance(problem, LateralQPProblem):
            raise ValueError(f"problem: expected LateralQPProblem, got {type(problem).__name__}")
        max_iter = integer("max_iter", max_iter, low=1)
        if time_limit_s is None:
            limit = _NO_TIME_LIMIT_S
        else:
            limit = float(time_limit_s)
            if not limit > 0 or math.isnan(limit):
                raise ValueError(f"time_limit_s: must be > 0, got {time_limit_s!r}")

        n = problem.n
        q, l, u = qp_vectors(problem)  # noqa: E741
        handing = self._second_backend and second_backend
        # proven infeasible before any solve (the usual case: an ego that cannot steer back inside its
        # bounds in time): the second backend's proof is not needed, the elastic problem starts at once
        gap = reach_gap(problem) if handing else 0.0
        unreachable = gap > self._feasibility_tol
        if unreachable and not (relax or relax_later):
            return self._unreachable(problem, l, u, gap, start)  # a caller that takes converged answers only
        started = unreachable and self._start_elastic(problem, time_limit_s)  # relaxed now or later
        workspace, setup_ms = self._workspace(problem, q, l, u, fresh=not warm_start)
        solver = workspace.solver
        if workspace.max_iter != max_iter or workspace.time_limit_s != limit:
            solver.update_settings(max_iter=max_iter, time_limit=limit)
            workspace.max_iter, workspace.time_limit_s = max_iter, limit
        if warm_start and workspace.last_x is not None and workspace.last_y is not None:
            solver.warm_start(x=workspace.last_x, y=workspace.last_y)
        else:
            solver.warm_start(x=clipped_reference(problem), y=np.zeros(l.shape[0]))

        results = solver.solve(raise_error=False)
        info = results.info
        workspace.rho_adapted |= int(info.rho_updates) > 0
        status = _STATUS_MAP.get(int(info.status_val), SolverStatus.FAILED)
        message = f"osqp: {info.status}"
        x = np.asarray(results.x, dtype=np.float64)
        y = np.asarray(results.y, dtype=np.float64)
        finite = np.concatenate([l[np.isfinite(l)], u[np.isfinite(u)], q])
        scale = 1.0 + float(np.max(np.abs(finite)))
        finite_iterate = (
            x.shape == (3 * n,)
            and bool(np.isfinite(x).all() and np.isfinite(y).all())
            and float(np.max(np.abs(x))) < _DIVERGED * scale
        )
        polished = int(info.status_polish) == 1
        returned = "solution"
        if status.converged and finite_iterate:
            violation = max_violation(workspace.A @ x, l, u)
            if polished and violation <= self._feasibility_tol:
                message += ", polished"
            elif violation > self._feasibility_tol:
                status = SolverStatus.SOLVED_INACCURATE
                message += f"; constraints violated by up to {violation:.1e}"
            workspace.last_x, workspace.last_y = x.copy(), y.copy()
        else:
            workspace.last_x = workspace.last_y = None
            if status.converged:  # "solved" with a non-finite or diverged iterate: never hand that out
                status = SolverStatus.FAILED
                message += ", diverged"
            if finite_iterate and status in (SolverStatus.MAX_ITERATIONS, SolverStatus.TIME_LIMIT):
                x = integrate_profile(problem, np.clip(x[2 * n :], l[2 * n : 3 * n], u[2 * n : 3 * n]))
                returned = "integrated_iterate"
                message += (
                    "; returned the last iterate's d″ integrated from the initial state "
                    "(consistent, not a solution: the d bounds may be broken)"
                )
            else:
                x = clipped_reference(problem)
                returned = "clipped_reference"
                message += "; returned the reference clipped to the bounds (not a solution)"

        osqp_status = str(info.status)
        extras: dict[str, Extra] = {
            "backend": "osqp",
            "backend_status": osqp_status,
            "osqp_status": osqp_status,
            "second_status": "",
            "polished": polished,
            "returned": returned,
        }
        A = workspace.A
        iterations = int(info.iter)

        def result(x: FloatArray, status: SolverStatus, message: str) -> LateralQPResult:
            info = SolveInfo(
                status=status,
                iterations=iterations,
                solve_time_ms=(time.perf_counter() - start) * 1e3 - setup_ms,
                objective=objective(problem, x[:n], x[n : 2 * n], x[2 * n :]) if status.converged else None,
                message=message,
                max_violation=max_violation(A @ x, l, u),
                setup_time_ms=setup_ms,
                extras=extras,
            )
            return LateralQPResult.of(x, info)

        # a converged answer that breaks a constraint by more than the tolerance (polishing picked a wrong
        # active set, or did not run) goes too: an interior-point solve is accurate where ADMM is not
        hand_over = (
            status in _HAND_OVER
            or status is SolverStatus.SOLVED_INACCURATE
            or int(info.status_val) == _INACCURATE_INFEASIBLE
        )
        proven = status is SolverStatus.INFEASIBLE and not hand_over  # OSQP's own certificate

        def remaining() -> float | None:
            """What is left of ``time_limit_s`` for the second backend [s] (None: no limit)."""
            return None if time_limit_s is None else max(limit - _since(start), 1e-3)

        if not (handing and (hand_over or (proven and relax))):
            if started and not proven:
                self._drop_elastic(problem)
            return replace(result(x, status, message), infeasible=proven)
        if proven:  # the certificate is the proof (no second opinion on it): straight to the elastic QP
            return self.relax(
                problem, replace(result(x, status, message), infeasible=True), time_limit_s=remaining()
            )
        if unreachable and not status.converged:
            message += f"; infeasible: the initial state misses the bounds by {gap:.2e}"
            first = replace(result(x, status, message), infeasible=True)
            return self.relax(problem, first, time_limit_s=remaining()) if relax else first
        if started:  # OSQP converged inaccurately on a problem proven infeasible: the second backend judges
            self._drop_elastic(problem)
        # where the QP proves infeasible its elastic problem is next: started beside the proof
        likely = (relax or relax_later) and float(info.prim_res) > self._spare_residual
        started = likely and self._start_elastic(problem, remaining())
        second = solve_conic_qp(
            workspace.P,
            q,
            A,
            l,
            u,
            max_iter=self._second_max_iter,
            time_limit_s=remaining(),
            feasibility_tol=self._feasibility_tol,
        )
        if started and (status.converged or second.info.status is not SolverStatus.INFEASIBLE):
            self._drop_elastic(problem)  # no proof that OSQP's answer needs relaxing: nothing to relax
        extras["second_status"] = str(second.info.extras["backend_status"])
        message += f"; {second.info.message}"
        first = result(x, status, message)
        if second.info.converged and (
            not status.converged or second.info.max_violation < first.info.max_violation
        ):
            if second.info.status is SolverStatus.SOLVED_INACCURATE:
                message += f" (constraints violated by up to {second.info.max_violation:.1e})"
            extras.update(backend=BACKEND, backend_status=extras["second_status"], returned="solution")
            return replace(result(second.x, second.info.status, message), first=first)
        if status.converged or second.info.status is not SolverStatus.INFEASIBLE:
            return first  # OSQP's answer, nearly feasible, beats a proof that none is exactly
        first = replace(first, infeasible=True)
        if not relax:
            return first
        return self.relax(problem, first, time_limit_s=remaining())

    def _unreachable(
        self, problem: LateralQPProblem, lower: FloatArray, upper: FloatArray, gap: float, start: float
    ) -> LateralQPResult:
        """The result of a solve proven infeasible before it began (the initial state misses the bounds by
        ``gap``, :func:`~solvers.lateral_qp_problem.reach_gap`) for a caller that takes converged answers
        only: the reference clipped to the bounds, ``infeasible``, no backend run. The set-up's next solve
        starts from the clipped reference, as after an unconverged solve."""
        key: _MatrixKey = (problem.n, problem.ds, problem.weights, problem.end_d is not None)
        workspace = self._workspaces.get(key)
        if workspace is not None:
            workspace.last_x = workspace.last_y = None
        _, A = qp_matrices(*key)
        x = clipped_reference(problem)
        info = SolveInfo(
            status=SolverStatus.INFEASIBLE,
            iterations=0,
            solve_time_ms=_since(start) * 1e3,
            objective=None,
            message=(
                f"infeasible: the initial state misses the bounds by {gap:.2e}; not solved; returned the "
                "reference clipped to the bounds (not a solution)"
            ),
            max_violation=max_violation(A @ x, lower, upper),
            extras={
                "backend": "osqp",
                "backend_status": "not run",
                "osqp_status": "not run",
                "second_status": "",
                "polished": False,
                "returned": "clipped_reference",
            },
        )
        return LateralQPResult.of(x, info, infeasible=True)

    def _solve_elastic(self, problem: LateralQPProblem, time_limit_s: float | None) -> ConicQPResult:
        """``problem``'s elastic problem solved by the second backend within ``time_limit_s`` [s]."""
        return solve_conic_qp(
            *elastic_qp(problem),
            max_iter=self._second_max_iter,
            time_limit_s=time_limit_s,
            feasibility_tol=self._feasibility_tol,
        )

    def _start_elastic(self, problem: LateralQPProblem, time_limit_s: float | None) -> bool:
        """Start ``problem``'s elastic problem on the spare thread for :meth:`relax` (False: no spare)."""
        if self._spare is None:
            return False
        self._elastic[id(problem)] = (problem, self._spare.submit(self._solve_elastic, problem, time_limit_s))
        while len(self._elastic) > self._max_cached:  # started for results nobody relaxed
            self._elastic.popitem(last=False)[1][1].cancel()
        return True

    def _drop_elastic(self, problem: LateralQPProblem) -> None:
        """Cancel ``problem``'s elastic problem where it has not started (else its result goes unused)."""
        started = self._elastic.pop(id(problem), None)
        if started is not None:
            started[1].cancel()

    def relax(
        self, problem: LateralQPProblem, first: LateralQPResult, *, time_limit_s: float | None = None
    ) -> LateralQPResult:
        """The path breaking ``problem``'s offset and curvature bounds least (the elastic problem's,
        :mod:`solvers.lateral_qp_elastic`; ``relaxed``: usable, not converged), ``first`` beside it, after
        a proof that ``problem`` has none (``first``, :meth:`solve`'s result with ``infeasible``: solved
        with ``relax=False``, to relax only where the caller needs it); ``first`` itself where the elastic
        problem does not converge. ``time_limit_s`` [s]: the second backend's safety net (None: none;
        an elastic problem started on the spare thread keeps the limit it started with).

        Raises:
            ValueError: ``first`` carries no proof of infeasibility.
        """
        if not first.infeasible:
            raise ValueError("first: relax() needs a result proven infeasible (solve(..., relax=False))")
        start = time.perf_counter()
        started = self._elastic.pop(id(problem), None)
        if started is not None and started[0] is problem:
            elastic = started[1].result()
        else:
            elastic = self._solve_elastic(problem, time_limit_s)
        if not elastic.info.converged:
            return first
        x, slack = split(problem, elastic.x)
        worst = float(np.max(slack, initial=0.0))
        _, A = qp_matrices(problem.n, problem.ds, problem.weights, problem.end_d is not None)
        _, lower, upper = qp_vectors(problem)
        extras = dict(first.info.extras)
        extras.update(
            backend=BACKEND, backend_status=str(elastic.info.extras["backend_status"]), returned="relaxed"
        )
        info = replace(
            first.info,
            status=SolverStatus.RELAXED,
            solve_time_ms=first.info.solve_time_ms + (time.perf_counter() - start) * 1e3,
            objective=None,
            message=f"{first.info.message}; the bounds relaxed by up to {worst:.2e}",
            max_violation=max_violation(A @ x, lower, upper),
            extras=extras,
        )
        return LateralQPResult.of(x, info, first=first)
