r"""The piecewise-jerk lateral path QP in the arc length ``s`` (Apollo-style): the problem, its matrices, its
cost; solved by :mod:`solvers.lateral_qp`.

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
         + w_jerk   Σ_{i=0}^{n−2} ((d″_{i+1} − d″_i)/Δs − r_i)²   (r = jerk_ref, default 0)
         + w_end_target (d_{n−1} − end_d)² + w_end_slope d′_{n−1}² + w_end_curv d″_{n−1}²

Constraints, for ``i = 0 … n−2`` (exact integration of a constant jerk over ``[s_i, s_{i+1}]``)::

    Δs·jerk_lower,i ≤ d″_{i+1} − d″_i ≤ Δs·jerk_upper,i      (default ∓jerk_max)
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
    q = −2·[ w_ref d_ref + w_end_target end_d e ;  0 ;  (w_jerk/Δs) Dᵀr ]
    A = [ I_{3n} ; jerk rows ; slope-integration rows ; offset-integration rows ]   ((6n − 3) × 3n)

with ``e`` the last unit vector and ``D`` the ``(n−1) × n`` forward difference. ``P`` and ``A`` depend
only on ``(n, Δs, weights, end_d given)``; :class:`~solvers.lateral_qp.LateralQPSolver` sets OSQP up once
per such key and afterwards only updates ``q, l, u``.

Default weights (per knot, so their ratios — not ``Δs`` — set the shape): each derivative order costs
ten times the previous one, which gives a smoothing length of about ``√10 ≈ 3.2 m`` for every term
(``(w_slope/w_ref)^{1/2} = (w_curv/w_ref)^{1/4} = (w_jerk/w_ref)^{1/6}``), short against a lane change.
``w_offset = 0.1`` pulls towards the reference line: on a long constant stretch the optimum is
``d = d_ref · w_ref/(w_ref + w_offset) ≈ 0.91 d_ref`` — set ``offset=0`` for pure tracking. The end
terms act on one knot and are worth about ten knots of their per-knot counterparts, so the path ends
settled (parallel to the reference, straight) and, if ``end_d`` is given, near it."""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, fields

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from solvers.result import SolveInfo
from solvers.validation import check_ordered, check_weights, float_array, scalar

FloatArray = NDArray[np.float64]

__all__ = [
    "LateralQPProblem",
    "LateralQPResult",
    "LateralWeights",
    "build_qp_matrices",
    "clipped_reference",
    "integrate_profile",
    "max_violation",
    "objective",
    "qp_matrices",
    "qp_vectors",
    "reach_gap",
]


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
        jerk_lower, jerk_upper: optional bounds on ``d‴`` [1/m²] per interval (``n − 1`` values, interval
            ``i`` from knot ``i`` to ``i + 1``), in place of ``∓jerk_max`` (``jerk_lower ≤ jerk_upper``).
        jerk_ref: optional jerk per interval [1/m²] the jerk term pulls ``d‴`` towards (default 0):
            e.g. the one that evens out the reference's own changes of curvature.
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
    jerk_lower: FloatArray | None = None
    jerk_upper: FloatArray | None = None
    jerk_ref: FloatArray | None = None
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
        if self.jerk_lower is not None:
            put("jerk_lower", float_array("jerk_lower", self.jerk_lower, size=n - 1, allow_neginf=True))
        if self.jerk_upper is not None:
            put("jerk_upper", float_array("jerk_upper", self.jerk_upper, size=n - 1, allow_posinf=True))
        if self.jerk_lower is not None and self.jerk_upper is not None:
            check_ordered("jerk_lower", self.jerk_lower, "jerk_upper", self.jerk_upper)
        if self.jerk_ref is not None:
            put("jerk_ref", float_array("jerk_ref", self.jerk_ref, size=n - 1))

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

    def _pinned_bounds(self) -> tuple[FloatArray, FloatArray]:
        """:meth:`_bounds` with knot 0 pinned to the initial state."""
        lower, upper = self._bounds()
        n = self.n
        lower[[0, n, 2 * n]] = upper[[0, n, 2 * n]] = (self.d0, self.dd0, self.ddd0)
        return lower, upper

    def jerk_bounds(self) -> tuple[FloatArray, FloatArray]:
        """Lower and upper bounds on ``d‴`` [1/m²] per interval (``∓jerk_max`` where not given)."""
        m1 = self.n - 1
        lower = np.full(m1, -self.jerk_max) if self.jerk_lower is None else np.asarray(self.jerk_lower)
        upper = np.full(m1, self.jerk_max) if self.jerk_upper is None else np.asarray(self.jerk_upper)
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
    ``[d, d′, d″]``. Where a second backend's solution is returned, ``first`` is the first backend's
    own result (its unfinished iterate, say), else None. ``infeasible`` says that the QP was proven to
    have no solution (OSQP's certificate, or the second backend's where OSQP did not converge) and not
    yet relaxed: :meth:`solvers.lateral_qp.LateralQPSolver.relax` gives its least-violating path.
    """

    info: SolveInfo
    d: FloatArray
    dd: FloatArray
    ddd: FloatArray
    x: FloatArray
    first: LateralQPResult | None = None
    infeasible: bool = False

    @classmethod
    def of(
        cls, x: FloatArray, info: SolveInfo, first: LateralQPResult | None = None, infeasible: bool = False
    ) -> LateralQPResult:
        """The result whose decision vector is ``x = [d, d′, d″]`` (``d``, ``dd``, ``ddd`` copied out)."""
        n = x.shape[0] // 3
        d, dd, ddd = x[:n].copy(), x[n : 2 * n].copy(), x[2 * n :].copy()
        return cls(info=info, d=d, dd=dd, ddd=ddd, x=x, first=first, infeasible=infeasible)


# --------------------------------------------------------------------------------------------------------
# Matrices


@functools.lru_cache(maxsize=8)
def qp_matrices(
    n: int, ds: float, weights: LateralWeights, has_end_d: bool
) -> tuple[sp.csc_matrix, sp.csc_matrix]:
    """``P`` (upper triangle, CSC) and ``A`` (CSC) for ``n`` knots at spacing ``ds``; the last few kept
    (a plan solves the same knots several times: retries, the second backend, the elastic problem), so
    they are shared: read them, never write to them."""
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


def qp_vectors(problem: LateralQPProblem) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``q, l, u`` of ``problem`` (bounds may be ±∞)."""
    n, w = problem.n, problem.weights
    q = np.zeros(3 * n)
    q[:n] = -2.0 * w.ref * problem.d_ref
    if problem.end_d is not None:
        q[n - 1] -= 2.0 * w.end_target * problem.end_d
    if problem.jerk_ref is not None:  # −2 (w_jerk/Δs) Σ r_i (d″_{i+1} − d″_i)
        pull = 2.0 * w.jerk / problem.ds * problem.jerk_ref
        q[2 * n : 3 * n - 1] += pull
        q[2 * n + 1 :] -= pull
    box_l, box_u = problem._pinned_bounds()
    jerk_lower, jerk_upper = problem.jerk_bounds()  # may be ∓inf
    m1 = n - 1
    l = np.concatenate([box_l, problem.ds * jerk_lower, np.zeros(2 * m1)])  # noqa: E741
    u = np.concatenate([box_u, problem.ds * jerk_upper, np.zeros(2 * m1)])
    return q, l, u


def build_qp_matrices(
    problem: LateralQPProblem,
) -> tuple[sp.csc_matrix, FloatArray, sp.csc_matrix, FloatArray, FloatArray]:
    """The QP of ``problem`` as ``(P, q, A, l, u)``: ``min ½ xᵀPx + qᵀx  s.t.  l ≤ Ax ≤ u``.

    ``P`` is the upper triangle of the (symmetric) Hessian in CSC form, as OSQP wants it; add its strict
    upper triangle's transpose for a full matrix. ``l``/``u`` may hold ±∞. Rows of ``A``: ``3n`` box rows
    (identity; knot 0 pinned to the initial state), then ``n−1`` jerk rows, ``n−1`` slope-integration rows
    and ``n−1`` offset-integration rows. The constant dropped from ``J`` is
    ``w_ref Σ d_ref,i² + w_end_target end_d² + w_jerk Σ r_i²``.
    """
    P, A = qp_matrices(problem.n, problem.ds, problem.weights, problem.end_d is not None)
    q, l, u = qp_vectors(problem)  # noqa: E741
    return P, q, A, l, u


def objective(problem: LateralQPProblem, d: FloatArray, dd: FloatArray, ddd: FloatArray) -> float:
    """The cost ``J`` of the module docstring (constant included) of a path ``(d, d′, d″)``."""
    w = problem.weights
    jerk = np.diff(ddd) / problem.ds
    if problem.jerk_ref is not None:
        jerk = jerk - problem.jerk_ref
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
    jerk ``(d″_{i+1} − d″_i)/Δs`` is clipped to its bounds (``±jerk_max`` unless given)."""
    ds = problem.ds
    jerk_lower, jerk_upper = problem.jerk_bounds()
    step = np.clip(np.diff(np.asarray(ddd, dtype=float)), ds * jerk_lower, ds * jerk_upper)
    return _integrated(problem, problem.ddd0 + np.concatenate(([0.0], np.cumsum(step))))


def _integrated(problem: LateralQPProblem, curv: FloatArray) -> FloatArray:
    """``x = [d, d′, d″]`` with d″ = ``curv`` [1/m] per knot, ``d′`` and ``d`` integrated from the initial
    state by the QP's equality rows."""
    ds = problem.ds
    slope = problem.dd0 + np.concatenate(([0.0], np.cumsum(0.5 * ds * (curv[:-1] + curv[1:]))))
    rise = ds * slope[:-1] + ds**2 / 3.0 * curv[:-1] + ds**2 / 6.0 * curv[1:]
    d = problem.d0 + np.concatenate(([0.0], np.cumsum(rise)))
    return np.concatenate([d, slope, curv])


def reach_gap(problem: LateralQPProblem) -> float:
    r"""How far [in each row's unit: m, -, 1/m] every path from the initial state misses a box bound: a
    proof of infeasibility where positive, found without solving (0 where none is found).

    Every ``d_i``, ``d′_i`` and ``d″_i`` of a path that meets the equality rows and the jerk rows grows
    with each jerk (non-negative coefficients), so the lowest path within the jerk rows and the ``d″``
    boxes bounds them from below::

        g_0 = d″_0,   g_{i+1} = max(ddd_lower,i+1, g_i + Δs·jerk_lower,i)      (g ≤ d″ of any such path)

    and ``d, d′`` integrated from ``g`` bound ``d, d′`` from below (likewise from above). The gap is the
    largest excess of such a bound over the opposite box bound at a knot ``i ≥ 1``: an ego that cannot
    steer back inside its bounds within the jerk limit (the usual cause), say. The offset bounds
    themselves are not propagated, so a positive gap proves infeasibility but 0 does not prove the
    opposite. Unbounded jerk gives 0."""
    jerk_lower, jerk_upper = problem.jerk_bounds()
    if not (np.all(np.isfinite(jerk_lower)) and np.all(np.isfinite(jerk_upper))):
        return 0.0
    n, ds = problem.n, problem.ds
    box_l, box_u = problem._pinned_bounds()

    def extreme(step: FloatArray, box: FloatArray, sign: float) -> FloatArray:
        # g_i − c_i = max(box_i − c_i, g_{i−1} − c_{i−1}), c the jerks accumulated; the upper path as the
        # lower one of the mirrored problem (sign −1: steps and box negated)
        c = np.concatenate(([0.0], np.cumsum(ds * step)))
        return _integrated(problem, sign * (c + np.maximum.accumulate(box[2 * n :] - c)))

    low = extreme(jerk_lower, box_l, 1.0)
    high = extreme(-jerk_upper, -box_u, -1.0)
    return float(max(np.max(low - box_u), np.max(box_l - high), 0.0))


def clipped_reference(problem: LateralQPProblem) -> FloatArray:
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


def max_violation(Ax: FloatArray, lower: FloatArray, upper: FloatArray) -> float:
    """Largest violation of ``l ≤ Ax ≤ u`` (in each row's own unit)."""
    return float(max(np.max(lower - Ax), np.max(Ax - upper), 0.0))
