r"""Speed profile ``s(t)`` along a fixed path: a jerk-controlled optimal control problem, solved by SQP.

Time grid ``t_k = k·Δt``, ``k = 0 … N`` (``Δt > 0`` [s], horizon ``N·Δt``). The state at ``t_k`` is the
arc length ``s_k`` [m], the speed ``v_k`` [m/s] and the acceleration ``a_k`` [m/s²]; the control is the
jerk ``j_k`` [m/s³], constant on ``[t_k, t_{k+1}]``, ``k = 0 … N−1``. Path, limits and obstacles reach
this module only as arrays: nothing here knows about roads.

Dynamics (exact integration of a constant jerk) and initial state, hard::

    a_{k+1} = a_k + j_k Δt
    v_{k+1} = v_k + a_k Δt + j_k Δt²/2
    s_{k+1} = s_k + v_k Δt + a_k Δt²/2 + j_k Δt³/6
    (s_0, v_0, a_0) = (s0, v0, a0)

Boxes, hard (``j_k`` for ``k = 0 … N−1``, the others for ``k = 1 … N``)::

    −j_max ≤ j_k ≤ j_max
    a_lo,k ≤ a_k ≤ a_hi,k        a_lo,k = min(a_min, a0 + j_max t_k),   a_hi,k = max(a_max, a0 − j_max t_k)
    v_k ≥ v_lo,k,   v_k + a_k Δt/2 + j_k Δt²/8 ≥ v_lo,k+½        (the speed at the knots and half-way)

The acceleration box is ``[a_min, a_max]`` unless the measured ``a0`` lies outside it; the box then opens
exactly as far as the jerk limit forces (the fastest return ``a0 ± j_max t``). That is the only relaxation of
``a_min`` and it needs no slack: ``a_min`` is the vehicle's physical limit, so braking harder is never traded
against a soft constraint — when full braking cannot keep a limit, the limit is violated (and the violation
reported). Likewise ``v ≥ 0`` (no reversing) gives way only where ``a0 < 0`` makes it impossible:
``v_lo = min(0, v_rec)`` with ``v_rec`` the speed under the fastest release of the brake,
``a_rec,k = min(a0 + j_max t_k, 0)``. With these bounds the hard constraints always have a solution (the
release profile), so every QP is feasible. The half-step row keeps a stopped vehicle stopped: with ``v ≥ 0``
at the knots only, an alternating ``a = ±ε`` would let it creep backwards between them.

Soft constraints, ``k = 1 … N``, with slacks ``σᵛ_k ≥ 0`` [m/s], ``σˢ_k ≥ 0`` [m] and ``σˡ_k ≥ 0`` [m]::

    v_k ≤ v_lim(s_k) + σᵛ_k      (k < N)        path speed limit
    v_N ≤ v_end(s_N) + σᵛ_N                      … at the horizon's end, with room to brake beyond it
    s_k ≤ s_bound,k + σˢ_k,      s_bound,k = min(s_stop, s_upper,k)
    s_k ≥ s_lower,k − σˡ_k                       (only where s_lower,k is finite)

``v_lim`` is the piecewise-linear interpolant of ``(limit_s, limit_v)``, constant beyond both ends (the caller
computes it as ``min(max_speed, target, √(a_lat,max/|κ(s)|))``); ``s_upper`` is optional (``+∞`` where free),
and so is ``s_lower`` (``−∞`` where free): a lower space-time bound, such as staying ahead of a vehicle that
comes from behind.
``v_end`` makes ``s_stop`` hold for all time, lets the next plan slow down for limits beyond the horizon
and keeps the vehicle able to stay behind ``s_upper`` continued at its final rate
``u = max(0, (s_upper,N − s_upper,N−1)/Δt)``. With ``b = −a_min/2`` and ``c = b²/(2 j_max)``::

    v_end(s) = min( min_{s′ ≥ s} √((v*(s′) + c)² + 2b(s′ − s)) − c,   u + √(c² + 2b(s_upper,N − s)₊) − c )

with ``v* = v_lim`` before ``s_stop`` and 0 from ``s_stop`` on: the highest speed at ``s`` from which braking
(a jerk-limited ramp to ``−b``, then ``−b``) gets below ``v*`` everywhere ahead, and down to the speed ``u``
before reaching the moving bound (the second term only when ``s_upper`` is given and finite at ``N``).
Constraints at ``k = 0`` are not imposed: the initial state is a measurement.

Cost (``w·`` and ``ρ·`` are the fields of :class:`SpeedWeights`)::

    J = Σ_{k=1}^{N} Δt [w_speed (v_k − v_target)² + w_acc a_k²] + Σ_{k=0}^{N−1} Δt w_jerk j_k²
      + Σ_{k=1}^{N} [ρ_v (σᵛ_k + σᵛ_k²/100) + ρ_s (σˢ_k + σˢ_k²/100) + ρ_l (σˡ_k + σˡ_k²/100)]

The running terms are weighted by ``Δt`` (an integral over time), so the weights do not depend on the grid.
The slack penalty is exact (ℓ1): when the soft constraints can be met, the optimum meets them exactly
(``ρ`` is far above their multipliers); when they cannot — ``v0`` above the limit, too close to ``s_stop``
to stop with ``a_min``, ``s_upper`` already behind the vehicle — the optimum is the physically best effort
(full braking within the jerk limit) instead of an infeasible problem. The small quadratic part spreads an
unavoidable violation instead of piling it up. :class:`SpeedResult` reports the violation of the returned
profile, evaluated on ``v_lim``, ``v ≥ 0``, ``s_bound`` and ``s_lower`` themselves.

The two position bounds can conflict: ``s_lower,k > s_bound,k`` (a block or a leader ahead, a follower
behind). The weights settle it. At such a knot the linear part of the penalty is
``ρ_s (s_k − s_bound,k)₊ + ρ_l (s_lower,k − s_k)₊``, falling with slope ``ρ_l`` up to ``s_bound,k``, rising
with ``ρ_s − ρ_l`` up to ``s_lower,k`` and with ``ρ_s`` beyond; with ``ρ_l < ρ_s`` its minimum is
``s_k = s_bound,k``. So the upper bound is kept and the lower one gives way by ``s_lower,k − s_bound,k``,
unless the rest of ``J`` pushes ``s_k`` forward by more than ``ρ_s − ρ_l`` per metre. The knots are coupled
through the dynamics: where ``s_bound`` dips for a few knots, keeping it holds ``s`` back at the knots
around the dip as well, and each of those can carry a lower-bound penalty, so ``ρ_s`` must exceed ``ρ_l``
times the number of knots involved (the default ``ρ_s = 100 ρ_l`` does; a ratio of 10 let a
staircase-shaped leader bound be overshot by 0.5 m). Likewise a speed excess ``δ`` over one step moves
every later knot by ``δ·Δt``, so the speed limit outranks ``s_lower`` while ``ρ_v > ρ_l·N·Δt`` (default:
10⁴ against 800 for 8 s).

Solution method: sequential quadratic programming. The only nonlinearity is the speed limit. Iteration
``i`` replaces it, around the current profile ``s̄``, by a local model that is a minimum of affine pieces
(so the QP stays convex)::

    v_k ≤ ℓ_k(s_k) + σᵛ_k  for every piece ℓ_k of knot k

* ``k < N``: the segment of ``v_lim`` holding ``s̄_k`` (the tangent), plus the segments behind and ahead of
  it where the kink between is concave. The minimum of the pieces is ``v_lim`` itself across a concave kink
  and lies below it beyond a convex one, so the model never over-estimates the limit near ``s̄_k``.
* ``k = N``: ``v_lim``'s tangent and, for each term of ``v_end``, its form ``(w + c)² + 2b s ≤ K`` (``w = v``,
  or ``v − u`` for the moving bound), convex in ``(s, v)`` and linear in ``s``, with ``(w + c)²`` replaced by
  its tangent at ``ŵ``, the expected value (Newton), or, when ``ŵ < 1 m/s``, by its chord over
  ``[0, 1 m/s]`` (exact at standstill, slightly conservative above). Linearised in ``s`` instead, ``v_end``
  would be far too steep near a stop. The QP's cost gets the Lagrangian's curvature of these rows,
  ``½ Σ λ/(ŵ + c)·(v_N − v̂)²`` with ``λ`` their multipliers in the previous QP, so that an end state sliding
  along the curved ``v_end`` converges quadratically rather than zig-zagging.

The QP is solved with HPIPM, a structure-exploiting (Riccati) interior-point method, through CasADi's
``qpsol``. It is built once per ``(N, Δt, weights)`` with ``v_target``, the pieces' slopes and the end
curvature as CasADi parameters and everything else as bounds, so nothing about its structure changes
between requests (the limit profile may have any number of points; an unused piece gets an infinite bound).
A problem whose ``s_lower`` is finite somewhere in ``k = 1 … N`` gets a second QP of that size, with ``σˡ``
as a fourth input per stage and the row ``s_{k+1} + σˡ_{k+1} ≥ s_lower,k+1``; every other problem keeps the
smaller one (one input and one row fewer per stage). The step to the QP's solution is globalised by a
backtracking line search on the exact penalty function (``J`` with the true violations as slacks); every
trial is dynamically feasible, since the dynamics are linear and the boxes convex. The iteration stops when
the model agrees with the limit at the QP's solution, wherever the speed is at the limit, to ``tolerance``
(100 × that at ``k = N``, a braking margin rather than a limit) — status ``solved`` — or after
``max_iterations`` QPs or a failed line search (``solved_inaccurate``: the best iterate, a valid profile
whose violations are reported truthfully; it happens where a sharp convex kink of ``v_lim``, a V-shaped
dip, has to be crossed by many knots, one or two per iteration). ``s̄`` starts from the previous solution
shifted in time (warm start) or from a forward–backward pass of the limit along the path, timed (cold
start), raised to ``s_lower`` and then capped by ``s_bound`` (the upper bound wins there too). The problem
is not convex, and at a sharp dip the SQP can end in a local minimum of the penalty function that violates
the limit. So when the result violates the limit, ``v ≥ 0`` or ``s_bound`` although :func:`braking_profile`
(a full stop) meets them (``s_lower`` aside: a full stop rarely keeps ahead of anything), the SQP runs once
more from that stop and the result with the lower penalty function is kept; if the violation remains, the
status is ``solved_inaccurate`` and the message says so. A QP that HPIPM stops early (iteration limit,
minimum step) is used if its iterate is finite and within the boxes, never as ``solved``; otherwise, and if
CasADi raises, the solve fails: status ``failed`` and the braking profile. The returned profile is
re-integrated from the jerks with the formulas above, so it meets the dynamics to rounding error whatever
the QP's accuracy.

Internally ``s`` is measured from ``s0``, so the QP's numbers stay small wherever the path frame starts.
What does not depend on the profile — the limit's segments and the model's pieces per segment, the
candidates of ``v_end``'s minimum as suffix minima sorted by ``s′``, the boxes — is computed once per
problem (on first use, kept on it), so each evaluation during the SQP is a lookup; and the QP reads and
writes numpy arrays directly (CasADi's function buffer), with no conversion per call.
"""

from __future__ import annotations

import math
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from solvers.result import SolveInfo, SolverStatus
from solvers.validation import check_weights, float_array, integer, scalar

FloatArray = NDArray[np.float64]

__all__ = [
    "MAX_STEPS",
    "SpeedProblem",
    "SpeedResult",
    "SpeedSolver",
    "SpeedWeights",
    "braking_profile",
    "cruise_profile",
    "end_speed_limit",
    "integrate_jerk",
    "objective",
    "solve_speed",
    "speed_limit",
]

#: largest horizon accepted [steps]
MAX_STEPS = 1000
#: HPIPM replaces ±∞ bounds by ± this (relative to s0, every quantity stays far below it)
_HPIPM_INF = 1e6
#: HPIPM's settings: about 20 interior-point iterations per QP here
_HPIPM_OPTIONS: dict[str, Any] = {
    "mode": "speed_abs",
    "mu0": 1.0,
    "iter_max": 100,
    "res_g_max": 1e-7,
    "res_b_max": 1e-7,
    "res_d_max": 1e-7,
    "res_m_max": 1e-7,
}
_HPIPM_RESIDUALS = ("res_g_max", "res_b_max", "res_d_max", "res_m_max")
#: HPIPM's return flags: converged; usable if the iterate is finite and within the boxes (converged,
#: iteration limit, minimum step length)
_HPIPM_SUCCESS = 0
_HPIPM_USABLE = (0, 1, 2)
#: a limit row counts as active when the speed is within this of the limit or its model [m/s]
_ACTIVE_BAND = 1e-3
#: step lengths the line search tries
_STEP_LENGTHS = tuple(0.5**i for i in range(7))
#: points of the cold start's forward–backward pass
_GUESS_POINTS = 257
#: the quadratic slack penalty, as a share of the linear one (per m/s or m)
_QUADRATIC_SHARE = 0.01
#: limit rows per knot (tangent, piece behind, piece ahead)
_PIECES = 3
#: the smallest v̂ of the horizon-end linearisation [m/s]
_NEWTON_MIN_SPEED = 1.0
#: the horizon-end row converges to this many times the tolerance
_END_TOLERANCE_FACTOR = 100.0
#: relative merit increase still accepted with a converged step (rounding)
_MERIT_SLACK = 1e-6
#: violations below this are rounding, not worth a word in the message
_REPORTED_VIOLATION = 1e-6
#: a violation above this is checked against a full stop, and the SQP restarted from it if that meets all
_RESTORE_VIOLATION = 1e-4
#: rows per stage: 3 dynamics, the half-step speed, the limit pieces, the position (and, in the QP with a
#: lower bound, one more: the lower position row)
_ROWS = 5 + _PIECES


# --------------------------------------------------------------------------------------------------------
# Problem and result


@dataclass(frozen=True)
class SpeedWeights:
    """Cost weights (see ``J`` in the module docstring); finite, ``acceleration ≥ 0``, the others ``> 0``.

    The defaults pull the speed towards ``v_target`` with a time constant of about
    ``√(acceleration/speed) ≈ 1.4 s``, smoothed by the jerk term; a 5 m/s speed-up takes about 4 s at
    ``a_max = 2 m/s²``. The slack penalties are per knot. The penalty is exact only above the constraints'
    multipliers, which grow like ``2·speed·v_target·N·Δt`` (a stop line held against a 35 m/s target over
    8 s: about 600): the defaults cover ``v_target·N·Δt`` up to a few thousand m. Raise them with the
    running weights or much longer horizons; ``max_violation`` shows when they were too low.

    ``follower_violation`` is a hundredth of ``position_violation`` and far below ``speed_violation``:
    where ``s_lower`` conflicts with ``s_bound`` or the limit, those win (module docstring). It is still
    exact for ``s_lower`` alone: keeping one metre further ahead costs about ``2·speed·|v − v_target|`` of
    running cost (a bound that holds the vehicle at 40 m/s against a target of 0: about 80).

    Attributes:
        speed: on ``Δt (v_k − v_target)²``.
        acceleration: on ``Δt a_k²``.
        jerk: on ``Δt j_k²``.
        speed_violation: ρ_v, on ``σᵛ_k + σᵛ_k²/100`` (``σᵛ`` in m/s).
        position_violation: ρ_s, on ``σˢ_k + σˢ_k²/100`` (``σˢ`` in m).
        follower_violation: ρ_l, on ``σˡ_k + σˡ_k²/100`` (``σˡ`` in m); below ``position_violation`` for the
            upper bound to win a conflict.
    """

    speed: float = 1.0
    acceleration: float = 2.0
    jerk: float = 0.5
    speed_violation: float = 1e4
    position_violation: float = 1e4
    follower_violation: float = 1e2

    def __post_init__(self) -> None:
        check_weights(self, zero_allowed=("acceleration",))


@dataclass(frozen=True, kw_only=True, eq=False)
class SpeedProblem:
    """One speed-profile request, validated on construction (``ValueError`` on misuse).

    Arrays are copied to read-only float64. Bounds and limits that cannot be met are not misuse: they are
    soft (see the module docstring) and the violation is reported.

    Attributes:
        dt: time step Δt [s], finite, > 0.
        steps: number of steps N, an integer in ``1 … MAX_STEPS``; profiles have N + 1 knots.
        v0: initial speed [m/s], finite, ≥ 0.
        limit_s: arc lengths of the speed limit [m], finite, strictly increasing, at least one point.
        limit_v: speed limit at ``limit_s`` [m/s], finite, ≥ 0; linear in between, constant beyond the ends.
        v_target: desired speed [m/s], finite, ≥ 0.
        a_min: most negative acceleration, −(max deceleration) [m/s²], finite, < 0.
        a_max: largest acceleration [m/s²], finite, ≥ 0.
        jerk_max: bound on ``|j|`` [m/s³], finite, > 0.
        s0: initial arc length [m], finite.
        a0: initial acceleration [m/s²], finite (may lie outside ``[a_min, a_max]``).
        s_stop: ``s(t) ≤ s_stop`` for all t [m] (a blocked point or the path's end); ``+inf``: none.
        s_upper: optional ``s(t_k) ≤ s_upper[k]`` [m], shape (N + 1,), ``+inf`` where free, no NaN or
            ``−inf`` (entry 0 is not imposed).
        s_lower: optional ``s(t_k) ≥ s_lower[k]`` [m], shape (N + 1,), ``−inf`` where free, no NaN or
            ``+inf`` (entry 0 is not imposed); softer than ``s_stop`` and ``s_upper`` where they conflict
            (``weights.follower_violation``).
        weights: cost weights.
    """

    dt: float
    steps: int
    v0: float
    limit_s: FloatArray
    limit_v: FloatArray
    v_target: float
    a_min: float
    a_max: float
    jerk_max: float
    s0: float = 0.0
    a0: float = 0.0
    s_stop: float = math.inf
    s_upper: FloatArray | None = None
    s_lower: FloatArray | None = None
    weights: SpeedWeights = field(default_factory=SpeedWeights)

    def __post_init__(self) -> None:
        def put(name: str, value: object) -> None:
            object.__setattr__(self, name, value)

        dt = scalar("dt", self.dt)
        if dt <= 0:
            raise ValueError(f"dt: must be > 0, got {dt}")
        put("dt", dt)
        put("steps", integer("steps", self.steps, low=1, high=MAX_STEPS))
        for name in ("v0", "v_target", "a_min", "a_max", "jerk_max", "s0", "a0"):
            put(name, scalar(name, getattr(self, name)))
        put("s_stop", scalar("s_stop", self.s_stop, allow_posinf=True))
        for name, value, ok, rule in (
            ("v0", self.v0, self.v0 >= 0, "≥ 0"),
            ("v_target", self.v_target, self.v_target >= 0, "≥ 0"),
            ("a_min", self.a_min, self.a_min < 0, "< 0"),
            ("a_max", self.a_max, self.a_max >= 0, "≥ 0"),
            ("jerk_max", self.jerk_max, self.jerk_max > 0, "> 0"),
        ):
            if not ok:
                raise ValueError(f"{name}: must be {rule}, got {value}")

        limit_s = float_array("limit_s", self.limit_s)
        if limit_s.size < 1:
            raise ValueError("limit_s: must have at least one point")
        limit_v = float_array("limit_v", self.limit_v, size=limit_s.size)
        steps_s = np.diff(limit_s)
        if np.any(steps_s <= 0):
            i = int(np.flatnonzero(steps_s <= 0)[0]) + 1
            raise ValueError(f"limit_s: must be strictly increasing (index {i}: {limit_s[i]})")
        if np.any(limit_v < 0):
            i = int(np.flatnonzero(limit_v < 0)[0])
            raise ValueError(f"limit_v: must be ≥ 0 (index {i}: {limit_v[i]})")
        put("limit_s", limit_s)
        put("limit_v", limit_v)
        knots = self.steps + 1
        if self.s_upper is not None:
            put("s_upper", float_array("s_upper", self.s_upper, size=knots, allow_posinf=True))
        if self.s_lower is not None:
            put("s_lower", float_array("s_lower", self.s_lower, size=knots, allow_neginf=True))
        if not isinstance(self.weights, SpeedWeights):
            raise ValueError(f"weights: expected SpeedWeights, got {type(self.weights).__name__}")

    @property
    def t(self) -> FloatArray:
        """Knot times ``t_k = k·Δt`` [s], shape (N + 1,)."""
        return np.arange(self.steps + 1, dtype=np.float64) * self.dt

    @cached_property
    def _tables(self) -> _Tables:
        """What the solver looks up again and again, computed on first use (the problem is immutable)."""
        return _Tables.of(self)

    def s_bound(self) -> FloatArray:
        """``min(s_stop, s_upper[k])`` per knot [m] (``+inf`` where free), shape (N + 1,)."""
        bound = np.full(self.steps + 1, self.s_stop)
        if self.s_upper is not None:
            bound = np.minimum(bound, self.s_upper)
        return bound

    def accel_bounds(self) -> tuple[FloatArray, FloatArray]:
        """``(a_lo, a_hi)`` per knot [m/s²]: ``[a_min, a_max]``, opened as far as an outside ``a0`` forces."""
        ramp = self.jerk_max * self.t
        return np.minimum(self.a_min, self.a0 + ramp), np.maximum(self.a_max, self.a0 - ramp)

    def speed_floor(self) -> tuple[FloatArray, FloatArray]:
        """``v_lo`` [m/s] at the knots (shape (N + 1,)) and half-way through the steps (shape (N,)).

        0, or less where ``a0 < 0`` makes a negative speed unavoidable: the speed under the fastest release
        of the brake, ``a_k = min(a0 + j_max t_k, 0)``. That is feasible, so the bound is safe; on the grid it
        is not always tight (a release overshooting to ``a > 0`` for one step can lose up to ``|a0|·Δt/2``
        less speed).
        """
        if self.a0 >= 0:
            return np.zeros(self.steps + 1), np.zeros(self.steps)
        dt = self.dt
        jerk = np.diff(np.minimum(self.a0 + self.jerk_max * self.t, 0.0)) / dt
        _, v, a = integrate_jerk(dt, 0.0, self.v0, self.a0, jerk)
        half = v[:-1] + a[:-1] * dt / 2 + jerk * dt**2 / 8
        return np.minimum(v, 0.0), np.minimum(half, 0.0)


@dataclass(frozen=True, eq=False)
class _Tables:
    """A problem's numbers that do not depend on the profile, computed once (read-only arrays).

    Attributes:
        slopes: ``slopes[i]`` is the slope of ``v_lim`` [1/s] where ``searchsorted(limit_s, s, "right")``
            is ``i``: 0 before and beyond the ends, else that of the segment holding ``s``; shape (M + 1,).
        rel_s: ``limit_s − s0`` [m] (the QP's frame).
        piece_e, piece_d: the pieces of :func:`_local_model` for ``s`` (relative to s0) with
            ``searchsorted(rel_s, s, "right")`` equal to the column: ``v ≤ e + d·s`` of the segment holding
            ``s`` (row 0), of the one behind and of the one ahead where the kink between is concave (rows 1
            and 2; ``e = +inf``, ``d = 0`` where not); shape ``(_PIECES, M + 1)``.
        b, c, rate, bound: as in :class:`_EndTerms` (``rate`` and ``bound`` ``None`` without a moving bound).
        end_s: the points ``s′ < s_stop`` where the minimum of ``v_end`` can lie other than ``s′ = s``
            (breakpoints, ``s_stop`` when finite, stationary points on falling segments), sorted [m].
        end_min: ``end_min[i]`` is the least energy ``(v*(s′) + c)² + 2b s′`` over ``end_s[i:]``, ``+inf`` at
            the end [m²/s²]; so the minimum over ``s′ > s`` is ``end_min[searchsorted(end_s, s, "right")]``.
        s_bound: :meth:`SpeedProblem.s_bound`; ``bound_finite``: where it is finite; ``bound_or_zero``: it,
            0 where infinite.
        lower: ``s_lower`` with entry 0 (not imposed) and a missing bound as ``−inf`` [m]; ``lower_finite``:
            where it is finite; ``lower_or_zero``: it, 0 where infinite; ``has_lower``: whether it is finite
            anywhere (the problem needs the QP with the ``σˡ`` slack).
        a_lo, a_hi: :meth:`SpeedProblem.accel_bounds`; v_lo, v_lo_half: :meth:`SpeedProblem.speed_floor`.
    """

    slopes: FloatArray
    rel_s: FloatArray
    piece_e: FloatArray
    piece_d: FloatArray
    b: float
    c: float
    rate: float | None
    bound: float | None
    end_s: FloatArray
    end_min: FloatArray
    s_bound: FloatArray
    bound_finite: NDArray[np.bool_]
    bound_or_zero: FloatArray
    lower: FloatArray
    lower_finite: NDArray[np.bool_]
    lower_or_zero: FloatArray
    has_lower: bool
    a_lo: FloatArray
    a_hi: FloatArray
    v_lo: FloatArray
    v_lo_half: FloatArray

    @staticmethod
    def of(problem: SpeedProblem) -> _Tables:
        xs, ys = problem.limit_s, problem.limit_v
        rel_s = xs - problem.s0
        edge = np.zeros(1)
        slopes = np.concatenate([edge, np.diff(ys) / np.diff(xs), edge])
        # segments −1 (before xs[0]) … M−1 (after xs[−1]) in columns 0 … M: lines v = e + d·s through their
        # left end (the first point for segment −1)
        piece_d = np.zeros((_PIECES, xs.size + 1))
        piece_e = np.full((_PIECES, xs.size + 1), np.inf)
        line_d = np.concatenate([edge, np.diff(ys) / np.diff(rel_s), edge])
        anchor = np.clip(np.arange(-1, xs.size), 0, xs.size - 1)
        line_e = ys[anchor] - line_d * rel_s[anchor]
        concave = line_d[1:] < line_d[:-1]  # the kink at each breakpoint
        piece_e[0], piece_d[0] = line_e, line_d
        piece_e[1, 1:] = np.where(concave, line_e[:-1], np.inf)
        piece_d[1, 1:] = np.where(concave, line_d[:-1], 0.0)
        piece_e[2, :-1] = np.where(concave, line_e[1:], np.inf)
        piece_d[2, :-1] = np.where(concave, line_d[1:], 0.0)

        b = -0.5 * problem.a_min
        c = b * b / (2.0 * problem.jerk_max)
        stop = problem.s_stop
        rate = bound = None
        if problem.s_upper is not None and math.isfinite(problem.s_upper[-1]):
            bound, before = float(problem.s_upper[-1]), float(problem.s_upper[-2])
            rate = max((bound - before) / problem.dt, 0.0) if math.isfinite(before) else 0.0
        ahead = xs < stop
        cand_s = [xs[ahead]]
        cand_v = [ys[ahead]]
        if math.isfinite(stop):
            cand_s.append(np.array([stop]))
            cand_v.append(np.array([0.0]))
        if xs.size >= 2:
            # stationary points of (v(s′) + c)² + 2b s′ on falling segments: v(s′) + c = −b/m
            m = slopes[1:-1]
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                x_star = xs[:-1] + (-b / m - c - ys[:-1]) / m
            inside = (m < 0) & (x_star > xs[:-1]) & (x_star < np.minimum(xs[1:], stop))
            cand_s.append(x_star[inside])
            cand_v.append(ys[:-1][inside] + m[inside] * (x_star[inside] - xs[:-1][inside]))
        end_s = np.concatenate(cand_s)
        energy = (np.maximum(np.concatenate(cand_v), 0.0) + c) ** 2 + 2.0 * b * end_s
        order = np.argsort(end_s, kind="stable")
        end_s = end_s[order]
        end_min = np.append(np.minimum.accumulate(energy[order][::-1])[::-1], math.inf)

        s_bound = problem.s_bound()
        bound_finite = np.isfinite(s_bound)
        bound_or_zero = np.where(bound_finite, s_bound, 0.0)
        lower = np.full(problem.steps + 1, -math.inf)
        if problem.s_lower is not None:
            lower[1:] = problem.s_lower[1:]
        lower_finite = np.isfinite(lower)
        lower_or_zero = np.where(lower_finite, lower, 0.0)
        a_lo, a_hi = problem.accel_bounds()
        v_lo, v_lo_half = problem.speed_floor()
        tables = _Tables(
            slopes=slopes,
            rel_s=rel_s,
            piece_e=piece_e,
            piece_d=piece_d,
            b=b,
            c=c,
            rate=rate,
            bound=bound,
            end_s=end_s,
            end_min=end_min,
            s_bound=s_bound,
            bound_finite=bound_finite,
            bound_or_zero=bound_or_zero,
            lower=lower,
            lower_finite=lower_finite,
            lower_or_zero=lower_or_zero,
            has_lower=bool(lower_finite.any()),
            a_lo=a_lo,
            a_hi=a_hi,
            v_lo=v_lo,
            v_lo_half=v_lo_half,
        )
        for value in vars(tables).values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
        return tables


@dataclass(frozen=True, eq=False)
class SpeedResult:
    """A speed profile: knots ``t, s, v, a`` (shape (N + 1,)) and the jerks ``jerk`` (shape (N,)).

    Never contains NaN, and always meets the dynamics (it is integrated from ``jerk``). When ``info.ok`` is
    false the profile is :func:`braking_profile`: full braking within the jerk limit, ignoring every other
    constraint — a safe fallback, not a solution.

    Attributes:
        info: status; iterations (interior-point iterations summed over the QPs); time; objective ``J``
            with the true violations as slacks (``None`` when not ok); message.
        t, s, v, a: time [s], arc length [m], speed [m/s], acceleration [m/s²] at the knots.
        jerk: jerk on each step [m/s³].
        speed_violation: largest ``max(v_k − v_lim(s_k), −v_k)`` over ``k ≥ 1``, or 0 [m/s].
        position_violation: largest ``s_k − min(s_stop, s_upper,k)`` over ``k ≥ 1``, or 0 [m].
        max_violation: the largest of the three violations (each in its own unit): the slack the profile
            needed.
        qp_solves: QPs solved (SQP iterations).
        follower_violation: largest ``s_lower,k − s_k`` over ``k ≥ 1``, or 0 [m].
    """

    info: SolveInfo
    t: FloatArray
    s: FloatArray
    v: FloatArray
    a: FloatArray
    jerk: FloatArray
    speed_violation: float
    position_violation: float
    max_violation: float
    qp_solves: int
    follower_violation: float = 0.0

    @property
    def ok(self) -> bool:
        """True when the profile is a solution (status ``solved`` or ``solved_inaccurate``)."""
        return self.info.ok


# --------------------------------------------------------------------------------------------------------
# Profile arithmetic (vectorised)


def speed_limit(problem: SpeedProblem, s: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """``(v_lim(s), v_lim′(s))`` [m/s, 1/s]: the path's limit and the slope of the segment holding ``s``.

    At a breakpoint the slope is that of the segment ahead; beyond the ends the limit is constant (slope 0).
    """
    s = np.asarray(s, dtype=np.float64)
    value = np.interp(s, problem.limit_s, problem.limit_v)
    slope = problem._tables.slopes[np.searchsorted(problem.limit_s, s, side="right")]
    return value, np.asarray(slope, dtype=np.float64)


def _limit_at(problem: SpeedProblem, s: float) -> tuple[float, float]:
    """:func:`speed_limit` at one point, as floats."""
    value = float(np.interp(s, problem.limit_s, problem.limit_v))
    return value, float(problem._tables.slopes[np.searchsorted(problem.limit_s, s, side="right")])


@dataclass(frozen=True)
class _EndTerms:
    """The binding terms of ``v_end`` at one ``s`` (see the module docstring).

    ``b``, ``c``: braking parameters. ``energy``: ``K = (v*(s′) + c)² + 2b s′`` of the binding ``s′`` (the
    constraint is ``(v + c)² + 2b s ≤ K``), ``None`` when ``s′ = s`` binds (then ``v_end = v_lim(s)``).
    ``rate``, ``bound``: ``u`` and ``s_upper,N`` of the moving-bound term, ``None`` without it.
    """

    b: float
    c: float
    energy: float | None
    rate: float | None
    bound: float | None


def _end_terms(problem: SpeedProblem, s: float) -> _EndTerms:
    tables = problem._tables
    b, c, stop = tables.b, tables.c, problem.s_stop
    if s >= stop:
        return _EndTerms(b, c, (0.0 + c) ** 2 + 2.0 * b * stop, tables.rate, tables.bound)
    # the least energy over s′ > s (table) against that of s′ = s; s′ = s wins a tie (then v_end = v_lim)
    ahead = float(tables.end_min[np.searchsorted(tables.end_s, s, side="right")])
    here = max(float(np.interp(s, problem.limit_s, problem.limit_v)), 0.0) + c
    energy = ahead if ahead < here * here + 2.0 * b * s else None
    return _EndTerms(b, c, energy, tables.rate, tables.bound)


def end_speed_limit(problem: SpeedProblem, s: float) -> float:
    """``v_end(s)`` [m/s], the horizon-end limit of the module docstring.

    The minimum over ``s′ ≥ s`` is exact: over ``s′ = s``, the breakpoints ahead, ``s_stop`` and, on each
    falling segment, the point where ``(v + c)² + 2b s′`` is stationary.
    """
    s = float(s)
    terms = _end_terms(problem, s)
    b, c = terms.b, terms.c
    if terms.energy is None:
        value = float(np.interp(s, problem.limit_s, problem.limit_v))
    else:
        value = math.sqrt(max(terms.energy - 2.0 * b * s, 0.0)) - c
    if terms.rate is not None and terms.bound is not None:
        value = min(value, terms.rate + math.sqrt(c * c + 2.0 * b * max(terms.bound - s, 0.0)) - c)
    return max(value, 0.0)


def integrate_jerk(
    dt: float, s0: float, v0: float, a0: float, jerk: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(s, v, a)`` at the knots from the initial state and the jerks (exact: constant jerk per step)."""
    jerk = np.asarray(jerk, dtype=np.float64)
    a = np.empty(jerk.size + 1)
    a[0] = 0.0
    np.cumsum(jerk * dt, out=a[1:])
    a += a0
    v = np.empty_like(a)
    v[0] = 0.0
    np.cumsum(a[:-1] * dt + jerk * (dt**2 / 2), out=v[1:])
    v += v0
    s = np.empty_like(a)
    s[0] = 0.0
    np.cumsum(v[:-1] * dt + a[:-1] * (dt**2 / 2) + jerk * (dt**3 / 6), out=s[1:])
    s += s0
    return s, v, a


def _violations(
    problem: SpeedProblem, s: FloatArray, v: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per-knot violations ``(e_v, e_s, e_l)`` of ``v_lim``/``v ≥ 0``, ``s_bound`` and ``s_lower`` (0 at
    knot 0)."""
    limit = np.interp(s, problem.limit_s, problem.limit_v)
    e_v = np.maximum(np.maximum(v - limit, -v), 0.0)
    e_v[0] = 0.0
    return e_v, _position_violations(problem, s), _follower_violations(problem, s)


def _position_violations(problem: SpeedProblem, s: FloatArray) -> FloatArray:
    """Per-knot violations of ``s_bound`` [m] (0 at knot 0)."""
    tables = problem._tables
    e_s = np.where(tables.bound_finite, np.maximum(s - tables.bound_or_zero, 0.0), 0.0)
    e_s[0] = 0.0
    return e_s


def _follower_violations(problem: SpeedProblem, s: FloatArray) -> FloatArray:
    """Per-knot violations of ``s_lower`` [m] (0 at knot 0 and where it is ``−inf``)."""
    tables = problem._tables
    if not tables.has_lower:
        return np.zeros_like(s)
    return np.where(tables.lower_finite, np.maximum(tables.lower_or_zero - s, 0.0), 0.0)


def objective(problem: SpeedProblem, s: FloatArray, v: FloatArray, a: FloatArray, jerk: ArrayLike) -> float:
    """``J`` of the module docstring for a profile, with its true violations as the slacks."""
    w, dt = problem.weights, problem.dt
    jerk = np.asarray(jerk, dtype=np.float64)
    s = np.asarray(s, dtype=np.float64)
    limit = np.interp(s[1:], problem.limit_s, problem.limit_v)
    limit[-1] = end_speed_limit(problem, float(s[-1]))
    e_v = np.maximum(v[1:] - limit, 0.0)
    e_s = _position_violations(problem, s)
    e_l = _follower_violations(problem, s)
    running = dt * (
        w.speed * np.sum((v[1:] - problem.v_target) ** 2)
        + w.acceleration * np.sum(a[1:] ** 2)
        + w.jerk * np.sum(jerk**2)
    )
    penalty = (
        w.speed_violation * np.sum(e_v + _QUADRATIC_SHARE * e_v**2)
        + w.position_violation * np.sum(e_s + _QUADRATIC_SHARE * e_s**2)
        + w.follower_violation * np.sum(e_l + _QUADRATIC_SHARE * e_l**2)
    )
    return float(running + penalty)


def _release(a: float, dt: float, jmax: float) -> tuple[list[float], float]:
    """The fastest return of ``a`` to 0 within ``jmax`` (full-jerk steps, then one partial step).

    Returns the jerks and the change of speed over them.
    """
    if a == 0.0:
        return [], 0.0
    direction = -math.copysign(1.0, a)
    full = math.floor(abs(a) / (jmax * dt) + 1e-12)
    rest = a + direction * jmax * dt * full  # what the partial step removes
    dv = full * a * dt + direction * jmax * dt**2 * full**2 / 2 + rest * dt / 2
    jerks = [direction * jmax] * full + ([-rest / dt] if abs(rest) > 1e-12 * (1.0 + abs(a)) else [])
    return jerks, dv


def _spare_speed(v: float, a: float, dt: float, jmax: float) -> float:
    """Speed left when ``a`` returns to 0 as fast as possible from ``(v, a)`` [m/s]."""
    return v + _release(a, dt, jmax)[1]


def braking_profile(problem: SpeedProblem) -> FloatArray:
    """Jerks of a full stop: ``a → a_min`` within ``jerk_max``, then back to 0 just as ``v`` reaches 0.

    The fallback when the solver fails; it ignores the path limit, ``s_stop`` and ``s_upper``. Each step
    brakes harder (towards ``a_min``) as long as the fastest release of the brake after it still ends at
    ``v ≥ 0``. Then one step with the jerk that makes that release end exactly at ``v = 0`` (found by
    bisection: the speed left is increasing in it), the release, and standstill. The jerk limit holds
    throughout, and ``v = a = 0`` at the end up to rounding. Where ``a0`` makes overshooting ``v = 0``
    unavoidable it releases as fast as possible and then stops the backward motion the same way (mirrored),
    so ``v`` stays above :meth:`SpeedProblem.speed_floor`.
    """
    dt, jmax, a_min = problem.dt, problem.jerk_max, problem.a_min
    n = problem.steps
    jerk: list[float] = []
    v, a = problem.v0, problem.a0

    def after(v: float, a: float, j: float) -> tuple[float, float]:
        return v + a * dt + j * dt**2 / 2, a + j * dt

    while len(jerk) < n and not (abs(v) <= 1e-12 and abs(a) <= 1e-12):
        sign = 1.0 if v > 0 or (v == 0 and a > 0) else -1.0  # mirror a backward motion
        vm, am = sign * v, sign * a
        brake = float(np.clip((a_min - am) / dt, -jmax, jmax))
        if _spare_speed(*after(vm, am, brake), dt, jmax) >= 0:
            steps = [brake]
        elif _spare_speed(vm, am, dt, jmax) < 0:
            steps = [min(jmax, -am / dt)]  # overshooting whatever happens: release as fast as possible
        else:  # the landing: the spare speed after j is −… at j = brake and ≥ 0 at j = jmax
            low, high = brake, jmax
            for _ in range(60):
                mid = 0.5 * (low + high)
                low, high = (mid, high) if _spare_speed(*after(vm, am, mid), dt, jmax) < 0 else (low, mid)
            steps = [high, *_release(after(vm, am, high)[1], dt, jmax)[0]]
        for j in steps[: n - len(jerk)]:
            jerk.append(sign * j)
            v, a = after(v, a, sign * j)
        if len(steps) > 1:  # landed, up to rounding
            v = a = 0.0
    return np.array(jerk + [0.0] * (n - len(jerk)), dtype=np.float64)


def cruise_profile(problem: SpeedProblem) -> FloatArray:
    """Jerks that keep the speed: ``a0`` back to 0 as fast as ``jerk_max`` allows, then constant speed.

    Like :func:`braking_profile` it ignores every soft constraint. Where releasing a brake (``a0 < 0``)
    would end below ``v = 0`` the vehicle stops instead: the result is then :func:`braking_profile`.
    """
    jerks, dv = _release(problem.a0, problem.dt, problem.jerk_max)
    if problem.v0 + dv < 0.0:
        return braking_profile(problem)
    jerk = np.zeros(problem.steps)
    head = jerks[: problem.steps]
    jerk[: len(head)] = head
    return jerk


# --------------------------------------------------------------------------------------------------------
# The QP, built once per (N, dt, weights)


class _QP:
    """A built QP evaluated on numpy arrays through CasADi's function buffer (no conversion per call).

    Fill ``p``, ``lbx``, ``ubx``, ``lbg`` and ``ubg`` in place (``slopes`` and ``limit_rows`` are views of
    ``p`` and ``ubg`` in the shape ``(_PIECES, N)`` of :func:`_local_model`), call :meth:`solve`, then read
    ``x`` and ``lam_g``: the next call overwrites them. The outputs the solver does not read are not
    copied. The initial guesses are zero, as in a call without them. ``width`` is the number of variables
    per stage (3 states, then 3 inputs, or 4 with the lower bound's slack) and ``rows`` that of rows.
    """

    def __init__(self, function: Any, steps: int, lower: bool = False) -> None:
        n = steps
        self.width = 7 if lower else 6
        self.rows = _ROWS + 1 if lower else _ROWS
        width, rows = self.width, self.rows
        self.p = np.zeros(3 + _PIECES * n)
        self.lbx = np.zeros(width * n + 3)
        self.ubx = np.zeros(width * n + 3)
        self.lbg = np.zeros(rows * n)
        self.ubg = np.zeros(rows * n)
        self.x = np.zeros(width * n + 3)
        self.lam_g = np.zeros(rows * n)
        self.slopes = self.p[3:].reshape(n, _PIECES).T
        self.limit_rows = self.ubg.reshape(n, rows).T[4 : 4 + _PIECES]
        self._function = function
        zero_x, zero_g = np.zeros(width * n + 3), np.zeros(rows * n)
        inputs = {"p": self.p, "lbx": self.lbx, "ubx": self.ubx, "lbg": self.lbg, "ubg": self.ubg}
        inputs |= {"x0": zero_x, "lam_x0": zero_x, "lam_g0": zero_g}
        self._inputs = [(function.index_in(name), array.data) for name, array in inputs.items()]
        outputs = {"x": self.x, "lam_g": self.lam_g}
        self._outputs = [(function.index_out(name), array.data) for name, array in outputs.items()]

    def solve(self) -> tuple[int, int]:
        """Solve the QP in the arrays: ``(HPIPM's return flag, its iterations)``.

        Raises:
            RuntimeError: CasADi reports a failed evaluation.
        """
        # A new buffer per call (about 30 µs): in CasADi 3.7.0 and 3.8.0 (not 3.8.2) a buffer evaluated
        # again carries state over from the last evaluation (the QP's x came out as the sum of both).
        buffer, evaluate = self._function.buffer()
        for index, data in self._inputs:
            buffer.set_arg(index, data)
        for index, data in self._outputs:
            buffer.set_res(index, data)
        self.x.fill(np.nan)  # so that an evaluation that writes nothing cannot pass for a solution
        self.lam_g.fill(np.nan)
        evaluate()
        code = buffer.ret()
        if code:
            raise RuntimeError(f"the QP's evaluation failed (CasADi code {code})")
        # the buffer's own statistics (it evaluates in its own memory); CasADi 3.6 has only the function's
        stats = buffer.stats() if hasattr(buffer, "stats") else self._function.stats()
        return int(stats.get("return_status", -1)), int(stats.get("iter_count", 0))


def _build_qp(steps: int, dt: float, w: SpeedWeights, lower: bool = False, residual: float = 1e-7) -> _QP:
    """The CasADi/HPIPM QP in stage order ``z = [x_0, u_0, x_1, u_1, …, x_N]``.

    ``x_k = (s_k − s0, v_k, a_k)``, ``u_k = (j_k, σᵛ_{k+1}, σˢ_{k+1})``. Rows of stage ``k < N``: the three
    dynamics rows ``f(x_k, u_k) − x_{k+1} = 0``, the half-step speed ``≥ v_lo``, then the soft rows of
    knot ``k + 1`` written through the dynamics (so that they belong to stage ``k``): ``v − d·s − σᵛ ≤ ·``
    (the linearised limit, one per piece, slope ``d`` a parameter) and ``s − σˢ ≤ ·``. With ``lower``,
    ``u_k`` ends with ``σˡ_{k+1}`` and the stage with the row ``s + σˡ ≥ ·``. Parameters
    ``p = [v_target, end curvature, v̂_N, d_1 … d_N]``; all else is bounds.
    """
    n = steps
    X = ca.SX.sym("x", 3, n + 1)
    U = ca.SX.sym("u", 4 if lower else 3, n)
    p = ca.SX.sym("p", 3 + _PIECES * n)
    v_target, curvature, v_hat = p[0], p[1], p[2]
    slope = ca.reshape(p[3:], _PIECES, n)
    s, v, a = X[0, :n], X[1, :n], X[2, :n]
    j, sig_v, sig_s = U[0, :], U[1, :], U[2, :]
    s1 = s + dt * v + dt**2 / 2 * a + dt**3 / 6 * j
    v1 = v + dt * a + dt**2 / 2 * j
    a1 = a + dt * j
    v_half = v + dt / 2 * a + dt**2 / 8 * j
    limit_rows = [v1 - slope[i, :] * s1 - sig_v for i in range(_PIECES)]
    soft = [s1 - sig_s]
    cost = (
        dt * (w.speed * ca.sumsqr(X[1, 1:] - v_target) + w.acceleration * ca.sumsqr(X[2, 1:]))
        + dt * w.jerk * ca.sumsqr(j)
        + w.speed_violation * (ca.sum2(sig_v) + _QUADRATIC_SHARE * ca.sumsqr(sig_v))
        + w.position_violation * (ca.sum2(sig_s) + _QUADRATIC_SHARE * ca.sumsqr(sig_s))
        + curvature / 2 * (X[1, n] - v_hat) ** 2
    )
    if lower:
        sig_l = U[3, :]
        soft.append(s1 + sig_l)
        cost += w.follower_violation * (ca.sum2(sig_l) + _QUADRATIC_SHARE * ca.sumsqr(sig_l))
    rows = ca.vertcat(s1 - X[0, 1:], v1 - X[1, 1:], a1 - X[2, 1:], v_half, *limit_rows, *soft)
    width, n_rows = 3 + U.shape[0], rows.shape[0]
    g = ca.reshape(rows, n_rows * n, 1)
    z = ca.vertcat(ca.reshape(ca.vertcat(X[:, :n], U), width * n, 1), X[:, n])
    options: dict[str, Any] = {
        "error_on_fail": False,
        "inf": _HPIPM_INF,
        "hpipm": {**_HPIPM_OPTIONS, **{k: residual for k in _HPIPM_RESIDUALS}},
        "N": n,
        "nx": [3] * (n + 1),
        "nu": [width - 3] * n + [0],
        "ng": [n_rows - 3] * n + [0],
    }
    return _QP(ca.qpsol("speed_qp", "hpipm", {"x": z, "p": p, "f": cost, "g": g}, options), n, lower)


# --------------------------------------------------------------------------------------------------------
# Start profiles


def _cap(problem: SpeedProblem, s_bar: FloatArray) -> FloatArray:
    """``s_bar`` (relative to s0) raised to ``s_lower`` at and before each knot, then capped by the bounds
    at and ahead of each knot (the upper bounds win), non-decreasing, ≥ 0."""
    tables = problem._tables
    if tables.has_lower:
        s_bar = np.maximum(s_bar, np.maximum.accumulate(tables.lower - problem.s0))
    s_bar = np.minimum(s_bar, tables.s_bound - problem.s0)
    s_bar = np.minimum.accumulate(s_bar[::-1])[::-1]
    return np.maximum(s_bar, 0.0)


def _cold_start(problem: SpeedProblem) -> tuple[FloatArray, float]:
    """Guesses of ``s_k − s0`` and ``v_N``: a forward–backward pass of the limit along the path, timed.

    Along ``σ = s − s0`` the speed ``min(v_target, v_lim)`` (0 at ``s_stop``) is lowered to what braking at
    ``a_min/2`` ahead of every point and accelerating at ``a_max/2`` from ``v0`` allow (running minima of
    ``v² ± 2aσ``), but not below braking from ``v0`` at ``a_min``; the time along it is sampled at ``t_k``.
    """
    n, dt = problem.steps, problem.dt
    stop = problem.s_stop - problem.s0
    reach = n * dt * max(problem.v0, problem.v_target, float(np.max(problem.limit_v))) + 1.0
    end = min(reach, stop)
    if end <= 1e-6:
        return np.zeros(n + 1), 0.0
    sigma = np.linspace(0.0, end, _GUESS_POINTS)
    v_cap = np.minimum(np.interp(problem.s0 + sigma, problem.limit_s, problem.limit_v), problem.v_target)
    if stop <= reach:
        v_cap[-1] = 0.0
    brake, accel = -0.5 * problem.a_min, max(0.5 * problem.a_max, 1e-3)
    v2 = np.minimum.accumulate((v_cap**2 + 2 * brake * sigma)[::-1])[::-1] - 2 * brake * sigma
    v2 = np.minimum(v2, np.minimum.accumulate(v2 - 2 * accel * sigma) + 2 * accel * sigma)
    v2 = np.minimum(v2, problem.v0**2 + 2 * accel * sigma)
    v2 = np.maximum(v2, problem.v0**2 + 2 * problem.a_min * sigma)
    speed = np.sqrt(np.maximum(v2, 0.0))
    mean = 0.5 * (speed[1:] + speed[:-1])
    t_of_sigma = np.concatenate([[0.0], np.cumsum(np.diff(sigma) / np.maximum(mean, 1e-3))])
    t = problem.t
    s_bar = np.interp(t, t_of_sigma, sigma)
    beyond = t > t_of_sigma[-1]
    s_bar[beyond] = end + speed[-1] * (t[beyond] - t_of_sigma[-1])
    s_bar = _cap(problem, s_bar)
    v_end = float(np.interp(s_bar[-1], sigma, speed))
    terms = _end_terms(problem, problem.s0 + float(s_bar[-1]))
    if terms.rate is not None and terms.bound is not None and problem.s0 + s_bar[-1] >= terms.bound - 1e-6:
        v_end = min(v_end, terms.rate)  # held at the moving bound: its speed
    if s_bar[-1] >= stop - 1e-6:
        v_end = 0.0  # held at the stop
    return s_bar, v_end


def _shifted(problem: SpeedProblem, previous: SpeedResult, shift: int) -> tuple[FloatArray, float]:
    """``s_k − s0`` and ``v_N`` of ``previous`` advanced by ``shift`` of its steps, re-anchored at ``s0``."""
    t_prev, s_prev, v_prev = previous.t, previous.s, previous.v
    offset = shift * float(t_prev[1] - t_prev[0])
    t = problem.t + offset
    s_bar = np.interp(t, t_prev, s_prev)
    beyond = t > t_prev[-1]
    s_bar[beyond] = s_prev[-1] + max(float(v_prev[-1]), 0.0) * (t[beyond] - t_prev[-1])
    s_bar -= float(np.interp(offset, t_prev, s_prev))
    return _cap(problem, s_bar), max(float(np.interp(t[-1], t_prev, v_prev)), 0.0)


# --------------------------------------------------------------------------------------------------------
# Solver


@dataclass
class _Iterate:
    """A profile (``s`` relative to s0) and its exact penalty function."""

    jerk: FloatArray
    s: FloatArray
    v: FloatArray
    a: FloatArray
    merit: float


def _iterate(problem: SpeedProblem, jerk: FloatArray) -> _Iterate:
    s, v, a = integrate_jerk(problem.dt, 0.0, problem.v0, problem.a0, jerk)
    return _Iterate(jerk=jerk, s=s, v=v, a=a, merit=objective(problem, s + problem.s0, v, a, jerk))


def _within_boxes(problem: SpeedProblem, iterate: _Iterate, tol: float = 1e-6) -> bool:
    """Whether an iterate keeps the hard acceleration and speed bounds (its jerks are clipped already)."""
    tables = problem._tables
    return bool(
        np.all(iterate.a[1:] >= tables.a_lo[1:] - tol)
        and np.all(iterate.a[1:] <= tables.a_hi[1:] + tol)
        and np.all(iterate.v >= tables.v_lo - tol)
    )


@dataclass
class _Run:
    """What one SQP run produced."""

    best: _Iterate | None
    converged: bool
    qp_solves: int
    ipm_iterations: int
    notes: list[str]


def _max_violation(problem: SpeedProblem, iterate: _Iterate) -> float:
    """The largest violation of ``v_lim``, ``v ≥ 0`` and ``s_bound`` by an iterate (not ``s_lower``: this
    decides a restart from a full stop, which rarely keeps ahead of anything)."""
    e_v, e_s, _ = _violations(problem, iterate.s + problem.s0, iterate.v)
    return float(max(np.max(e_v), np.max(e_s)))


def _true_limit(problem: SpeedProblem, s: FloatArray) -> FloatArray:
    """The limit rows' true right-hand side at knots ``1 … N`` of ``s`` (relative to s0)."""
    value = np.interp(problem.s0 + s[1:], problem.limit_s, problem.limit_v)
    value[-1] = end_speed_limit(problem, problem.s0 + float(s[-1]))
    return value


def _local_model(
    problem: SpeedProblem, s_bar: FloatArray, v_end_guess: float
) -> tuple[FloatArray, FloatArray, bool, FloatArray]:
    """The linear model of the limit at knots ``1 … N`` of ``s_bar`` (relative to s0): ``v ≤ e + d·s``.

    Returns ``(e, d)`` of shape ``(_PIECES, N)``; a row with ``e = +inf`` is unused. For ``k < N`` row 0 is
    the segment holding ``s̄_k`` and rows 1 and 2 the segments behind and ahead where the kink between is
    concave: there the minimum of the pieces *is* ``v_lim``, so the model stays exact across the kink (at a
    convex kink the tangent alone lies below ``v_lim``, which is safe). At ``N`` row 0 is ``v_lim``'s
    tangent and rows 1 and 2 linearise ``v_end``'s two terms (module docstring) around ``v_end_guess``, the
    expected ``v_N`` [m/s]. Also returns whether those are tangents (exact at ``v_N = v_end_guess``) rather
    than chords, and their curvature in ``v`` per unit multiplier, ``1/(ŵ + c)`` (0 for a chord or unused).
    """
    tables = problem._tables
    s = s_bar[1:]
    column = np.searchsorted(tables.rel_s, s, side="right")
    e = tables.piece_e[:, column]
    d = tables.piece_d[:, column]
    # knot N: v_end. Its terms (v + c)² + 2b s ≤ K are convex in (s, v) (in s alone v_end is far too steep
    # near a stop to linearise). (v + c)² is replaced by its tangent at v̂, the expected v_N (Newton: exact
    # where v_N = v̂), or, when v̂ is below _NEWTON_MIN_SPEED, by its chord over [0, _NEWTON_MIN_SPEED]
    # (exact at standstill, conservative up to that speed).
    e[:, -1], d[:, -1] = np.inf, 0.0
    s_end = float(s[-1])
    terms = _end_terms(problem, problem.s0 + s_end)
    b, c = terms.b, terms.c
    limit, slope = _limit_at(problem, problem.s0 + s_end)
    e[0, -1], d[0, -1] = limit - slope * s_end, slope
    exact = True
    inverse = np.zeros(_PIECES)  # 1/(v̂ + c) of tangent rows: their curvature in v per unit multiplier

    def row(i: int, speed: float, offset: float, energy: float) -> None:
        """Row ``i`` at N: ``(w + c)² + 2b s ≤ energy`` for ``w = v − offset`` around ``w = speed``."""
        nonlocal exact
        if speed >= _NEWTON_MIN_SPEED:
            e[i, -1] = offset + speed + (energy - (speed + c) ** 2) / (2 * (speed + c))
            d[i, -1] = -b / (speed + c)
            inverse[i] = 1.0 / (speed + c)
        else:
            exact = False
            top = _NEWTON_MIN_SPEED
            e[i, -1], d[i, -1] = offset + (energy - c * c) / (top + 2 * c), -2 * b / (top + 2 * c)

    if problem.s0 + s_end >= problem.s_stop:  # beyond the stop already: the end state must be at rest
        e[1, -1] = 0.0
    elif terms.energy is not None:
        row(1, v_end_guess, 0.0, terms.energy - 2.0 * b * problem.s0)
    if terms.rate is not None and terms.bound is not None:
        if problem.s0 + s_end >= terms.bound:  # at or beyond the moving bound: no faster than it
            e[2, -1] = terms.rate
        else:
            row(2, v_end_guess - terms.rate, terms.rate, c * c + 2.0 * b * (terms.bound - problem.s0))
    return e, d, exact, inverse


class SpeedSolver:
    """Solves :class:`SpeedProblem` s by SQP over HPIPM QPs built once per ``(N, Δt, weights)``.

    Building a QP takes about 0.1 s (N = 80); up to ``max_cached`` are kept, least recently used dropped
    first. Not thread-safe: use one solver per thread (see :func:`solve_speed`).

    Args:
        max_iterations: QPs per solve (SQP iterations), ≥ 1.
        tolerance: agreement of the linearised limit with the limit, wherever the speed is near it, that
            counts as converged [m/s], > 0.
        max_cached: number of built QPs kept, ≥ 1.
        restore_violation: a violation [m/s or m] above which the SQP restarts from a full stop (when
            that meets every constraint); a caller that checks the profile anyway can save the second
            run by raising it.
    """

    def __init__(
        self,
        *,
        max_iterations: int = 5,
        tolerance: float = 1e-4,
        max_cached: int = 4,
        restore_violation: float = _RESTORE_VIOLATION,
        qp_residual: float = 1e-7,
    ) -> None:
        if not 0 < qp_residual < 1:
            raise ValueError(f"qp_residual: must be in (0, 1), got {qp_residual!r}")
        if not 0 < restore_violation < math.inf:
            raise ValueError(f"restore_violation: must be a finite number > 0, got {restore_violation!r}")
        self._max_iterations = integer("max_iterations", max_iterations, low=1)
        self._tolerance = scalar("tolerance", tolerance)
        if self._tolerance <= 0:
            raise ValueError(f"tolerance: must be > 0, got {tolerance!r}")
        self._max_cached = integer("max_cached", max_cached, low=1)
        self._restore_violation = float(restore_violation)
        self._qp_residual = float(qp_residual)
        self._qps: OrderedDict[tuple[int, float, SpeedWeights, bool], _QP] = OrderedDict()
        self._build_count = 0

    @property
    def build_count(self) -> int:
        """How many QPs this solver has built (one per new ``(N, Δt, weights)`` still in the cache, and per
        whether the problem has a lower bound)."""
        return self._build_count

    def _qp(self, problem: SpeedProblem) -> _QP:
        key = (problem.steps, problem.dt, problem.weights, problem._tables.has_lower)
        qp = self._qps.get(key)
        if qp is None:
            qp = self._qps[key] = _build_qp(*key, residual=self._qp_residual)
            self._build_count += 1
            while len(self._qps) > self._max_cached:
                self._qps.popitem(last=False)
        else:
            self._qps.move_to_end(key)
        return qp

    def solve(
        self, problem: SpeedProblem, *, warm_start: SpeedResult | None = None, shift: int = 1
    ) -> SpeedResult:
        """Solve ``problem``; non-convergence is reported in ``result.info.status``, never raised.

        Args:
            problem: the request (validated on construction).
            warm_start: a previous result (any horizon and Δt); its profile, advanced by ``shift`` of its
                steps and re-anchored at ``problem.s0``, is the first point of linearisation (the QPs are
                interior-point, so that point is all a warm start can carry).
            shift: steps of ``warm_start`` elapsed since it was computed, ≥ 0.

        Raises:
            ValueError: ``problem`` is not a :class:`SpeedProblem`, ``warm_start`` not a
                :class:`SpeedResult` (or ``None``), or ``shift`` not an integer ≥ 0.
        """
        start = time.perf_counter()
        if not isinstance(problem, SpeedProblem):
            raise ValueError(f"problem: expected SpeedProblem, got {type(problem).__name__}")
        if warm_start is not None and not isinstance(warm_start, SpeedResult):
            raise ValueError(f"warm_start: expected SpeedResult or None, got {type(warm_start).__name__}")
        shift = integer("shift", shift, low=0)

        qp = self._qp(problem)
        if warm_start is not None and warm_start.t.size >= 2:
            (s_bar, v_end), origin = _shifted(problem, warm_start, shift), "warm"
        else:
            (s_bar, v_end), origin = _cold_start(problem), "cold"
        self._set_bounds(problem, qp)
        run = self._sqp(problem, qp, s_bar, v_end, self._max_iterations)
        best, converged, notes = run.best, run.converged, run.notes
        qp_solves, ipm_iterations = run.qp_solves, run.ipm_iterations
        if best is not None and _max_violation(problem, best) > self._restore_violation:
            # a violation although a full stop meets every constraint: a local minimum of the penalty
            # function (a sharp V-shaped dip of v_lim can hold one); try again from the full stop
            stop = braking_profile(problem)
            s_stop, v_stop, a_stop = integrate_jerk(problem.dt, 0.0, problem.v0, problem.a0, stop)
            if _max_violation(problem, _Iterate(stop, s_stop, v_stop, a_stop, 0.0)) <= 1e-9:
                retry = self._sqp(problem, qp, s_stop, 0.0, self._max_iterations)
                qp_solves += retry.qp_solves
                ipm_iterations += retry.ipm_iterations
                if retry.best is not None and retry.best.merit < best.merit:
                    best, converged = retry.best, retry.converged
                    notes = [*retry.notes, "restarted from a full stop after a violation it did not need"]
                if _max_violation(problem, best) > self._restore_violation:
                    converged = False
                    notes.append("a violation remains although a full stop meets every constraint")

        if best is None:
            status = SolverStatus.FAILED
            jerk = braking_profile(problem)
            notes.append("returned the braking profile (not a solution)")
        else:
            status = SolverStatus.SOLVED if converged else SolverStatus.SOLVED_INACCURATE
            jerk = best.jerk
            if not converged and not notes:
                notes.append(f"the limit's linearisation had not converged after {qp_solves} QPs")
        s, v, a = integrate_jerk(problem.dt, problem.s0, problem.v0, problem.a0, jerk)
        e_v, e_s, e_l = _violations(problem, s, v)
        speed_violation, position_violation = float(np.max(e_v)), float(np.max(e_s))
        follower_violation = float(np.max(e_l))
        message = f"SQP from a {origin} start: {qp_solves} QPs, {ipm_iterations} HPIPM iterations"
        if best is not None and max(speed_violation, position_violation) > _REPORTED_VIOLATION:
            notes.append(
                f"soft constraints violated by up to {speed_violation:.3g} m/s and {position_violation:.3g} m"
            )
        if best is not None and follower_violation > _REPORTED_VIOLATION:
            notes.append(f"s_lower violated by up to {follower_violation:.3g} m")
        if notes:
            message += "; " + "; ".join(notes)
        info = SolveInfo(
            status=status,
            iterations=ipm_iterations,
            solve_time_ms=(time.perf_counter() - start) * 1e3,
            objective=best.merit if best is not None and status.ok else None,  # J of this very profile
            message=message,
        )
        return SpeedResult(
            info=info,
            t=problem.t,
            s=s,
            v=v,
            a=a,
            jerk=np.array(jerk, dtype=np.float64),
            speed_violation=speed_violation,
            position_violation=position_violation,
            max_violation=max(speed_violation, position_violation, follower_violation),
            qp_solves=qp_solves,
            follower_violation=follower_violation,
        )

    def _sqp(self, problem: SpeedProblem, qp: _QP, s_bar: FloatArray, v_end: float, budget: int) -> _Run:
        """Up to ``budget`` SQP iterations, linearised first at ``(s̄, v̂_N)`` (bounds set in ``qp``)."""
        n = problem.steps
        best: _Iterate | None = None
        multipliers = np.zeros(_PIECES)  # of the end rows in the last QP
        converged = False
        qp_solves = ipm_iterations = 0
        notes: list[str] = []
        end_rows = slice(qp.rows * (n - 1) + 4, qp.rows * (n - 1) + 4 + _PIECES)
        qp.p[0] = problem.v_target
        for _ in range(budget):
            e, d, exact_end, inverse = _local_model(problem, s_bar, v_end)
            qp.limit_rows[...] = e
            qp.slopes[...] = d
            qp.p[1] = float(np.dot(multipliers, inverse))  # the end rows' curvature
            qp.p[2] = v_end
            try:
                flag, iterations = qp.solve()
            except RuntimeError as error:  # CasADi reports a crashed backend this way
                notes.append(f"QP {qp_solves + 1} raised: {str(error).splitlines()[-1][:120]}")
                break
            qp_solves += 1
            ipm_iterations += iterations
            jerk = qp.x[3 : qp.width * n : qp.width]
            if flag not in _HPIPM_USABLE or not np.all(np.isfinite(jerk)):
                notes.append(f"QP {qp_solves} failed (HPIPM flag {flag})")
                break
            target = _iterate(problem, np.clip(jerk, -problem.jerk_max, problem.jerk_max))
            if flag != _HPIPM_SUCCESS:
                if not _within_boxes(problem, target):
                    notes.append(f"QP {qp_solves} failed (HPIPM flag {flag}, iterate outside the boxes)")
                    break
                notes.append(f"QP {qp_solves} stopped early (HPIPM flag {flag}); its iterate was used")
            lam = qp.lam_g[end_rows]
            multipliers = np.maximum(np.nan_to_num(lam, nan=0.0, posinf=0.0, neginf=0.0), 0.0)
            no_worse = best is None or target.merit <= best.merit + _MERIT_SLACK * (1 + abs(best.merit))
            if no_worse and self._model_error(problem, e, d, target, exact_end) <= self._tolerance:
                best, converged = target, flag == _HPIPM_SUCCESS
                break
            candidate = target if best is None else self._line_search(problem, best, target)
            if candidate is best:
                notes.append("the line search found no decrease")
                break
            best, s_bar = candidate, candidate.s
            # linearise v_end next at the boundary point below an over-shooting v_N
            v_end = min(float(candidate.v[-1]), end_speed_limit(problem, problem.s0 + float(candidate.s[-1])))
        return _Run(best, converged, qp_solves, ipm_iterations, notes)

    @staticmethod
    def _set_bounds(problem: SpeedProblem, qp: _QP) -> None:
        """Sets ``lbx, ubx`` (in stage order) and ``lbg, ubg`` of ``qp``, but the limit rows' ``ubg``."""
        n = problem.steps
        tables = problem._tables
        a_lo, a_hi, v_lo = tables.a_lo, tables.a_hi, tables.v_lo
        width = qp.width
        lower = qp.lbx[: width * n].reshape(n, width).T  # (width, n) views of the stages 0 … N−1
        upper = qp.ubx[: width * n].reshape(n, width).T
        lower[0], upper[0] = -np.inf, np.inf  # s − s0
        lower[1], upper[1] = v_lo[:n], np.inf
        lower[2], upper[2] = a_lo[:n], a_hi[:n]
        lower[:3, 0] = upper[:3, 0] = (0.0, problem.v0, problem.a0)
        lower[3], upper[3] = -problem.jerk_max, problem.jerk_max
        lower[4:], upper[4:] = 0.0, np.inf
        qp.lbx[width * n :] = (-np.inf, v_lo[n], a_lo[n])
        qp.ubx[width * n :] = (np.inf, np.inf, a_hi[n])
        # rows × N: dynamics (= 0), half-step speed (≥ v_lo), limit and position (≤), lower position (≥)
        lbg = qp.lbg.reshape(n, qp.rows).T
        ubg = qp.ubg.reshape(n, qp.rows).T
        lbg[:3], ubg[:3] = 0.0, 0.0
        lbg[3], ubg[3] = tables.v_lo_half, np.inf
        lbg[4:] = -np.inf
        ubg[_ROWS - 1] = tables.s_bound[1:] - problem.s0  # may be +inf
        if qp.rows > _ROWS:
            lbg[_ROWS] = tables.lower[1:] - problem.s0  # may be −inf
            ubg[_ROWS] = np.inf

    @staticmethod
    def _model_error(
        problem: SpeedProblem, e: FloatArray, d: FloatArray, target: _Iterate, exact_end: bool
    ) -> float:
        """How far the QP's model of the limit was off at ``target``, where the speed is near the limit.

        Knot N, a braking margin rather than a limit, gets ``_END_TOLERANCE_FACTOR`` times the tolerance, and
        where a chord (conservative below ``_NEWTON_MIN_SPEED``) stood in for its tangent only an
        over-estimate counts.
        """
        model = np.min(e + d * target.s[1:], axis=0)
        true = _true_limit(problem, target.s)
        near = target.v[1:] >= np.minimum(model, true) - _ACTIVE_BAND
        error = np.abs(true - model)
        if not exact_end:
            error[-1] = max(model[-1] - true[-1], 0.0)
        error[-1] /= _END_TOLERANCE_FACTOR
        return float(np.max(error[near], initial=0.0))

    @staticmethod
    def _line_search(problem: SpeedProblem, current: _Iterate, target: _Iterate) -> _Iterate:
        """The longest of ``_STEP_LENGTHS`` towards ``target`` that lowers the merit; ``current`` if none."""
        for alpha in _STEP_LENGTHS:
            if alpha == 1.0:
                trial = target
            else:
                trial = _iterate(problem, current.jerk + alpha * (target.jerk - current.jerk))
            if trial.merit < current.merit:
                return trial
        return current


_thread_local = threading.local()


def solve_speed(
    problem: SpeedProblem, *, warm_start: SpeedResult | None = None, shift: int = 1
) -> SpeedResult:
    """Solve ``problem`` with a :class:`SpeedSolver` kept per thread (so built QPs are reused)."""
    solver = getattr(_thread_local, "solver", None)
    if solver is None:
        solver = _thread_local.solver = SpeedSolver()
    result: SpeedResult = solver.solve(problem, warm_start=warm_start, shift=shift)
    return result
