r"""Piecewise-jerk lateral path QP in the arc length ``s`` (Apollo-style), solved with OSQP.

Knots ``s_i = s_0 + i·Δs``, ``i = 0 … n−1`` (``n ≥ 3``, ``Δs > 0`` [m]). At each knot the unknowns are the
lateral offset ``d_i`` [m] (positive to the left), its slope ``d′_i = dd/ds`` [-] and its second
derivative ``d″_i`` [1/m]; between knots the third derivative is constant,
``d‴ = j_i = (d″_{i+1} − d″_i)/Δs`` [1/m²]. The decision vector is::

    x = [d_0 … d_{n−1}, d′_0 … d′_{n−1}, d″_0 … d″_{n−1}] ∈ ℝ^{3n}

Cost (``w·`` are the fields of :class:`LateralWeights`; the three end terms apply to the last knot only,
the ``end_target`` one only when the problem gives ``end_d``)::

    J(x) = w_ref    Σ_{i=0}^{n−1} (d_i − d_ref,i)²          track the reference offset
         + w_offset Σ_{i=0}^{n−1} d_i²                      stay near the reference line
         + w_slope  Σ_{i=0}^{n−1} d′_i²
         + w_curv   Σ_{i=0}^{n−1} d″_i²
         + w_jerk   Σ_{i=0}^{n−2} ((d″_{i+1} − d″_i)/Δs)²
         + w_end_target (d_{n−1} − end_d)² + w_end_slope d′_{n−1}² + w_end_curv d″_{n−1}²

Constraints, for ``i = 0 … n−2`` (exact integration of a constant jerk over ``[s_i, s_{i+1}]``)::

    −Δs·jerk_max ≤ d″_{i+1} − d″_i ≤ Δs·jerk_max
    d′_{i+1} = d′_i + Δs (d″_i + d″_{i+1}) / 2
    d_{i+1}  = d_i + Δs d′_i + Δs²/3 d″_i + Δs²/6 d″_{i+1}

for ``i = 1 … n−1`` (box bounds; a missing ``dd``/``ddd`` bound is ±∞)::

    d_lower,i ≤ d_i ≤ d_upper,i      dd_lower,i ≤ d′_i ≤ dd_upper,i      ddd_lower,i ≤ d″_i ≤ ddd_upper,i

and at knot 0 the initial state ``d_0 = d0, d′_0 = dd0, d″_0 = ddd0``. The initial state *replaces* the
bounds of knot 0: it is a measurement, and an ego slightly outside its bounds must still get a path that
returns inside as fast as the jerk limit allows (if it cannot, the problem is infeasible).

In OSQP's form ``min ½ xᵀPx + qᵀx  s.t.  l ≤ Ax ≤ u`` with ``J(x) = ½ xᵀPx + qᵀx + const``::

    P = 2·blockdiag( (w_ref + w_offset) I + w_end_target e eᵀ,
                     w_slope I + w_end_slope e eᵀ,
                     w_curv I + w_end_curv e eᵀ + (w_jerk/Δs²) DᵀD )       (upper triangle, CSC)
    q = −2·[ w_ref d_ref + w_end_target end_d e ;  0 ;  0 ]
    A = [ I_{3n} ; jerk rows ; slope-integration rows ; offset-integration rows ]   ((6n − 3) × 3n)

with ``e`` the last unit vector and ``D`` the ``(n−1) × n`` forward difference. ``P`` and ``A`` depend
only on ``(n, Δs, weights, end_d given)``; :class:`LateralQPSolver` sets OSQP up once per such key and
afterwards only updates ``q, l, u`` and warm-starts from the previous solution.

Default weights (per knot, so their ratios — not ``Δs`` — set the shape): each derivative order costs
ten times the previous one, which gives a smoothing length of about ``√10 ≈ 3.2 m`` for every term
(``(w_slope/w_ref)^{1/2} = (w_curv/w_ref)^{1/4} = (w_jerk/w_ref)^{1/6}``), short against a lane change.
``w_offset = 0.1`` pulls towards the reference line: on a long constant stretch the optimum is
``d = d_ref · w_ref/(w_ref + w_offset) ≈ 0.91 d_ref`` — set ``offset=0`` for pure tracking. The end
terms act on one knot and are worth about ten knots of their per-knot counterparts, so the path ends
settled (parallel to the reference, straight) and, if ``end_d`` is given, near it.

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
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import osqp
import scipy.sparse as sp
from numpy.typing import NDArray

from solvers.result import SolveInfo, SolverStatus
from solvers.validation import check_ordered, check_weights, float_array, integer, scalar

FloatArray = NDArray[np.float64]

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


@dataclass(frozen=True)
class LateralWeights:
    """Cost weights of the lateral QP (all ≥ 0 and finite); see the module docstring for ``J``.

    Attributes:
        ref: on ``(d_i − d_ref,i)²`` [1/m²].
        offset: on ``d_i²`` [1/m²], a pull towards the reference line.
        slope: on ``d′_i²`` [-].
        curvature: on ``d″_i²`` [m²].
        jerk: on ``((d″_{i+1} − d″_i)/Δs)²`` [m⁴].
        end_target: on ``(d_{n−1} − end_d)²`` [1/m²], only when the problem gives ``end_d``.
        end_slope: on ``d′_{n−1}²`` [-].
        end_curvature: on ``d″_{n−1}²`` [m²].
    """

    ref: float = 1.0
    offset: float = 0.1
    slope: float = 10.0
    curvature: float = 100.0
    jerk: float = 1000.0
    end_target: float = 10.0
    end_slope: float = 100.0
    end_curvature: float = 1000.0

    def __post_init__(self) -> None:
        check_weights(self, zero_allowed=[entry.name for entry in fields(self)])


@dataclass(frozen=True, kw_only=True, eq=False)
class LateralQPProblem:
    """One lateral QP: knot spacing, per-knot bounds and reference, jerk limit, initial state, weights.

    All arrays have length ``n ≥ 3`` (one value per knot); they are copied, converted to float64 and made
    read-only on construction. Construction raises ``ValueError`` on misuse: wrong shapes, NaN, a
    non-finite reference or initial state, ``lower > upper`` at any knot, ``ds ≤ 0`` or ``jerk_max ≤ 0``.
    Bounds may be ±∞ on their open side; ``jerk_max`` may be ``+∞`` (no jerk limit).

    Attributes:
        ds: knot spacing Δs [m], > 0.
        d_lower, d_upper: bounds on the offset ``d`` [m] per knot (knot 0 is pinned to ``d0`` instead).
        d_ref: target offset per knot [m] (e.g. a candidate profile).
        jerk_max: bound on ``|d‴|`` [1/m²], > 0.
        d0, dd0, ddd0: initial state ``d`` [m], ``d′`` [-], ``d″`` [1/m] at knot 0 (equality constraints).
        dd_lower, dd_upper: optional bounds on ``d′ = dd/ds`` [-] per knot.
        ddd_lower, ddd_upper: optional bounds on ``d″`` [1/m] per knot.
        weights: cost weights.
        end_d: optional target offset at the last knot [m], weighted by ``weights.end_target``.
    """

    ds: float
    d_lower: FloatArray
    d_upper: FloatArray
    d_ref: FloatArray
    jerk_max: float
    d0: float = 0.0
    dd0: float = 0.0
    ddd0: float = 0.0
    dd_lower: FloatArray | None = None
    dd_upper: FloatArray | None = None
    ddd_lower: FloatArray | None = None
    ddd_upper: FloatArray | None = None
    weights: LateralWeights = field(default_factory=LateralWeights)
    end_d: float | None = None

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        ds = scalar("ds", self.ds)
        if ds <= 0:
            raise ValueError(f"ds: must be > 0, got {ds}")
        put("ds", ds)

        jerk_max = scalar("jerk_max", self.jerk_max, allow_posinf=True)
        if jerk_max <= 0:
            raise ValueError(f"jerk_max: must be > 0 (or +inf), got {jerk_max}")
        put("jerk_max", jerk_max)

        d_ref_raw = np.asarray(self.d_ref)
        if d_ref_raw.ndim != 1 or d_ref_raw.shape[0] < 3:
            raise ValueError(f"d_ref: expected a 1-D array of at least 3 knots, got shape {d_ref_raw.shape}")
        n = int(d_ref_raw.shape[0])
        put("d_ref", float_array("d_ref", self.d_ref, size=n, item="knot"))
        put("d_lower", float_array("d_lower", self.d_lower, size=n, allow_neginf=True, item="knot"))
        put("d_upper", float_array("d_upper", self.d_upper, size=n, allow_posinf=True, item="knot"))
        check_ordered("d_lower", self.d_lower, "d_upper", self.d_upper)
        for prefix in ("dd", "ddd"):
            lower_name, upper_name = f"{prefix}_lower", f"{prefix}_upper"
            lower, upper = getattr(self, lower_name), getattr(self, upper_name)
            if lower is not None:
                lower = float_array(lower_name, lower, size=n, allow_neginf=True, item="knot")
                put(lower_name, lower)
            if upper is not None:
                upper = float_array(upper_name, upper, size=n, allow_posinf=True, item="knot")
                put(upper_name, upper)
            if lower is not None and upper is not None:
                check_ordered(lower_name, lower, upper_name, upper)

        for name in ("d0", "dd0", "ddd0"):
            put(name, scalar(name, getattr(self, name)))
        if self.end_d is not None:
            put("end_d", scalar("end_d", self.end_d))
        if not isinstance(self.weights, LateralWeights):
            raise ValueError(f"weights: expected LateralWeights, got {type(self.weights).__name__}")

    @property
    def n(self) -> int:
        """Number of knots."""
        return int(self.d_ref.shape[0])

    def _bounds(self) -> tuple[FloatArray, FloatArray]:
        """Lower and upper box bounds on ``x`` (knot 0 not yet pinned)."""
        n = self.n
        lower = np.full(3 * n, -np.inf)
        upper = np.full(3 * n, np.inf)
        lower[:n], upper[:n] = self.d_lower, self.d_upper
        if self.dd_lower is not None:
            lower[n : 2 * n] = self.dd_lower
        if self.dd_upper is not None:
            upper[n : 2 * n] = self.dd_upper
        if self.ddd_lower is not None:
            lower[2 * n :] = self.ddd_lower
        if self.ddd_upper is not None:
            upper[2 * n :] = self.ddd_upper
        return lower, upper


@dataclass(frozen=True, eq=False)
class LateralQPResult:
    """The solution of a lateral QP.

    ``d`` [m], ``dd`` (= d′) [-], ``ddd`` (= d″) [1/m] have one value per knot and never contain NaN. When
    the solve did not converge (``info.converged`` false) they hold, out of iterations or time
    (``max_iterations``, ``time_limit``), the last iterate's ``d″`` integrated from the initial state: a
    consistent path, usable (``info.usable``) after the caller's own checks, but the ``d`` bounds may be
    broken; otherwise (``infeasible``, ``failed``) the reference clipped to the bounds (with its
    finite-difference derivatives), for display or as a fallback, not a solution of the QP
    (``info.extras["returned"]`` says which). ``info.max_violation`` is the largest violation of
    ``l ≤ Ax ≤ u`` by ``x`` (each row in its own unit: m, -, 1/m). ``x`` is the raw decision vector
    ``[d, d′, d″]``.
    """

    info: SolveInfo
    d: FloatArray
    dd: FloatArray
    ddd: FloatArray
    x: FloatArray


# --------------------------------------------------------------------------------------------------------
# Matrices


_MatrixKey = tuple[int, float, LateralWeights, bool]


def _matrices(
    n: int, ds: float, weights: LateralWeights, has_end_d: bool
) -> tuple[sp.csc_matrix, sp.csc_matrix]:
    """``P`` (upper triangle, CSC) and ``A`` (CSC) for ``n`` knots at spacing ``ds``."""
    last = n - 1
    diag_d = np.full(n, weights.ref + weights.offset)
    if has_end_d:
        diag_d[last] += weights.end_target
    diag_dd = np.full(n, weights.slope)
    diag_dd[last] += weights.end_slope
    # curvature plus (w_jerk/Δs²)·DᵀD: DᵀD has diagonal [1, 2, …, 2, 1] and off-diagonals −1
    w_j = weights.jerk / ds**2
    diag_ddd = np.full(n, weights.curvature + 2.0 * w_j)
    diag_ddd[0] -= w_j
    diag_ddd[last] += weights.end_curvature - w_j
    diagonal = 2.0 * np.concatenate([diag_d, diag_dd, diag_ddd])
    k = np.arange(2 * n, 3 * n - 1)  # d″_i·d″_{i+1} entries, above the diagonal
    P = sp.csc_matrix(
        (
            np.concatenate([diagonal, np.full(n - 1, -2.0 * w_j)]),
            (np.concatenate([np.arange(3 * n), k]), np.concatenate([np.arange(3 * n), k + 1])),
        ),
        shape=(3 * n, 3 * n),
    )
    P.sort_indices()

    i = np.arange(n - 1)
    i_d, i_dd, i_ddd = i, n + i, 2 * n + i
    r_jerk = 3 * n + i
    r_vel = 4 * n - 1 + i
    r_pos = 5 * n - 2 + i
    rows = np.concatenate(
        [
            np.arange(3 * n),
            r_jerk, r_jerk,
            r_vel, r_vel, r_vel, r_vel,
            r_pos, r_pos, r_pos, r_pos, r_pos,
        ]
    )  # fmt: skip
    cols = np.concatenate(
        [
            np.arange(3 * n),
            i_ddd, i_ddd + 1,
            i_dd, i_dd + 1, i_ddd, i_ddd + 1,
            i_d, i_d + 1, i_dd, i_ddd, i_ddd + 1,
        ]
    )  # fmt: skip
    m1 = n - 1
    h1, h2, h3 = ds / 2, ds**2 / 3, ds**2 / 6
    vals = np.concatenate(
        [
            np.ones(3 * n),
            np.full(m1, -1.0), np.ones(m1),
            np.full(m1, -1.0), np.ones(m1), np.full(m1, -h1), np.full(m1, -h1),
            np.full(m1, -1.0), np.ones(m1), np.full(m1, -ds), np.full(m1, -h2), np.full(m1, -h3),
        ]
    )  # fmt: skip
    A = sp.csc_matrix((vals, (rows, cols)), shape=(6 * n - 3, 3 * n))
    A.sort_indices()
    return P, A


def _vectors(problem: LateralQPProblem) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``q, l, u`` of ``problem`` (bounds may be ±∞)."""
    n, w = problem.n, problem.weights
    q = np.zeros(3 * n)
    q[:n] = -2.0 * w.ref * problem.d_ref
    if problem.end_d is not None:
        q[n - 1] -= 2.0 * w.end_target * problem.end_d
    box_l, box_u = problem._bounds()
    box_l[[0, n, 2 * n]] = box_u[[0, n, 2 * n]] = (problem.d0, problem.dd0, problem.ddd0)
    jerk_step = problem.ds * problem.jerk_max  # may be +inf
    m1 = n - 1
    l = np.concatenate([box_l, np.full(m1, -jerk_step), np.zeros(2 * m1)])  # noqa: E741
    u = np.concatenate([box_u, np.full(m1, jerk_step), np.zeros(2 * m1)])
    return q, l, u


def build_qp_matrices(
    problem: LateralQPProblem,
) -> tuple[sp.csc_matrix, FloatArray, sp.csc_matrix, FloatArray, FloatArray]:
    """The QP of ``problem`` as ``(P, q, A, l, u)``: ``min ½ xᵀPx + qᵀx  s.t.  l ≤ Ax ≤ u``.

    ``P`` is the upper triangle of the (symmetric) Hessian in CSC form, as OSQP wants it; add its strict
    upper triangle's transpose for a full matrix. ``l``/``u`` may hold ±∞. Rows of ``A``: ``3n`` box rows
    (identity; knot 0 pinned to the initial state), then ``n−1`` jerk rows, ``n−1`` slope-integration rows
    and ``n−1`` offset-integration rows. The constant dropped from ``J`` is
    ``w_ref Σ d_ref,i² + w_end_target end_d²``.
    """
    P, A = _matrices(problem.n, problem.ds, problem.weights, problem.end_d is not None)
    q, l, u = _vectors(problem)  # noqa: E741
    return P, q, A, l, u


def objective(problem: LateralQPProblem, d: FloatArray, dd: FloatArray, ddd: FloatArray) -> float:
    """The cost ``J`` of the module docstring (constant included) of a path ``(d, d′, d″)``."""
    w = problem.weights
    jerk = np.diff(ddd) / problem.ds
    value = (
        w.ref * np.sum((d - problem.d_ref) ** 2)
        + w.offset * np.sum(d**2)
        + w.slope * np.sum(dd**2)
        + w.curvature * np.sum(ddd**2)
        + w.jerk * np.sum(jerk**2)
        + w.end_slope * dd[-1] ** 2
        + w.end_curvature * ddd[-1] ** 2
    )
    if problem.end_d is not None:
        value += w.end_target * (d[-1] - problem.end_d) ** 2
    return float(value)


def integrate_profile(problem: LateralQPProblem, ddd: FloatArray) -> FloatArray:
    """``x = [d, d′, d″]`` integrated exactly from the initial state with d″ [1/m] per knot (the
    equality rows of the QP hold; the box bounds need not). ``ddd[0]`` is replaced by ``ddd0`` and each
    jerk ``(d″_{i+1} − d″_i)/Δs`` is clipped to ``±jerk_max``."""
    ds = problem.ds
    step = np.clip(np.diff(np.asarray(ddd, dtype=float)), -ds * problem.jerk_max, ds * problem.jerk_max)
    curv = problem.ddd0 + np.concatenate(([0.0], np.cumsum(step)))
    slope = problem.dd0 + np.concatenate(([0.0], np.cumsum(0.5 * ds * (curv[:-1] + curv[1:]))))
    rise = ds * slope[:-1] + ds**2 / 3.0 * curv[:-1] + ds**2 / 6.0 * curv[1:]
    d = problem.d0 + np.concatenate(([0.0], np.cumsum(rise)))
    return np.concatenate([d, slope, curv])


def _fallback_path(problem: LateralQPProblem) -> FloatArray:
    """The reference clipped to the bounds, with clipped finite-difference derivatives, as ``x``."""
    n = problem.n
    lower, upper = problem._bounds()
    d = np.clip(problem.d_ref, lower[:n], upper[:n])
    d[0] = problem.d0
    dd = np.clip(np.gradient(d, problem.ds), lower[n : 2 * n], upper[n : 2 * n])
    dd[0] = problem.dd0
    ddd = np.clip(np.gradient(dd, problem.ds), lower[2 * n :], upper[2 * n :])
    ddd[0] = problem.ddd0
    return np.concatenate([d, dd, ddd])


def _max_violation(Ax: FloatArray, lower: FloatArray, upper: FloatArray) -> float:
    """Largest violation of ``l ≤ Ax ≤ u`` (in each row's own unit)."""
    return float(max(np.max(lower - Ax), np.max(Ax - upper), 0.0))


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


@dataclass
class _Workspace:
    """One OSQP set-up (fixed ``P``, ``A``) and the last solution (for the next warm start)."""

    solver: Any
    A: sp.csc_matrix
    max_iter: int
    time_limit_s: float
    last_x: FloatArray | None = None
    last_y: FloatArray | None = None
    #: OSQP adapted its step ``rho`` in an earlier solve (it keeps the adapted value for the next one)
    rho_adapted: bool = False


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

    A result's ``info.extras`` holds ``backend_status`` (OSQP's status text), ``polished`` (whether OSQP's
    polishing succeeded) and ``returned``: ``"solution"``, ``"integrated_iterate"`` (out of iterations or
    time: the last iterate's ``d″`` integrated from the initial state, consistent but not a solution) or
    ``"clipped_reference"`` (infeasible or failed: the reference clipped to the bounds).

    Args:
        eps_abs, eps_rel: OSQP's absolute and relative tolerances.
        polish: run OSQP's solution polishing.
        feasibility_tol: largest constraint violation accepted as ``solved``.
        max_cached: number of set-ups kept.
    """

    def __init__(
        self,
        *,
        eps_abs: float = 1e-3,
        eps_rel: float = 1e-3,
        polish: bool = True,
        feasibility_tol: float = 1e-6,
        max_cached: int = 4,
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
        self._workspaces: OrderedDict[_MatrixKey, _Workspace] = OrderedDict()
        self._setup_count = 0

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
        if workspace is not None and fresh and workspace.rho_adapted:
            workspace = None
        if workspace is not None:
            self._workspaces.move_to_end(key)
            workspace.solver.update(q=q, l=lower, u=upper)
            return workspace, 0.0
        start = time.perf_counter()
        P, A = _matrices(*key)
        solver = osqp.OSQP()
        # Set up with q = 0, then q: OSQP's cost scaling is computed from the set-up's q, so a set-up made
        # with one problem's q would make every later solve depend on which problem came first.
        solver.setup(
            P, np.zeros_like(q), A, lower, upper, max_iter=4000, time_limit=_NO_TIME_LIMIT_S, **self._settings
        )
        solver.update(q=q)
        self._setup_count += 1
        workspace = _Workspace(solver=solver, A=A, max_iter=4000, time_limit_s=_NO_TIME_LIMIT_S)
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
        q, l, u = _vectors(problem)  # noqa: E741
        workspace, setup_ms = self._workspace(problem, q, l, u, fresh=not warm_start)
        solver = workspace.solver
        if workspace.max_iter != max_iter or workspace.time_limit_s != limit:
            solver.update_settings(max_iter=max_iter, time_limit=limit)
            workspace.max_iter, workspace.time_limit_s = max_iter, limit
        if warm_start and workspace.last_x is not None and workspace.last_y is not None:
            solver.warm_start(x=workspace.last_x, y=workspace.last_y)
        else:
            solver.warm_start(x=_fallback_path(problem), y=np.zeros(l.shape[0]))

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
            violation = _max_violation(workspace.A @ x, l, u)
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
                x = _fallback_path(problem)
                returned = "clipped_reference"
                message += "; returned the reference clipped to the bounds (not a solution)"

        d, dd, ddd = x[:n].copy(), x[n : 2 * n].copy(), x[2 * n :].copy()
        solve_info = SolveInfo(
            status=status,
            iterations=int(info.iter),
            solve_time_ms=(time.perf_counter() - start) * 1e3 - setup_ms,
            objective=objective(problem, d, dd, ddd) if status.converged else None,
            message=message,
            max_violation=_max_violation(workspace.A @ x, l, u),
            setup_time_ms=setup_ms,
            extras={"backend_status": str(info.status), "polished": polished, "returned": returned},
        )
        return LateralQPResult(info=solve_info, d=d, dd=dd, ddd=ddd, x=x)
