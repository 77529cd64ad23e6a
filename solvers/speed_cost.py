r"""The cost of a speed profile: ``J`` with the soft constraints, the limit ``v_lim`` and its end form
``v_end``, and the violations (the problem, its grid and its hard constraints: :mod:`solvers.speed_problem`).

Soft constraints, ``k = 1 … N``, with slacks ``σᵛ_k ≥ 0`` [m/s], ``σˢ_k ≥ 0`` [m], ``σˡ_k ≥ 0`` [m] and
``σᵍ⁻_k, σᵍ⁺_k ≥ 0`` [m]::

    v_k ≤ v_lim(s_k) + σᵛ_k      (k < N)        path speed limit
    v_N ≤ v_end(s_N) + σᵛ_N                      … at the horizon's end, with room to brake beyond it
    s_k ≤ s_bound,k + σˢ_k,      s_bound,k = min(s_stop, s_upper,k)
    s_k ≥ s_lower,k − σˡ_k                       (only where s_lower,k is finite)
    goal_lower,k − σᵍ⁻_k ≤ s_k ≤ goal_upper,k + σᵍ⁺_k   (only where finite)

``v_lim`` is the piecewise-linear interpolant of ``(limit_s, limit_v)``, constant beyond both ends (the caller
computes it as ``min(max_speed, target, √(a_lat,max/|κ(s)|))``); ``s_upper`` is optional (``+∞`` where free),
and so is ``s_lower`` (``−∞`` where free): a lower space-time bound, such as staying ahead of a vehicle that
comes from behind; and so are a goal's bounds ``goal_lower``, ``goal_upper`` (where to be by when: not late,
not early).
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
      + Σ_{k=1}^{N} [ρ_v (σᵛ_k + σᵛ_k²/100) + ρ_s (σˢ_k + σˢ_k²/100) + ρ_l (σˡ_k + σˡ_k²/100)
                     + ρ_g⁻ (σᵍ⁻_k + σᵍ⁻_k²/100) + ρ_g⁺ (σᵍ⁺_k + σᵍ⁺_k²/100)]

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

A goal's bounds give way to the others by the same argument, each imposed at one knot: ``ρ_g⁻ < ρ_s`` and
``ρ_g⁻ Δt < ρ_v`` (a stop, a leader, the limit), ``ρ_g⁺ < ρ_l`` (a vehicle from behind); ``goal_lower`` and
``s_lower`` never conflict.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from solvers.speed_problem import QUADRATIC_SHARE, FloatArray, SpeedProblem

__all__ = [
    "EndTerms",
    "end_speed_limit",
    "end_terms",
    "goal_excess",
    "limit_at",
    "objective",
    "speed_limit",
    "violations",
]


def speed_limit(problem: SpeedProblem, s: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """``(v_lim(s), v_lim′(s))`` [m/s, 1/s]: the path's limit and the slope of the segment holding ``s``.

    At a breakpoint the slope is that of the segment ahead; beyond the ends the limit is constant (slope 0).
    """
    s = np.asarray(s, dtype=np.float64)
    value = np.interp(s, problem.limit_s, problem.limit_v)
    slope = problem.tables.slopes[np.searchsorted(problem.limit_s, s, side="right")]
    return value, np.asarray(slope, dtype=np.float64)


def limit_at(problem: SpeedProblem, s: float) -> tuple[float, float]:
    """:func:`speed_limit` at one point, as floats."""
    value = float(np.interp(s, problem.limit_s, problem.limit_v))
    return value, float(problem.tables.slopes[np.searchsorted(problem.limit_s, s, side="right")])


@dataclass(frozen=True)
class EndTerms:
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


def end_terms(problem: SpeedProblem, s: float) -> EndTerms:
    tables = problem.tables
    b, c, stop = tables.b, tables.c, problem.s_stop
    if s >= stop:
        return EndTerms(b, c, (0.0 + c) ** 2 + 2.0 * b * stop, tables.rate, tables.bound)
    # the least energy over s′ > s (table) against that of s′ = s; s′ = s wins a tie (then v_end = v_lim)
    ahead = float(tables.end_min[np.searchsorted(tables.end_s, s, side="right")])
    here = max(float(np.interp(s, problem.limit_s, problem.limit_v)), 0.0) + c
    energy = ahead if ahead < here * here + 2.0 * b * s else None
    return EndTerms(b, c, energy, tables.rate, tables.bound)


def end_speed_limit(problem: SpeedProblem, s: float) -> float:
    """``v_end(s)`` [m/s], the horizon-end limit of the module docstring.

    The minimum over ``s′ ≥ s`` is exact: over ``s′ = s``, the breakpoints ahead, ``s_stop`` and, on each
    falling segment, the point where ``(v + c)² + 2b s′`` is stationary.
    """
    s = float(s)
    terms = end_terms(problem, s)
    b, c = terms.b, terms.c
    if terms.energy is None:
        value = float(np.interp(s, problem.limit_s, problem.limit_v))
    else:
        value = math.sqrt(max(terms.energy - 2.0 * b * s, 0.0)) - c
    if terms.rate is not None and terms.bound is not None:
        value = min(value, terms.rate + math.sqrt(c * c + 2.0 * b * max(terms.bound - s, 0.0)) - c)
    return max(value, 0.0)


def violations(
    problem: SpeedProblem, s: FloatArray, v: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per-knot violations ``(e_v, e_s, e_l)`` of ``v_lim``/``v ≥ 0``, ``s_bound`` and ``s_lower`` (0 at
    knot 0)."""
    limit = np.interp(s, problem.limit_s, problem.limit_v)
    e_v = np.maximum(np.maximum(v - limit, -v), 0.0)
    e_v[0] = 0.0
    return e_v, _position_excess(problem, s), _follower_excess(problem, s)


def _position_excess(problem: SpeedProblem, s: FloatArray) -> FloatArray:
    """Per-knot violations of ``s_bound`` [m] (0 at knot 0)."""
    tables = problem.tables
    e_s = np.where(tables.bound_finite, np.maximum(s - tables.bound_or_zero, 0.0), 0.0)
    e_s[0] = 0.0
    return e_s


def _follower_excess(problem: SpeedProblem, s: FloatArray) -> FloatArray:
    """Per-knot violations of ``s_lower`` [m] (0 at knot 0 and where it is ``−inf``)."""
    tables = problem.tables
    if not tables.has_lower:
        return np.zeros_like(s)
    return np.where(tables.lower_finite, np.maximum(tables.lower_or_zero - s, 0.0), 0.0)


def goal_excess(problem: SpeedProblem, s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Per-knot violations ``(late, early)`` of ``goal_lower`` and ``goal_upper`` [m] (0 at knot 0 and where
    free)."""
    tables = problem.tables
    if not tables.has_goal:
        return np.zeros_like(s), np.zeros_like(s)
    return np.maximum(tables.goal_lo - s, 0.0), np.maximum(s - tables.goal_hi, 0.0)


def objective(problem: SpeedProblem, s: FloatArray, v: FloatArray, a: FloatArray, jerk: ArrayLike) -> float:
    """``J`` of the module docstring for a profile, with its true violations as the slacks."""
    w, dt = problem.weights, problem.dt
    jerk = np.asarray(jerk, dtype=np.float64)
    s = np.asarray(s, dtype=np.float64)
    limit = np.interp(s[1:], problem.limit_s, problem.limit_v)
    limit[-1] = end_speed_limit(problem, float(s[-1]))
    e_v = np.maximum(v[1:] - limit, 0.0)
    e_s = _position_excess(problem, s)
    e_l = _follower_excess(problem, s)
    running = dt * (
        w.speed * np.sum((v[1:] - problem.v_target) ** 2)
        + w.acceleration * np.sum(a[1:] ** 2)
        + w.jerk * np.sum(jerk**2)
    )
    penalty = (
        w.speed_violation * np.sum(e_v + QUADRATIC_SHARE * e_v**2)
        + w.position_violation * np.sum(e_s + QUADRATIC_SHARE * e_s**2)
        + w.follower_violation * np.sum(e_l + QUADRATIC_SHARE * e_l**2)
    )
    if problem.tables.has_goal:
        late, early = goal_excess(problem, s)
        penalty += w.goal_late_violation * np.sum(late + QUADRATIC_SHARE * late**2)
        penalty += w.goal_early_violation * np.sum(early + QUADRATIC_SHARE * early**2)
    return float(running + penalty)
