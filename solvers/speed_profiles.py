r"""Analytic speed profiles along a path: a full stop, keeping the speed, and driving at a speed within
the path's limit, within the jerk limit.

Each returns the jerks ``j_k`` [m/s³], ``k = 0 … N−1``, of a :class:`~solvers.speed_problem.SpeedProblem`'s
grid from its initial state ``(v0, a0)``; :func:`~solvers.speed_problem.integrate_jerk` turns them into
``(s, v, a)``. :func:`braking_profile` and :func:`cruise_profile` honour only the hard constraints
(``|j| ≤ j_max``, the acceleration box, the speed floor ``v_lo``) and ignore the soft ones (limit,
``s_stop``, ``s_upper``, ``s_lower``); :func:`limited_profile` also keeps the limit ``v_lim`` wherever full
braking could. The SQP returns :func:`braking_profile` when it has no solution (and restarts from it after
a violation it did not need); the planner uses all three as fallbacks.

The release of an acceleration ``a`` (the fastest return to 0) takes ``⌊|a|/(j_max Δt)⌋`` full-jerk steps
and one partial step, and changes the speed by::

    Δv = n a Δt − sign(a) j_max Δt² n²/2 + r Δt/2,      n full steps, r = a − sign(a) j_max Δt n
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from solvers.speed_problem import FloatArray, SpeedProblem, integrate_jerk, steer_jerk

__all__ = ["braking_profile", "cruise_profile", "limited_profile"]

#: a speed this far above the limit [m/s] still counts as within it (rounding)
_LIMIT_TOL = 1e-6
#: the most steps a braking check simulates (a stop from the largest speeds within any sane limits)
_MAX_BRAKING_STEPS = 100_000


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
    """Speed left when ``a`` returns to 0 as fast as possible from ``(v, a)`` [m/s] (:func:`_release`'s
    change of speed, without its list of jerks: the bisection of the landing asks 60 times a step)."""
    if a == 0.0:
        return v + 0.0
    direction = -math.copysign(1.0, a)
    full = math.floor(abs(a) / (jmax * dt) + 1e-12)
    rest = a + direction * jmax * dt * full
    return v + (full * a * dt + direction * jmax * dt**2 * full**2 / 2 + rest * dt / 2)


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
    steps = _braking_steps(problem.v0, problem.a0, problem.steps, problem.dt, problem.jerk_max, problem.a_min)
    return np.fromiter(steps, dtype=np.float64, count=problem.steps)


def _braking_steps(v: float, a: float, n: int, dt: float, jmax: float, a_min: float) -> Iterator[float]:
    """The jerks of :func:`braking_profile` from ``(v, a)`` on a grid of ``n`` steps of ``dt`` [s], one at a
    time (then zeros): a caller that follows only the first few steps computes only those."""
    done = 0

    def after(v: float, a: float, j: float) -> tuple[float, float]:
        return v + a * dt + j * dt**2 / 2, a + j * dt

    while done < n and not (abs(v) <= 1e-12 and abs(a) <= 1e-12):
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
        for j in steps[: n - done]:
            done += 1
            yield sign * j
            v, a = after(v, a, sign * j)
        if len(steps) > 1:  # landed, up to rounding
            v = a = 0.0
    yield from itertools.repeat(0.0, n - done)


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


def _step_count(steps: float) -> int:
    """``⌈steps⌉`` (at least 0), or :data:`_MAX_BRAKING_STEPS` where that is more, infinite or NaN (an
    extreme vehicle's ramp or stop: the braking is cut there anyway)."""
    if not steps < _MAX_BRAKING_STEPS:
        return _MAX_BRAKING_STEPS
    return max(0, math.ceil(steps))


def _brakes_within(problem: SpeedProblem, s: float, v: float, a: float) -> bool:
    """Whether full braking from ``(s, v, a)`` (``a → a_min`` at ``jerk_max``, then ``a_min`` to a stop, on
    the problem's grid) keeps ``v ≤ v_lim(s)`` at every knot until it stops."""
    dt, jmax, a_min = problem.dt, problem.jerk_max, problem.a_min
    ramp = _step_count((a - a_min) / (jmax * dt) - 1e-9)
    fastest = v + max(a, 0.0) * ramp * dt
    steps = min(ramp + _step_count(max(fastest, 0.0) / (-a_min * dt)) + 2, _MAX_BRAKING_STEPS)
    accel = np.maximum(a - jmax * dt * np.arange(steps + 1), a_min)
    s_k, v_k, _ = integrate_jerk(dt, s, v, a, np.diff(accel) / dt)
    moving = v_k > 0.0
    limit = np.interp(s_k[moving], problem.limit_s, problem.limit_v)
    return bool(np.all(v_k[moving] <= limit + _LIMIT_TOL))


@dataclass(frozen=True)
class _Envelope:
    """A quick sufficient test for :func:`_brakes_within`, in two look-ups.

    Full braking from ``(s, v, a)`` is no faster than ``v̂ = v + a₊ T`` while its ramp lasts (``T = (a −
    a_min)/j_max`` plus a step) and covers at most ``r = s + v̂ T`` meanwhile; after it ``v(s′)² ≤ v̂² −
    2b(s′ − r)`` (``b = −a_min``). So it keeps ``v_lim`` if ``v̂`` is at most the limit's least over
    ``[s, r]`` and ``v̂² + 2b r`` at most ``v_lim(s′)² + 2b s′`` for every ``s′ ≥ r``: on each segment of
    the limit at least ``min(v_i, v_i+1)² + 2b s_i`` (``energy``, its suffix minima; beyond the last knot
    ``v_M² + 2b s_M``)."""

    problem: SpeedProblem
    energy: tuple[float, ...]
    #: the limit's knots as Python floats (scalar look-ups without numpy's per-call cost)
    knots_s: tuple[float, ...]
    knots_v: tuple[float, ...]

    @classmethod
    def of(cls, problem: SpeedProblem) -> _Envelope:
        s, v, b = problem.limit_s, problem.limit_v, -problem.a_min
        lowest = np.minimum(v, np.append(v[1:], v[-1]))
        energy = np.minimum.accumulate((lowest**2 + 2.0 * b * s)[::-1])[::-1]
        return cls(problem, tuple(energy.tolist()), tuple(s.tolist()), tuple(v.tolist()))

    def keeps(self, s: float, v: float, a: float) -> bool:
        """Whether full braking from ``(s, v, a)`` surely keeps the limit (False: perhaps not)."""
        p = self.problem
        ramp = max(a - p.a_min, 0.0) / p.jerk_max + p.dt
        peak = v + max(a, 0.0) * ramp
        reach = s + max(peak, 0.0) * ramp
        knots_v = self.knots_v
        lo, hi = bisect.bisect_right(self.knots_s, s), bisect.bisect_right(self.knots_s, reach)
        end_s, end_reach = np.interp((s, reach), p.limit_s, p.limit_v).tolist()
        least = min(end_s, end_reach, min(knots_v[lo:hi]) if hi > lo else math.inf)
        if peak > least + _LIMIT_TOL:
            return False
        ahead = min(end_reach, knots_v[min(hi, len(knots_v) - 1)]) ** 2 + 2.0 * -p.a_min * reach
        beyond = self.energy[hi] if hi < len(self.energy) else math.inf
        return peak**2 + 2.0 * -p.a_min * reach <= min(ahead, beyond) + _LIMIT_TOL


def limited_profile(problem: SpeedProblem, v_keep: float) -> FloatArray:
    """Jerks that drive at ``v_keep`` [m/s] within the path's limit ``v_lim`` (``limit_s``, ``limit_v``).

    Each step takes the jerk that steers towards ``v_keep`` (:func:`~solvers.speed_problem.steer_jerk`)
    when full braking from the state after it still keeps ``v ≤ v_lim`` everywhere ahead until it stops
    (:func:`_brakes_within`, after the quick sufficient test of :class:`_Envelope`);
    otherwise the next step of full braking (:func:`braking_profile`) from the state before it, whose own
    braking was checked the step before. So the limit is kept at the knots wherever full braking from the
    initial state keeps it, and the profile slows before a dip in the limit only as late as it must and
    speeds up again after it: time-optimal where the limit binds, at the price of an acceleration that
    swings between speeding up and braking fully while ``v_keep`` lies above the limit (a caller that wants
    to drive at the limit passes a ``v_keep`` within it). From an initial state whose braking cannot keep
    the limit it brakes fully until it can (best effort). Every step keeps ``|j| ≤ j_max``, the
    acceleration box and the speed floor (a step towards ``v_keep`` is taken only if releasing the
    acceleration after it cannot end below standstill); ``s_stop``, ``s_upper`` and ``s_lower`` are
    ignored.
    """
    dt, n, jmax = problem.dt, problem.steps, problem.jerk_max
    a_lo, a_hi = problem.a_min, problem.a_max
    jerk = np.zeros(n)
    s, v, a = problem.s0, problem.v0, problem.a0
    brake: Iterator[float] | None = None  # the rest of the full stop being followed, if any
    envelope = _Envelope.of(problem)

    def after(s: float, v: float, a: float, j: float) -> tuple[float, float, float]:
        return s + v * dt + a * dt**2 / 2 + j * dt**3 / 6, v + a * dt + j * dt**2 / 2, a + j * dt

    for k in range(n):
        j = steer_jerk(v, a, v_keep, dt, jmax, min(a_lo, a), max(a_hi, a))
        nxt = after(s, v, a, j)
        releasable = nxt[1] >= 0.0 and _spare_speed(nxt[1], nxt[2], dt, jmax) >= 0.0
        if releasable and (envelope.keeps(*nxt) or _brakes_within(problem, *nxt)):
            brake = None
        else:
            if brake is None:  # the full stop from here (its first steps only are taken)
                brake = _braking_steps(max(v, 0.0), a, n - k, dt, jmax, a_lo)
            j = next(brake)
            nxt = after(s, v, a, j)
        jerk[k] = j
        s, v, a = nxt
    return jerk
