"""The elastic lateral QP: the QP's own solution where it has one, the least relaxation where it has none."""

from __future__ import annotations

import warnings
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from typing import Any

import numpy as np
import pytest
import qpsolvers

from solvers.conic_qp import SETTINGS, qpsolvers_problem, solve_conic_qp
from solvers.lateral_qp import LateralQPSolver
from solvers.lateral_qp_elastic import _elastic_matrices, elastic_qp, split
from solvers.lateral_qp_problem import LateralQPProblem, objective
from solvers.result import SolverStatus


def _corridor(n: int = 80, width: float = 1.0, d0: float = 0.0, **kw: float) -> LateralQPProblem:
    s = np.arange(n) * 0.5
    return LateralQPProblem(
        ds=0.5,
        d_lower=np.full(n, -width),
        d_upper=np.full(n, width),
        d_ref=1.5 * np.sin(s / 6.0),  # leaves the corridor: the offset bounds are pressed
        jerk_max=0.5,
        d0=d0,
        ddd_lower=np.full(n, -0.2),
        ddd_upper=np.full(n, 0.2),
        **kw,
    )


def _elastic(problem: LateralQPProblem) -> tuple[SolverStatus, np.ndarray, np.ndarray]:
    result = solve_conic_qp(*elastic_qp(problem))
    x, slack = split(problem, result.x)
    return result.info.status, x, slack


def test_where_no_bound_presses_the_elastic_solution_is_the_qps() -> None:
    problem = _corridor(width=3.0)  # the reference stays inside: no bound is active
    exact = LateralQPSolver(second_backend=False).solve(problem)
    assert exact.info.status is SolverStatus.SOLVED
    status, x, slack = _elastic(problem)
    assert status is SolverStatus.SOLVED
    assert np.max(slack) < 1e-6
    np.testing.assert_allclose(x, exact.x, atol=1e-4)
    n = problem.n
    cost = objective(problem, x[:n], x[n : 2 * n], x[2 * n :])
    assert cost == pytest.approx(exact.info.objective, rel=1e-6)


def test_where_it_has_none_the_bounds_are_relaxed_least() -> None:
    # the ego 2 m left of a ±0.3 m corridor cannot get in before the corridor starts
    problem = _corridor(width=0.3, d0=2.0)
    status, x, slack = _elastic(problem)
    assert status is SolverStatus.SOLVED and np.max(slack) > 0.1
    n = problem.n
    d = x[:n]
    # the slacks are what the path needs: each offset bound broken by exactly its slack (knots 1 …)
    broken = np.maximum(d[1:] - problem.d_upper[1:], problem.d_lower[1:] - d[1:]).clip(0.0)
    np.testing.assert_allclose(slack[: n - 1], broken, atol=1e-4)  # to the interior point's accuracy
    # the violation is spread over the knots, not put on a few: it falls off as the path comes back
    outside = d[1:] - problem.d_upper[1:]
    assert outside[0] > 1.0 and np.all(np.diff(outside[outside > 0.01]) < 0.0)
    # a corridor that holds this path costs no relaxation at all
    wide = replace(problem, d_lower=np.full(n, -3.0), d_upper=np.full(n, 3.0))
    assert np.max(_elastic(wide)[2]) < 1e-6


def test_the_solver_hands_an_unfinished_qp_to_the_elastic_problem() -> None:
    problem = _corridor(width=0.3, d0=2.0)
    result = LateralQPSolver().solve(problem, max_iter=3)
    assert result.info.status is SolverStatus.RELAXED
    _, x, _ = _elastic(problem)
    np.testing.assert_allclose(result.x, x, atol=1e-9)


def _pinched() -> LateralQPProblem:
    """A 6 m corridor that jumps 4 m sideways within one knot: each side within reach of the start, no path
    makes the jump (the second backend's proof, not the start's reach)."""
    problem = _corridor(width=3.0)
    lower, upper = problem.d_lower.copy(), problem.d_upper.copy()
    lower[30], upper[31] = 2.0, -2.0
    return replace(problem, d_lower=lower, d_upper=upper)


def test_without_relaxation_an_unfinished_infeasible_qp_comes_back_with_the_proof_only() -> None:
    """``relax=False`` (a caller that takes converged answers only): the proof of infeasibility, no
    elastic path. Where the start's reach proves it, nothing is solved (the reference clipped to the
    bounds comes back); where the second backend does (a corridor pinched beyond the jerk limit's slope,
    each side within reach), OSQP's unfinished result with the proof beside it."""
    problem = _corridor(width=0.3, d0=2.0)
    result = LateralQPSolver().solve(problem, max_iter=3, relax=False)
    assert result.info.status is SolverStatus.INFEASIBLE and result.infeasible and not result.info.usable
    assert result.info.iterations == 0 and "the initial state misses the bounds" in result.info.message
    extras = result.info.extras
    assert (extras["osqp_status"], extras["second_status"], extras["returned"]) == (
        "not run",
        "",
        "clipped_reference",
    )
    assert result.d[0] == problem.d0 and np.all(np.abs(result.d[1:]) <= 0.3)
    pinched = _pinched()
    result = LateralQPSolver().solve(pinched, max_iter=3, relax=False)
    assert result.info.status is SolverStatus.MAX_ITERATIONS and result.infeasible
    extras = result.info.extras
    assert (extras["backend"], extras["second_status"], extras["returned"]) == (
        "osqp",
        "PrimalInfeasible",
        "integrated_iterate",
    )
    relaxed = LateralQPSolver().solve(pinched, max_iter=3)
    assert relaxed.info.status is SolverStatus.RELAXED
    np.testing.assert_array_equal(relaxed.first.x if relaxed.first is not None else None, result.x)


def test_a_proof_relaxed_later_is_the_path_relaxed_at_once() -> None:
    """``relax=False, relax_later=True`` marks the proof (``infeasible``: the start's reach after OSQP ran
    out, the second backend's, OSQP's own certificate) and :meth:`LateralQPSolver.relax` then gives exactly
    what ``relax=True`` gives at once: the same elastic path, status and extras, the unrelaxed result as
    ``first``; a result without a proof is misuse."""
    cases = ((_corridor(width=0.3, d0=2.0), 3), (_pinched(), 3), (_corridor(width=0.3, d0=2.0), 4000))
    for problem, max_iter in cases:
        proof = LateralQPSolver().solve(problem, max_iter=max_iter, relax=False, relax_later=True)
        assert proof.infeasible and not proof.info.converged
        later = LateralQPSolver().relax(problem, proof)
        at_once = LateralQPSolver().solve(problem, max_iter=max_iter)
        assert later.info.status is at_once.info.status is SolverStatus.RELAXED
        assert not later.infeasible and later.first is proof
        np.testing.assert_array_equal(later.x, at_once.x)
        assert later.info.extras == at_once.info.extras
        assert later.info.max_violation == at_once.info.max_violation
        assert later.info.iterations == at_once.info.iterations
    wide = _corridor(width=3.0, d0=0.0)
    solved = LateralQPSolver().solve(wide, relax=False)
    assert solved.info.converged and not solved.infeasible
    with pytest.raises(ValueError, match="proven infeasible"):
        LateralQPSolver().relax(wide, solved)


def test_the_elastic_matrices_are_the_ones_built_afresh() -> None:
    """The elastic problem's matrices, built once per key, are those built afresh, with each problem's own
    bounds."""
    problem = _corridor()
    first = elastic_qp(problem)
    built = _elastic_matrices.__wrapped__(problem.n, problem.ds, problem.weights, problem.end_d is not None)
    assert first[0] is elastic_qp(replace(problem, d0=problem.d0 + 0.1))[0]
    assert np.array_equal(first[0].toarray(), built[0].toarray())
    assert np.array_equal(first[2].toarray(), built[1].toarray())
    moved = elastic_qp(replace(problem, d0=problem.d0 + 0.1))
    assert not np.array_equal(moved[3], first[3])  # the bounds are the problem's own


def test_without_iterative_refinement_the_elastic_answer_is_that_with_it_to_a_micrometre() -> None:
    """Clarabel runs without refinement of its KKT solves (:data:`solvers.conic_qp.SETTINGS`, half of a
    lateral QP's solve): on an elastic lateral QP that must relax its bounds the answer is the refined
    one's to 1e-5 m and meets the constraints to 1e-8."""
    assert SETTINGS == {"iterative_refinement_enable": False}
    problem = _corridor(n=300, width=0.2, d0=1.0)  # starts outside a narrow corridor: infeasible
    P, q, A, lower, upper = elastic_qp(problem)
    fast = solve_conic_qp(P, q, A, lower, upper)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        refined = qpsolvers.solve_problem(qpsolvers_problem(P, q, A, lower, upper), solver="clarabel")
    assert fast.info.status is SolverStatus.SOLVED and refined.found
    np.testing.assert_allclose(fast.x, refined.x, atol=1e-5, rtol=0.0)
    assert fast.info.max_violation <= 1e-8
    _, slack = split(problem, fast.x)
    assert float(np.max(slack)) > 0.1  # the bounds are relaxed: a real elastic answer


class _Counting(ThreadPoolExecutor):
    """A one-worker executor that counts what it was given."""

    def __init__(self) -> None:
        super().__init__(max_workers=1)
        self.submitted = 0

    def submit(self, fn: Any, /, *args: Any, **kwargs: Any) -> Future[Any]:
        self.submitted += 1
        return super().submit(fn, *args, **kwargs)


def test_on_a_spare_thread_the_elastic_problem_starts_beside_the_proof_and_answers_the_same() -> None:
    """With a spare thread, an infeasible QP's elastic problem starts there beside the second backend's
    proof: relaxed at once, or later by :meth:`LateralQPSolver.relax`, the answer is the one without the
    spare thread. A QP the second backend solves leaves nothing behind to relax."""
    infeasible = _corridor(width=0.3, d0=2.0)
    alone = LateralQPSolver().solve(infeasible, max_iter=3)
    with _Counting() as spare:
        solver = LateralQPSolver(spare=spare)
        at_once = solver.solve(infeasible, max_iter=3)
        assert spare.submitted == 1
        assert at_once.info.status is SolverStatus.RELAXED
        np.testing.assert_array_equal(at_once.x, alone.x)
        assert at_once.info.extras == alone.info.extras
        proof = solver.solve(infeasible, max_iter=3, relax=False, relax_later=True)
        assert spare.submitted == 2 and proof.infeasible
        later = solver.relax(infeasible, proof)
        assert spare.submitted == 2  # the one started beside the proof
        np.testing.assert_array_equal(later.x, alone.x)
        # a proof nobody said would be relaxed starts nothing; relaxing it solves here
        unannounced = solver.solve(infeasible, max_iter=3, relax=False)
        assert spare.submitted == 2
        np.testing.assert_array_equal(solver.relax(infeasible, unannounced).x, alone.x)
        feasible = _corridor(width=3.0, d0=2.5)
        handed = solver.solve(feasible, max_iter=3, relax=False, relax_later=True)
        assert handed.info.converged and handed.info.extras["backend"] == "clarabel"
        assert not handed.infeasible
        np.testing.assert_array_equal(handed.x, LateralQPSolver().solve(feasible, max_iter=3).x)
