r"""The QP of one SQP iteration of :class:`solvers.speed_sqp.SpeedSolver`, built with CasADi, solved by HPIPM.

The only nonlinearity of the problem is the speed limit. Iteration ``i`` replaces it, around the current
profile ``s̄``, by a local model that is a minimum of affine pieces (so the QP stays convex)::

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

(``v_lim``, ``v_end``, ``b``, ``c``, ``u`` and the cost ``J`` are those of :mod:`solvers.speed_cost`.)
The QP minimises ``J`` with the slacks as variables and this model in place of the limit rows, subject
to the dynamics and boxes of :mod:`solvers.speed_problem`. Its variables, in stage order
``z = [x_0, u_0, x_1, u_1, …, x_N]``, are ``x_k = (s_k − s0, v_k, a_k)`` and
``u_k = (j_k, σᵛ_{k+1}, σˢ_{k+1})`` (``COL_*``); the rows of stage ``k < N`` (``ROW_*``) are the three
dynamics rows ``f(x_k, u_k) − x_{k+1} = 0``, the half-step speed ``≥ v_lo``, then the soft rows of knot
``k + 1`` written through the dynamics (so that they belong to stage ``k``): ``v − d·s − σᵛ ≤ e`` (one per
piece, slope ``d`` a parameter) and ``s − σˢ ≤ s_bound − s0``. Parameters
``p = [v_target, end curvature, v̂_N, d_1 … d_N]`` (``P_*``); all else is bounds.

It is solved with HPIPM, a structure-exploiting (Riccati) interior-point method, through CasADi's
``qpsol``, and built once per ``(N, Δt, weights)`` with ``v_target``, the pieces' slopes and the end
curvature as CasADi parameters and everything else as bounds, so nothing about its structure changes
between requests (the limit profile may have any number of points; an unused piece gets an infinite bound).
A problem whose ``s_lower`` is finite somewhere in ``k = 1 … N`` gets a second QP of that size, with ``σˡ``
as a fourth input per stage and the row ``s_{k+1} + σˡ_{k+1} ≥ s_lower,k+1``; every other problem keeps the
smaller one (one input and one row fewer per stage). Likewise a problem with a goal's bounds gets ``σᵍ⁻`` and
``σᵍ⁺`` as the next inputs (from :attr:`SpeedQP.col_goal`) and the rows ``s_{k+1} + σᵍ⁻_{k+1} ≥
goal_lower,k+1`` and ``s_{k+1} − σᵍ⁺_{k+1} ≤ goal_upper,k+1`` (from :attr:`SpeedQP.row_goal`). The QP
reads and writes numpy arrays directly (CasADi's function buffer), with no conversion per call.
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

import casadi as ca
import numpy as np

from solvers.speed_cost import end_terms, limit_at
from solvers.speed_problem import PIECES, QUADRATIC_SHARE, FloatArray, SpeedProblem, SpeedWeights

__all__ = [
    "CASADI_LOCK",
    "HPIPM_USABLE",
    "HpipmSettings",
    "HpipmStatus",
    "SpeedQP",
    "build_speed_qp",
    "local_model",
]


class HpipmStatus(IntEnum):
    """HPIPM's return flags (``enum hpipm_status``), as CasADi reports them in ``return_status``."""

    #: found a solution satisfying the accuracy tolerance
    SUCCESS = 0
    #: maximum number of iterations reached
    MAX_ITER = 1
    #: minimum step length reached
    MIN_STEP = 2
    #: NaN in the solution
    NAN_SOL = 3
    #: inconsistent equality constraints
    INCONS_EQ = 4


#: flags whose iterate may be used if it is finite and within the boxes (never as converged but SUCCESS)
HPIPM_USABLE = frozenset({HpipmStatus.SUCCESS, HpipmStatus.MAX_ITER, HpipmStatus.MIN_STEP})

#: HPIPM replaces ±∞ bounds by ± this (relative to s0, every quantity stays far below it)
_HPIPM_INF = 1e6

#: states per stage, ``x_k = (s_k − s0, v_k, a_k)``
STATES = 3
#: columns of stage ``k``'s variables in ``z``: the state, then the inputs ``u_k`` (``σˡ`` only in the QP
#: with the lower bound)
COL_S, COL_V, COL_A, COL_JERK, COL_SIGMA_V, COL_SIGMA_S, COL_SIGMA_L = range(7)
#: rows of stage ``k``: the dynamics (``STATES`` rows in the state's order), the half-step speed, the
#: ``PIECES`` limit rows of knot ``k + 1``, its upper position row and (with the lower bound) its lower one
ROW_DYNAMICS = 0
ROW_HALF_SPEED = ROW_DYNAMICS + STATES
ROW_LIMIT = ROW_HALF_SPEED + 1
ROW_POSITION = ROW_LIMIT + PIECES
ROW_LOWER = ROW_POSITION + 1
#: parameters: ``v_target``, the end rows' curvature, ``v̂_N``, then the slopes (``PIECES`` per stage)
P_V_TARGET, P_END_CURVATURE, P_V_HAT, P_SLOPES = range(4)
#: the smallest v̂ of the horizon-end linearisation [m/s]
_NEWTON_MIN_SPEED = 1.0


@dataclass(frozen=True)
class HpipmSettings:
    """HPIPM's options, about 20 interior-point iterations per QP here.

    Attributes:
        mode: HPIPM's preset, ``"speed_abs"``: tuned for speed, absolute IPM formulation.
        mu0: the initial barrier parameter.
        iter_max: interior-point iterations per QP before ``MAX_ITER``.
        residual: the largest residual of stationarity, equality, inequality and complementarity
            (``res_g_max``, ``res_b_max``, ``res_d_max``, ``res_m_max``) accepted as ``SUCCESS``.
    """

    mode: str = "speed_abs"
    mu0: float = 1.0
    iter_max: int = 100
    residual: float = 1e-7

    def options(self) -> dict[str, Any]:
        """CasADi's ``hpipm`` options dict."""
        tolerances = dict.fromkeys(("res_g_max", "res_b_max", "res_d_max", "res_m_max"), self.residual)
        return {"mode": self.mode, "mu0": self.mu0, "iter_max": self.iter_max, **tolerances}


class SpeedQP:
    """A built QP evaluated on numpy arrays through CasADi's function buffer (no conversion per call).

    Fill ``p``, ``lbx``, ``ubx``, ``lbg`` and ``ubg`` in place (:meth:`set_bounds`, ``slopes`` and
    ``limit_rows``: views of ``p`` and ``ubg`` in the shape ``(PIECES, N)`` of :func:`local_model`), call
    :meth:`solve`, then read ``x`` (``jerk``) and ``lam_g`` (``end_multipliers``): the next call overwrites
    them. The outputs the solver does not read are not copied. The initial guesses are zero, as in a call
    without them. ``width`` is the number of variables per stage (3 states, then 3 inputs, one more with
    the lower bound's slack and two more with the goal's) and ``rows`` that of rows; ``col_goal`` and
    ``row_goal`` are the goal's first slack column and row (late, then early; None without a goal);
    ``function`` is CasADi's ``qpsol`` function.
    """

    def __init__(self, function: Any, steps: int, lower: bool = False, goal: bool = False) -> None:
        n = self.steps = steps
        self.lower, self.goal = lower, goal
        width, rows = _layout(lower, goal)
        self.width, self.rows = width, rows
        self.col_goal = width - 2 if goal else None
        self.row_goal = rows - 2 if goal else None
        self.p = np.zeros(P_SLOPES + PIECES * n)
        self.lbx = np.zeros(width * n + STATES)
        self.ubx = np.zeros(width * n + STATES)
        self.lbg = np.zeros(rows * n)
        self.ubg = np.zeros(rows * n)
        self.x = np.zeros(width * n + STATES)
        self.lam_g = np.zeros(rows * n)
        self.slopes = self.p[P_SLOPES:].reshape(n, PIECES).T
        self.limit_rows = self.ubg.reshape(n, rows).T[ROW_LIMIT : ROW_LIMIT + PIECES]
        self.jerk = self.x[COL_JERK : width * n : width]
        end_limit = rows * (n - 1) + ROW_LIMIT  # the limit rows of knot N
        self.end_multipliers = self.lam_g[end_limit : end_limit + PIECES]
        self.function = function
        zero_x, zero_g = np.zeros(width * n + STATES), np.zeros(rows * n)
        inputs = {"p": self.p, "lbx": self.lbx, "ubx": self.ubx, "lbg": self.lbg, "ubg": self.ubg}
        inputs |= {"x0": zero_x, "lam_x0": zero_x, "lam_g0": zero_g}
        self._inputs = [(function.index_in(name), array.data) for name, array in inputs.items()]
        outputs = {"x": self.x, "lam_g": self.lam_g}
        self._outputs = [(function.index_out(name), array.data) for name, array in outputs.items()]

    def set_bounds(self, problem: SpeedProblem) -> None:
        """Sets ``lbx, ubx`` (in stage order) and ``lbg, ubg`` for ``problem``, but the limit rows' ``ubg``
        (:func:`local_model`'s, per iteration)."""
        n = problem.steps
        tables = problem.tables
        a_lo, a_hi, v_lo = tables.a_lo, tables.a_hi, tables.v_lo
        width = self.width
        lower = self.lbx[: width * n].reshape(n, width).T  # (width, n) views of the stages 0 … N−1
        upper = self.ubx[: width * n].reshape(n, width).T
        lower[COL_S], upper[COL_S] = -np.inf, np.inf
        lower[COL_V], upper[COL_V] = v_lo[:n], np.inf
        lower[COL_A], upper[COL_A] = a_lo[:n], a_hi[:n]
        lower[:STATES, 0] = upper[:STATES, 0] = (0.0, problem.v0, problem.a0)
        lower[COL_JERK], upper[COL_JERK] = -problem.jerk_max, problem.jerk_max
        lower[COL_SIGMA_V:], upper[COL_SIGMA_V:] = 0.0, np.inf
        self.lbx[width * n :] = (-np.inf, v_lo[n], a_lo[n])  # x_N
        self.ubx[width * n :] = (np.inf, np.inf, a_hi[n])
        lbg = self.lbg.reshape(n, self.rows).T  # (rows, n) views
        ubg = self.ubg.reshape(n, self.rows).T
        lbg[ROW_DYNAMICS : ROW_DYNAMICS + STATES] = ubg[ROW_DYNAMICS : ROW_DYNAMICS + STATES] = 0.0
        lbg[ROW_HALF_SPEED], ubg[ROW_HALF_SPEED] = tables.v_lo_half, np.inf
        lbg[ROW_LIMIT:] = -np.inf
        ubg[ROW_POSITION] = tables.s_bound[1:] - problem.s0  # may be +inf
        if self.lower:
            lbg[ROW_LOWER] = tables.lower[1:] - problem.s0  # may be −inf
            ubg[ROW_LOWER] = np.inf
        if self.row_goal is not None:
            lbg[self.row_goal], ubg[self.row_goal] = tables.goal_lo[1:] - problem.s0, np.inf  # may be −inf
            lbg[self.row_goal + 1], ubg[self.row_goal + 1] = -np.inf, tables.goal_hi[1:] - problem.s0

    def solve(self) -> tuple[int, int]:
        """Solve the QP in the arrays: ``(HPIPM's return flag, its iterations)``; the flag is a
        :class:`HpipmStatus` value, or −1 when CasADi reports none.

        Raises:
            RuntimeError: CasADi reports a failed evaluation.
        """
        # A new buffer per call (about 30 µs): in CasADi 3.7.0 and 3.8.0 (not 3.8.2) a buffer evaluated
        # again carries state over from the last evaluation (the QP's x came out as the sum of both).
        with CASADI_LOCK:  # only the evaluation itself runs beside another thread's CasADi work
            buffer, evaluate = self.function.buffer()
            for index, data in self._inputs:
                buffer.set_arg(index, data)
            for index, data in self._outputs:
                buffer.set_res(index, data)
        self.x.fill(np.nan)  # so that an evaluation that writes nothing cannot pass for a solution
        self.lam_g.fill(np.nan)
        evaluate()
        with CASADI_LOCK:
            code = buffer.ret()
            # the buffer's own statistics (it evaluates in its own memory); CasADi 3.6 has only the
            # function's
            stats = buffer.stats() if hasattr(buffer, "stats") else self.function.stats()
            status, iterations = int(stats.get("return_status", -1)), int(stats.get("iter_count", 0))
            del buffer, evaluate, stats
        if code:
            raise RuntimeError(f"the QP's evaluation failed (CasADi code {code})")
        return status, iterations


#: CasADi evaluates a function in a buffer's own memory from several threads at once, but its symbols,
#: the making of functions and buffers and its objects' reference counts are not thread-safe (two threads
#: building QPs at once crashed the process): all of that holds this lock (re-entrant), evaluation does
#: not (HPIPM runs without the GIL, so a plan's spare thread solves beside it:
#: :mod:`planner.thread_solvers`).
CASADI_LOCK = threading.RLock()


def _new_lock_in_child() -> None:
    """A forked child starts with the lock free (a fork copies a lock held by another thread, not the
    thread that would release it)."""
    global CASADI_LOCK
    CASADI_LOCK = threading.RLock()


if hasattr(os, "register_at_fork"):  # (not on Windows, which does not fork)
    os.register_at_fork(after_in_child=_new_lock_in_child)


def _layout(lower: bool, goal: bool) -> tuple[int, int]:
    """Variables and rows per stage of the QP with or without the lower bound's and the goal's slacks."""
    width = (COL_SIGMA_L if lower else COL_SIGMA_S) + 1 + (2 if goal else 0)
    rows = (ROW_LOWER if lower else ROW_POSITION) + 1 + (2 if goal else 0)
    return width, rows


def build_speed_qp(
    steps: int,
    dt: float,
    w: SpeedWeights,
    lower: bool = False,
    settings: HpipmSettings | None = None,
    *,
    goal: bool = False,
) -> SpeedQP:
    """The CasADi/HPIPM QP of the module docstring for ``steps`` steps of ``dt`` [s] and weights ``w``;
    with ``lower``, the one with the lower position bound's slack and row; with ``goal``, the goal's slack
    and rows. Built holding :data:`CASADI_LOCK` (its symbols made and dropped inside it)."""
    with CASADI_LOCK:
        return _build(steps, dt, w, lower, settings, goal)


def _build(
    steps: int, dt: float, w: SpeedWeights, lower: bool, settings: HpipmSettings | None, goal: bool
) -> SpeedQP:
    n = steps
    width, n_rows = _layout(lower, goal)
    X = ca.SX.sym("x", STATES, n + 1)
    U = ca.SX.sym("u", width - STATES, n)
    p = ca.SX.sym("p", P_SLOPES + PIECES * n)
    v_target, curvature, v_hat = p[P_V_TARGET], p[P_END_CURVATURE], p[P_V_HAT]
    slope = ca.reshape(p[P_SLOPES:], PIECES, n)
    s, v, a = X[COL_S, :n], X[COL_V, :n], X[COL_A, :n]
    j, sig_v, sig_s = (U[col - STATES, :] for col in (COL_JERK, COL_SIGMA_V, COL_SIGMA_S))
    s1 = s + dt * v + dt**2 / 2 * a + dt**3 / 6 * j
    v1 = v + dt * a + dt**2 / 2 * j
    a1 = a + dt * j
    v_half = v + dt / 2 * a + dt**2 / 8 * j
    cost = (
        dt * (w.speed * ca.sumsqr(X[COL_V, 1:] - v_target) + w.acceleration * ca.sumsqr(X[COL_A, 1:]))
        + dt * w.jerk * ca.sumsqr(j)
        + w.speed_violation * (ca.sum2(sig_v) + QUADRATIC_SHARE * ca.sumsqr(sig_v))
        + w.position_violation * (ca.sum2(sig_s) + QUADRATIC_SHARE * ca.sumsqr(sig_s))
        + curvature / 2 * (X[COL_V, n] - v_hat) ** 2
    )
    rows: list[Any] = [None] * n_rows
    rows[ROW_DYNAMICS : ROW_DYNAMICS + STATES] = [s1 - X[COL_S, 1:], v1 - X[COL_V, 1:], a1 - X[COL_A, 1:]]
    rows[ROW_HALF_SPEED] = v_half
    rows[ROW_LIMIT : ROW_LIMIT + PIECES] = [v1 - slope[i, :] * s1 - sig_v for i in range(PIECES)]
    rows[ROW_POSITION] = s1 - sig_s
    if lower:
        sig_l = U[COL_SIGMA_L - STATES, :]
        rows[ROW_LOWER] = s1 + sig_l
        cost += w.follower_violation * (ca.sum2(sig_l) + QUADRATIC_SHARE * ca.sumsqr(sig_l))
    if goal:
        late, early = U[width - 2 - STATES, :], U[width - 1 - STATES, :]
        rows[n_rows - 2 :] = [s1 + late, s1 - early]
        cost += w.goal_late_violation * (ca.sum2(late) + QUADRATIC_SHARE * ca.sumsqr(late))
        cost += w.goal_early_violation * (ca.sum2(early) + QUADRATIC_SHARE * ca.sumsqr(early))
    g = ca.reshape(ca.vertcat(*rows), n_rows * n, 1)
    z = ca.vertcat(ca.reshape(ca.vertcat(X[:, :n], U), width * n, 1), X[:, n])
    options: dict[str, Any] = {
        "error_on_fail": False,  # a QP that does not converge is a return flag, read from the statistics
        "inf": _HPIPM_INF,
        "hpipm": (settings or HpipmSettings()).options(),
        # the stage structure: N stages, states, inputs and rows besides the dynamics per stage (none at N)
        "N": n,
        "nx": [STATES] * (n + 1),
        "nu": [width - STATES] * n + [0],
        "ng": [n_rows - STATES] * n + [0],
    }
    function = ca.qpsol("speed_qp", "hpipm", {"x": z, "p": p, "f": cost, "g": g}, options)
    return SpeedQP(function, n, lower, goal)


def local_model(
    problem: SpeedProblem, s_bar: FloatArray, v_end_guess: float
) -> tuple[FloatArray, FloatArray, bool, FloatArray]:
    """The linear model of the limit at knots ``1 … N`` of ``s_bar`` (relative to s0): ``v ≤ e + d·s``.

    Returns ``(e, d)`` of shape ``(PIECES, N)``; a row with ``e = +inf`` is unused. For ``k < N`` row 0 is
    the segment holding ``s̄_k`` and rows 1 and 2 the segments behind and ahead where the kink between is
    concave: there the minimum of the pieces *is* ``v_lim``, so the model stays exact across the kink (at a
    convex kink the tangent alone lies below ``v_lim``, which is safe). At ``N`` row 0 is ``v_lim``'s
    tangent and rows 1 and 2 linearise ``v_end``'s two terms (module docstring) around ``v_end_guess``, the
    expected ``v_N`` [m/s]. Also returns whether those are tangents (exact at ``v_N = v_end_guess``) rather
    than chords, and their curvature in ``v`` per unit multiplier, ``1/(ŵ + c)`` (0 for a chord or unused).
    """
    tables = problem.tables
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
    terms = end_terms(problem, problem.s0 + s_end)
    b, c = terms.b, terms.c
    limit, slope = limit_at(problem, problem.s0 + s_end)
    e[0, -1], d[0, -1] = limit - slope * s_end, slope
    exact = True
    inverse = np.zeros(PIECES)  # 1/(v̂ + c) of tangent rows: their curvature in v per unit multiplier

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
