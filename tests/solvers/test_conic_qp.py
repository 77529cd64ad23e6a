"""The second QP backend (Clarabel through qpsolvers) on problems whose answers are known."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from solvers.conic_qp import BACKEND, qpsolvers_problem, solve_conic_qp
from solvers.result import SolverStatus


def _box_qp(lower: np.ndarray, upper: np.ndarray) -> tuple[sp.csc_matrix, np.ndarray, sp.csc_matrix]:
    """``min ½|x − (2, −3, 0.5)|²`` (constant dropped) with ``A`` the identity and the sum as a last row."""
    P = sp.identity(3, format="csc")
    q = -np.array([2.0, -3.0, 0.5])
    A = sp.vstack([sp.identity(3), sp.csr_matrix(np.ones((1, 3)))]).tocsc()
    assert lower.shape == upper.shape == (4,)
    return P, q, A


def test_a_box_and_an_equality_are_met_exactly() -> None:
    lower = np.array([-1.0, -1.0, -np.inf, 0.0])
    upper = np.array([1.0, np.inf, np.inf, 0.0])  # the sum is an equality row
    P, q, A = _box_qp(lower, upper)
    result = solve_conic_qp(P, q, A, lower, upper)
    assert result.info.status is SolverStatus.SOLVED and result.info.converged
    assert result.info.extras["backend"] == BACKEND and result.info.extras["backend_status"] == "Solved"
    # x₀ at its upper bound 1 and x₁ at its lower bound −1, x₂ = 0 closes the sum (multiplier 0.5 of the
    # sum, 0.5 of x₀'s bound, −2.5 of x₁'s: the KKT conditions hold)
    np.testing.assert_allclose(result.x, [1.0, -1.0, 0.0], atol=1e-7)
    assert result.info.max_violation <= 1e-6
    x = result.x
    assert result.info.objective == pytest.approx(0.5 * x @ x + q @ x, rel=1e-9)


def test_an_upper_triangle_is_read_as_the_symmetric_hessian() -> None:
    full = np.array([[2.0, 1.0], [1.0, 2.0]])
    P = sp.csc_matrix(np.triu(full))
    q = np.array([-1.0, -1.0])
    A = sp.identity(2, format="csc")
    result = solve_conic_qp(P, q, A, np.full(2, -10.0), np.full(2, 10.0))
    np.testing.assert_allclose(result.x, np.linalg.solve(full, -q), atol=1e-7)


def test_contradictory_rows_are_infeasible_not_an_exception() -> None:
    lower = np.array([-1.0, -1.0, -1.0, 5.0])  # the sum of three numbers in [−1, 1] cannot reach 5
    upper = np.array([1.0, 1.0, 1.0, np.inf])
    P, q, A = _box_qp(lower, upper)
    result = solve_conic_qp(P, q, A, lower, upper)
    assert result.info.status is SolverStatus.INFEASIBLE and not result.info.usable
    assert result.info.objective is None and np.all(np.isfinite(result.x))


def test_the_iteration_limit_is_a_status() -> None:
    lower = np.array([-1.0, -1.0, -np.inf, 0.0])
    upper = np.array([1.0, np.inf, np.inf, 0.0])
    P, q, A = _box_qp(lower, upper)
    result = solve_conic_qp(P, q, A, lower, upper, max_iter=1)
    assert result.info.status is SolverStatus.MAX_ITERATIONS and not result.info.converged


def test_misuse_raises() -> None:
    lower = np.zeros(4)
    P, q, A = _box_qp(lower, lower)
    with pytest.raises(ValueError, match="shape"):
        solve_conic_qp(P, q[:2], A, lower, lower)
    with pytest.raises(ValueError, match="max_iter"):
        solve_conic_qp(P, q, A, lower, lower, max_iter=0)
    with pytest.raises(ValueError, match="time_limit_s"):
        solve_conic_qp(P, q, A, lower, lower, time_limit_s=0.0)


def test_the_matrices_of_a_problem_seen_before_are_reused_and_those_built_anew() -> None:
    """qpsolvers' ``G`` and ``A_eq`` of an ``A`` with the same equal and finite rows, and the full ``P``,
    are those built before (not rebuilt); other bounds' finite rows give their own ``G``, and every
    matrix is the one a fresh build gives."""
    lower = np.array([-1.0, -1.0, -np.inf, 0.0])
    upper = np.array([1.0, np.inf, np.inf, 0.0])
    P, q, A = _box_qp(lower, upper)
    first = qpsolvers_problem(P, q, A, lower, upper)
    again = qpsolvers_problem(P, q, A, lower + 0.5, upper + 0.5)  # same equal and finite rows
    assert again.P is first.P and again.G is first.G and again.A is first.A
    np.testing.assert_array_equal(again.h, [1.5, 0.5, 0.5])  # h and b from these bounds
    np.testing.assert_array_equal(again.b, [0.5])
    other_upper = np.array([1.0, 2.0, np.inf, 0.0])  # x₁ bounded above too: another G
    other = qpsolvers_problem(P, q, A, lower, other_upper)
    assert other.G is not first.G and other.G.shape == (4, 3)
    fresh = qpsolvers_problem(P.copy(), q, A.copy(), lower, other_upper)  # new objects: built anew
    assert fresh.G is not other.G
    for built, anew in ((other.P, fresh.P), (other.G, fresh.G), (other.A, fresh.A)):
        assert (built != anew).nnz == 0 and built.format == anew.format == "csc"
    dense_G = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    np.testing.assert_array_equal(other.G.toarray(), dense_G)
