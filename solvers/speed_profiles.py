r"""Analytic speed profiles along a path: a full stop and keeping the speed, within the jerk limit.

Both return the jerks ``j_k`` [m/s³], ``k = 0 … N−1``, of a :class:`~solvers.speed_problem.SpeedProblem`'s
grid from its initial state ``(v0, a0)``; :func:`~solvers.speed_problem.integrate_jerk` turns them into
``(s, v, a)``. They honour only the hard constraints (``|j| ≤ j_max``, the acceleration box, the speed
floor ``v_lo``) and ignore the soft ones (limit, ``s_stop``, ``s_upper``, ``s_lower``). The SQP returns
:func:`braking_profile` when it has no solution (and restarts from it after a violation it did not
need); the planner uses both as fallbacks.

The release of an acceleration ``a`` (the fastest return to 0) takes ``⌊|a|/(j_max Δt)⌋`` full-jerk steps
and one partial step, and changes the speed by::

    Δv = n a Δt − sign(a) j_max Δt² n²/2 + r Δt/2,      n full steps, r = a − sign(a) j_max Δt n
"""

from __future__ import annotations

import math

import numpy as np

from solvers.speed_problem import FloatArray, SpeedProblem

__all__ = ["braking_profile", "cruise_profile"]


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
