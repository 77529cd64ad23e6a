r"""The speed-profile problem along a fixed path: a jerk-controlled optimal control problem.

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
``a_rec,k = min(a0 + j_max t_k, 0)``, then (if that ends below 0) under the fastest push back to
standstill. With these bounds the hard constraints always have a solution (that profile), so every QP is
feasible. The half-step row keeps a stopped vehicle stopped: with ``v ≥ 0`` at the knots only, an
alternating ``a = ±ε`` would let it creep backwards between them.

The soft constraints (the path's speed limit, its end form ``v_end``, the position bounds) and the cost
``J`` are in :mod:`solvers.speed_cost`; :class:`solvers.speed_sqp.SpeedSolver` solves the problem by SQP
over the QPs of :mod:`solvers.speed_qp`; :mod:`solvers.speed_profiles` has the analytic full stop and
cruise.

What does not depend on the profile — the limit's segments and the local model's pieces per segment, the
candidates of ``v_end``'s minimum as suffix minima sorted by ``s′``, the boxes — is computed once per
problem (:attr:`SpeedProblem.tables`, on first use, kept on it), so each evaluation during the SQP is a
lookup. Where the tables serve the QP they measure ``s`` from ``s0``, so that the QP's numbers stay small
wherever the path frame starts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from solvers.result import SolveInfo
from solvers.validation import check_weights, float_array, integer, scalar

FloatArray = NDArray[np.float64]

__all__ = [
    "MAX_STEPS",
    "PIECES",
    "QUADRATIC_SHARE",
    "SpeedProblem",
    "SpeedResult",
    "SpeedTables",
    "SpeedWeights",
    "integrate_jerk",
    "steer_jerk",
]

#: a speed [m/s] and acceleration [m/s²] this close to 0 are a standstill (rounding)
_LANDED = 1e-9
#: largest horizon accepted [steps]
MAX_STEPS = 1000
#: affine pieces of the limit's local model per knot (tangent, piece behind, piece ahead)
PIECES = 3
#: the quadratic slack penalty, as a share of the linear one (per m/s or m)
QUADRATIC_SHARE = 0.01


@dataclass(frozen=True)
class SpeedWeights:
    """Cost weights (``J`` of :mod:`solvers.speed_cost`); finite, ``acceleration ≥ 0``, the others ``> 0``.

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

    A goal's bounds are aims; the planner imposes each at one knot. ``goal_late_violation`` (on
    ``goal_lower``: not late) is a tenth of ``position_violation`` and of ``speed_violation``: a stop, an
    obstacle ahead and the limit win a conflict, at one knot, and a follower's ``s_lower`` never conflicts
    with it. ``goal_early_violation`` (on ``goal_upper``: not early) is half of ``follower_violation``: a
    vehicle from behind wins. Both are exact where the goal asks for a speed within about ``ρ/2`` m/s of
    ``v_target`` (a metre more or less costs about ``2·|v − v_target|``, spread over the horizon); beyond, the
    profile misses the goal by what is worth more than that to the running cost.

    Attributes:
        speed: on ``Δt (v_k − v_target)²``.
        acceleration: on ``Δt a_k²``.
        jerk: on ``Δt j_k²``.
        speed_violation: ρ_v, on ``σᵛ_k + σᵛ_k²/100`` (``σᵛ`` in m/s).
        position_violation: ρ_s, on ``σˢ_k + σˢ_k²/100`` (``σˢ`` in m).
        follower_violation: ρ_l, on ``σˡ_k + σˡ_k²/100`` (``σˡ`` in m); below ``position_violation`` for the
            upper bound to win a conflict.
        goal_late_violation: ρ_g⁻, on ``σᵍ⁻_k + σᵍ⁻_k²/100`` (``σᵍ⁻`` in m, short of ``goal_lower``); below
            ``position_violation``.
        goal_early_violation: ρ_g⁺, on ``σᵍ⁺_k + σᵍ⁺_k²/100`` (``σᵍ⁺`` in m, past ``goal_upper``); below
            ``follower_violation``.
    """

    speed: float = 1.0
    acceleration: float = 2.0
    jerk: float = 0.5
    speed_violation: float = 1e4
    position_violation: float = 1e4
    follower_violation: float = 1e2
    goal_late_violation: float = 1e3
    goal_early_violation: float = 50.0

    def __post_init__(self) -> None:
        check_weights(self, zero_allowed=("acceleration",))


@dataclass(frozen=True, kw_only=True, eq=False)
class SpeedProblem:
    """One speed-profile request, validated on construction (``ValueError`` on misuse).

    Arrays are copied to read-only float64. Bounds and limits that cannot be met are not misuse: they are
    soft (see :mod:`solvers.speed_cost`) and the violation is reported.

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
        goal_lower, goal_upper: optional ``goal_lower[k] ≤ s(t_k) ≤ goal_upper[k]`` [m], shape (N + 1,)
            each, ``−inf`` / ``+inf`` where free, no NaN (entry 0 is not imposed), ``goal_lower ≤
            goal_upper``: where a goal wants the vehicle by then (not late, not early); softer than
            the others (``weights.goal_late_violation``, ``weights.goal_early_violation``).
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
    goal_lower: FloatArray | None = None
    goal_upper: FloatArray | None = None
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
        if self.goal_lower is not None:
            put("goal_lower", float_array("goal_lower", self.goal_lower, size=knots, allow_neginf=True))
        if self.goal_upper is not None:
            put("goal_upper", float_array("goal_upper", self.goal_upper, size=knots, allow_posinf=True))
        if self.goal_lower is not None and self.goal_upper is not None:
            crossed = np.flatnonzero(self.goal_lower[1:] > self.goal_upper[1:])
            if crossed.size:
                k = int(crossed[0]) + 1
                raise ValueError(f"goal_lower: above goal_upper at knot {k} ({self.goal_lower[k]})")
        if not isinstance(self.weights, SpeedWeights):
            raise ValueError(f"weights: expected SpeedWeights, got {type(self.weights).__name__}")

    @property
    def t(self) -> FloatArray:
        """Knot times ``t_k = k·Δt`` [s], shape (N + 1,)."""
        return np.arange(self.steps + 1, dtype=np.float64) * self.dt

    @cached_property
    def tables(self) -> SpeedTables:
        """What the solver looks up again and again, computed on first use (the problem is immutable)."""
        return SpeedTables.of(self)

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
        of the brake, ``a_k = min(a0 + j_max t_k, 0)``, and then, if that ends below 0, under the fastest
        push back to standstill within the jerk limit and the acceleration box (:func:`steer_jerk`). That
        is feasible, so the bound is safe; on the grid it is not always tight (a release overshooting to
        ``a > 0`` for one step can lose up to ``|a0|·Δt/2`` less speed). Without the push back the floor
        kept the lowest speed: a vehicle that stopped braking hard could drift backwards to the horizon.
        """
        if self.a0 >= 0:
            return np.zeros(self.steps + 1), np.zeros(self.steps)
        dt, jmax = self.dt, self.jerk_max
        jerk = np.diff(np.minimum(self.a0 + jmax * self.t, 0.0)) / dt
        _, v, a = integrate_jerk(dt, 0.0, self.v0, self.a0, jerk)
        released = int(np.argmax(a >= 0.0)) if a[-1] >= 0.0 else self.steps
        if v[released] < 0.0 and self.a_max > 0.0:  # back to v = 0: a few steps, looped only here
            a_lo, a_hi = self.accel_bounds()
            vk, ak = float(v[released]), float(a[released])
            for k in range(released, self.steps):
                if abs(vk) <= _LANDED and abs(ak) <= _LANDED:  # standing (the jerks after are 0)
                    break
                jerk[k] = steer_jerk(vk, ak, 0.0, dt, jmax, float(a_lo[k + 1]), float(a_hi[k + 1]))
                vk, ak = vk + ak * dt + jerk[k] * dt**2 / 2, ak + jerk[k] * dt
            _, v, a = integrate_jerk(dt, 0.0, self.v0, self.a0, jerk)
        half = v[:-1] + a[:-1] * dt / 2 + jerk * dt**2 / 8
        return np.minimum(v, 0.0), np.minimum(half, 0.0)


@dataclass(frozen=True, eq=False)
class SpeedResult:
    """A speed profile: knots ``t, s, v, a`` (shape (N + 1,)) and the jerks ``jerk`` (shape (N,)).

    Never contains NaN, and always meets the dynamics (it is integrated from ``jerk``). When
    ``info.usable`` is false the profile is :func:`~solvers.speed_profiles.braking_profile`: full braking
    within the jerk limit, ignoring every other constraint — a safe fallback, not a solution.

    Attributes:
        info: status (:mod:`solvers.speed_sqp`); iterations (interior-point iterations summed over the QPs);
            times; objective ``J`` with the true violations as slacks (``None`` when not usable);
            ``max_violation`` as the field below; message; extras (:class:`solvers.speed_sqp.SpeedSolver`).
        t, s, v, a: time [s], arc length [m], speed [m/s], acceleration [m/s²] at the knots.
        jerk: jerk on each step [m/s³].
        speed_violation: largest ``max(v_k − v_lim(s_k), −v_k)`` over ``k ≥ 1``, or 0 [m/s].
        position_violation: largest ``s_k − min(s_stop, s_upper,k)`` over ``k ≥ 1``, or 0 [m].
        max_violation: the largest of the three violations (each in its own unit): the slack the profile
            needed.
        qp_solves: QPs solved (SQP iterations).
        follower_violation: largest ``s_lower,k − s_k`` over ``k ≥ 1``, or 0 [m].
        goal_violation: largest ``max(goal_lower,k − s_k, s_k − goal_upper,k)`` over ``k ≥ 1``, or 0 [m] (an
            aim missed, not a constraint broken: not part of ``max_violation``).
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
    goal_violation: float = 0.0


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


def steer_jerk(v: float, a: float, v_keep: float, dt: float, jmax: float, a_lo: float, a_hi: float) -> float:
    """The jerk of one step that brings the speed ``v`` towards ``v_keep`` [m/s] as fast as ``|j| ≤ jmax``
    and ``a_lo ≤ a ≤ a_hi`` allow without overshooting it on the grid.

    The acceleration ``u`` after the step is the one whose fastest release on the grid
    (:mod:`solvers.speed_profiles`' ``Δv``: ``n`` full-jerk steps and a partial one) ends at ``v_keep``:
    ``v + (a + u)Δt/2 + Δv(u) = v_keep``. With ``e = v_keep − v − aΔt/2`` and ``q = j_max Δt²``, for
    ``|u| ∈ [n j_max Δt, (n + 1) j_max Δt]`` that is ``|u|Δt(n + 1) − q n(n + 1)/2 = |e|``, linear in ``u``:
    ``n`` is the largest with ``q n(n + 1)/2 ≤ |e|`` and ``u`` takes the sign of ``e``; then
    ``j = (u − a)/Δt`` within the limits. At ``v = v_keep, a = 0`` it is 0: the speed is kept. (The
    continuous release ``u|u|/(2 j_max)`` undershoots the grid's by up to ``j_max Δt²/8``: steering by it
    overshoots ``v_keep`` and then swings about it.)
    """
    e = v_keep - v - 0.5 * a * dt
    q = jmax * dt * dt
    ratio = 8.0 * abs(e) / q if q > 0.0 else 0.0
    if math.isfinite(ratio):
        n = math.floor((math.sqrt(1.0 + ratio) - 1.0) / 2.0)
        u = math.copysign((abs(e) + q * n * (n + 1) / 2.0) / (dt * (n + 1)), e)
    else:  # a gap no release on the grid spans (an extreme v_keep): as far as the limits allow
        u = math.copysign(math.inf, e)
    u = min(max(u, a_lo), a_hi)
    return min(max((u - a) / dt, -jmax), jmax)


@dataclass(frozen=True, eq=False)
class SpeedTables:
    """A problem's numbers that do not depend on the profile, computed once (read-only arrays).

    Attributes:
        slopes: ``slopes[i]`` is the slope of ``v_lim`` [1/s] where ``searchsorted(limit_s, s, "right")``
            is ``i``: 0 before and beyond the ends, else that of the segment holding ``s``; shape (M + 1,).
        rel_s: ``limit_s − s0`` [m] (the QP's frame).
        piece_e, piece_d: the pieces of :func:`solvers.speed_qp.local_model` for ``s`` (relative to s0) with
            ``searchsorted(rel_s, s, "right")`` equal to the column: ``v ≤ e + d·s`` of the segment holding
            ``s`` (row 0), of the one behind and of the one ahead where the kink between is concave (rows 1
            and 2; ``e = +inf``, ``d = 0`` where not); shape ``(PIECES, M + 1)``.
        b, c, rate, bound: as in :class:`solvers.speed_cost.EndTerms` (``rate`` and ``bound`` ``None``
            without a moving bound).
        end_s: the points ``s′ < s_stop`` where the minimum of ``v_end`` can lie other than ``s′ = s``
            (breakpoints, ``s_stop`` when finite, stationary points on falling segments), sorted [m].
        end_min: ``end_min[i]`` is the least energy ``(v*(s′) + c)² + 2b s′`` over ``end_s[i:]``, ``+inf`` at
            the end [m²/s²]; so the minimum over ``s′ > s`` is ``end_min[searchsorted(end_s, s, "right")]``.
        s_bound: :meth:`SpeedProblem.s_bound`; ``bound_finite``: where it is finite; ``bound_or_zero``: it,
            0 where infinite.
        lower: ``s_lower`` with entry 0 (not imposed) and a missing bound as ``−inf`` [m]; ``lower_finite``:
            where it is finite; ``lower_or_zero``: it, 0 where infinite; ``has_lower``: whether it is finite
            anywhere (the problem needs the QP with the ``σˡ`` slack).
        goal_lo, goal_hi: ``goal_lower`` and ``goal_upper`` with entry 0 (not imposed) and a missing bound as
            ``∓inf`` [m]; ``has_goal``: whether either is finite anywhere (the problem needs the QP with the
            ``σᵍ`` slack).
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
    goal_lo: FloatArray
    goal_hi: FloatArray
    has_goal: bool
    a_lo: FloatArray
    a_hi: FloatArray
    v_lo: FloatArray
    v_lo_half: FloatArray

    @staticmethod
    def of(problem: SpeedProblem) -> SpeedTables:
        xs, ys = problem.limit_s, problem.limit_v
        rel_s = xs - problem.s0
        edge = np.zeros(1)
        slopes = np.concatenate([edge, np.diff(ys) / np.diff(xs), edge])
        # segments −1 (before xs[0]) … M−1 (after xs[−1]) in columns 0 … M: lines v = e + d·s through their
        # left end (the first point for segment −1)
        piece_d = np.zeros((PIECES, xs.size + 1))
        piece_e = np.full((PIECES, xs.size + 1), np.inf)
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
        goal_lo = np.full(problem.steps + 1, -math.inf)
        goal_hi = np.full(problem.steps + 1, math.inf)
        if problem.goal_lower is not None:
            goal_lo[1:] = problem.goal_lower[1:]
        if problem.goal_upper is not None:
            goal_hi[1:] = problem.goal_upper[1:]
        a_lo, a_hi = problem.accel_bounds()
        v_lo, v_lo_half = problem.speed_floor()
        tables = SpeedTables(
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
            goal_lo=goal_lo,
            goal_hi=goal_hi,
            has_goal=bool(np.isfinite(goal_lo).any() or np.isfinite(goal_hi).any()),
            a_lo=a_lo,
            a_hi=a_hi,
            v_lo=v_lo,
            v_lo_half=v_lo_half,
        )
        for value in vars(tables).values():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
        return tables
