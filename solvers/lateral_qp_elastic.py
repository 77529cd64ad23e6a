r"""The lateral QP (:mod:`solvers.lateral_qp_problem`) with its offset and curvature bounds made elastic:
where the QP has no solution, the path that breaks those bounds least (the second backend's answer then,
:mod:`solvers.lateral_qp`).

With slacks ``σ_i ≥ 0`` on the offset bounds and ``ς_i ≥ 0`` on the ``d″`` bounds of knots ``1 … n−1``
(knot 0 stays pinned to the initial state), the decision vector ``z = [x, σ, ς] ∈ ℝ^{5n}`` and::

    min  J(x) + w_σ Σ σ_i² + w_ς Σ ς_i²
    s.t. d_lower,i ≤ d_i + σ_i,   d_i − σ_i ≤ d_upper,i          (i = 1 … n−1)
         ddd_lower,i ≤ d″_i + ς_i, d″_i − ς_i ≤ ddd_upper,i     (i = 1 … n−1)
         σ, ς ≥ 0, and every other row of the QP as it is (initial state, d′ bounds, jerks, integration)

It always has a solution: holding ``d″`` at ``ddd0`` meets the jerk rows, the integration rows then
define ``d`` and ``d′``, and the slacks take up the rest (the planner sets no ``d′`` bounds). At the
optimum each slack is exactly its bound's violation. The penalties are quadratic: a violation is spread
over the knots rather than put on a few (as ADMM's iterates on an infeasible QP spread it: they approach
the solution with the least-squares smallest shift of the bounds), the curvature bounds weighted
``w_ς / w_σ`` times more than the offsets (a path rather leaves its corridor than the vehicle's
curvature). A quadratic penalty is not exact — where the QP has a solution the slacks would be its bound
multipliers over ``2w`` — so the solver solves the QP itself first and this problem only after a proof
of infeasibility.
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from solvers.lateral_qp_problem import (
    FloatArray,
    LateralQPProblem,
    LateralWeights,
    build_qp_matrices,
    qp_matrices,
)

__all__ = ["CURVATURE_WEIGHT", "OFFSET_WEIGHT", "elastic_qp", "split"]

#: ``w_σ``: cost of relaxing an offset bound by ``σ`` [m] at one knot is ``w_σ σ²`` (far above the QP's
#: own weights: the slacks are the last resort)
OFFSET_WEIGHT = 1e4
#: ``w_ς``: cost of relaxing a ``d″`` bound by ``ς`` [1/m] at one knot is ``w_ς ς²``
CURVATURE_WEIGHT = 1e6


def elastic_qp(
    problem: LateralQPProblem,
) -> tuple[sp.csc_matrix, FloatArray, sp.csc_matrix, FloatArray, FloatArray]:
    """The elastic problem of ``problem`` as ``(P, q, A, l, u)`` over ``z = [x, σ, ς]`` (``P`` its upper
    triangle), in the form of :func:`solvers.lateral_qp_problem.build_qp_matrices`."""
    P_z, rows, rigid, soft = _elastic_matrices(
        problem.n, problem.ds, problem.weights, problem.end_d is not None
    )
    _, q, _, lower, upper = build_qp_matrices(problem)
    m = soft.shape[0]
    inf = np.full(m, np.inf)
    low = np.concatenate((lower[rigid], lower[soft], -inf, np.zeros(m)))
    high = np.concatenate((upper[rigid], inf, upper[soft], inf))
    return P_z, np.concatenate((q, np.zeros(m))), rows, low, high


@functools.lru_cache(maxsize=4)
def _elastic_matrices(
    n: int, ds: float, weights: LateralWeights, has_end_d: bool
) -> tuple[sp.csc_matrix, sp.csc_matrix, NDArray[np.intp], NDArray[np.intp]]:
    """The elastic problem's ``P`` and constraint matrix for the QP's key (see
    :func:`solvers.lateral_qp_problem.qp_matrices`; shared: never write to them), the rows of the QP's
    ``A`` kept rigid and those made soft, in the order of the elastic problem's rows."""
    P, A = qp_matrices(n, ds, weights, has_end_d)
    knots = np.arange(1, n)
    soft = np.concatenate((knots, 2 * n + knots))  # the box rows of d and d″ past knot 0
    slack_of = np.concatenate((knots - 1, n - 1 + knots - 1))  # their slack's index among 2(n − 1)
    rigid = np.setdiff1d(np.arange(A.shape[0]), soft)
    m = slack_of.shape[0]
    rows_of = sp.csr_matrix(A)
    # d + slack ≥ lower and d − slack ≤ upper; the slacks themselves ≥ 0
    plus = sp.hstack([rows_of[soft], sp.csr_matrix((np.ones(m), (np.arange(m), slack_of)), shape=(m, m))])
    minus = sp.hstack([rows_of[soft], sp.csr_matrix((-np.ones(m), (np.arange(m), slack_of)), shape=(m, m))])
    rigid_rows = sp.hstack([rows_of[rigid], sp.csr_matrix((rigid.shape[0], m))])
    slacks = sp.hstack([sp.csr_matrix((m, 3 * n)), sp.identity(m, format="csr")])
    rows = sp.csc_matrix(sp.vstack([rigid_rows, plus, minus, slacks]))
    weights_z = np.concatenate((np.full(n - 1, OFFSET_WEIGHT), np.full(n - 1, CURVATURE_WEIGHT)))
    P_z = sp.csc_matrix(sp.block_diag([P, sp.diags(2.0 * weights_z)]))
    return P_z, rows, rigid, soft


def split(problem: LateralQPProblem, z: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``x`` (``[d, d′, d″]``) and the slacks ``[σ, ς]`` of an elastic solution ``z``."""
    return z[: 3 * problem.n], z[3 * problem.n :]
