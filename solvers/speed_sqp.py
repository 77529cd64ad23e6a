r"""The speed profile of a :class:`~solvers.speed_problem.SpeedProblem` by sequential quadratic programming.

Each iteration solves the QP of :mod:`solvers.speed_qp` (the limit replaced by its local model around the
current profile ``s̄``). The step to the QP's solution is globalised by a backtracking line search on the
exact penalty function (``J`` of :mod:`solvers.speed_cost` with the true violations as slacks); every
trial is dynamically feasible, since the dynamics are linear and the boxes convex. The iteration stops when
the model agrees with the limit at the QP's solution, wherever the speed is at the limit, to ``tolerance``
(100 × that at ``k = N``, a braking margin rather than a limit). ``s̄`` starts from the previous solution
shifted in time (warm start) or from a forward–backward pass of the limit along the path, timed (cold
start), raised to ``s_lower`` and a goal's lower bound as far as the limit lets the vehicle get (the
fastest such pass: a point it cannot reach would model the limit where the QP's profile is not) and then
capped by a goal's upper bound and by ``s_bound`` (the upper bounds win there too).

The problem is not convex, and at a sharp dip the SQP can end in a local minimum of the penalty function
that violates the limit. So when the result violates the limit, ``v ≥ 0`` or ``s_bound`` by more than
:func:`~solvers.speed_profiles.braking_profile` (a full stop) does (``s_lower`` and a goal's bounds aside: a
full stop rarely keeps ahead of anything), the SQP runs once more from that stop and the result with the
lower penalty function is kept; a violation the stop would avoid that still remains is reported
(``violation_remains``), never ``solved``. A result cut short by ``max_iterations`` is no local minimum,
though, only an iterate on its way: it first gets as many iterations again, continued from where it
stopped (line-searched from it, so never worse), and only what that still leaves above the stop's
violation restarts from the stop. (Judged as it was, against a run from the stop that converges there in
a QP or two, it lost to a profile that comes to a standstill or crawls on the road ahead, where more
iterations drive on.) The two runs are compared without the horizon-end row's excess up to its
convergence tolerance, which a profile that stops never has.

A QP that HPIPM stops early (iteration limit, minimum step) is used if its iterate is finite and within
the boxes, never as converged. The returned profile is re-integrated from the jerks with the dynamics, so
it meets them to rounding error whatever the QP's accuracy.

Statuses (:class:`~solvers.result.SolverStatus`):

* ``solved``: the model converged at an exact QP solution, and no violation remains that a full stop
  would avoid;
* ``solved_inaccurate``: the best iterate, a valid profile whose violations are reported truthfully, when
  the model converged at a QP that HPIPM stopped early, when the line search found no decrease, when a
  later QP failed, or when it converged with a violation a full stop would avoid (``violation_remains``);
* ``max_iterations``: the best iterate after ``max_iterations`` QPs without convergence (it happens where a
  sharp convex kink of ``v_lim``, a V-shaped dip, has to be crossed by many knots, one or two per
  iteration);
* ``failed``: no QP gave a usable iterate (HPIPM failed or CasADi raised): the braking profile.
"""

from __future__ import annotations

import math
import time
from collections import OrderedDict
from dataclasses import dataclass
from typing import Literal

import numpy as np

from solvers import speed_qp
from solvers.result import Extra, SolveInfo, SolverStatus
from solvers.speed_cost import end_speed_limit, end_terms, goal_excess, objective, violations
from solvers.speed_problem import (
    PIECES,
    QUADRATIC_SHARE,
    FloatArray,
    SpeedProblem,
    SpeedResult,
    SpeedWeights,
    integrate_jerk,
)
from solvers.speed_profiles import braking_profile
from solvers.speed_qp import (
    HPIPM_USABLE,
    P_END_CURVATURE,
    P_V_HAT,
    P_V_TARGET,
    HpipmSettings,
    HpipmStatus,
    SpeedQP,
    build_speed_qp,
    local_model,
)
from solvers.validation import integer, scalar

__all__ = ["SpeedSolver"]

#: a limit row counts as active when the speed is within this of the limit or its model [m/s]
_ACTIVE_BAND = 1e-3
#: step lengths the line search tries
_STEP_LENGTHS = tuple(0.5**i for i in range(7))
#: points of the cold start's forward–backward pass
_GUESS_POINTS = 257
#: the horizon-end row converges to this many times the tolerance
_END_TOLERANCE_FACTOR = 100.0
#: relative merit increase still accepted with a converged step (rounding)
_MERIT_SLACK = 1e-6
#: violations below this are rounding, not worth a word in the message
_REPORTED_VIOLATION = 1e-6
#: a violation above this is checked against a full stop's, and the SQP restarted from the stop if that
#: violates less by more than this
_RESTORE_VIOLATION = 1e-4

#: why an SQP run stopped
Stop = Literal["converged", "max_iterations", "line_search", "qp_failed"]


def _cap(problem: SpeedProblem, s_bar: FloatArray) -> FloatArray:
    """``s_bar`` (relative to s0) raised to ``s_lower`` and a goal's lower bound at and before each knot, as
    far as the limit lets the vehicle get by then (:func:`_reach`), then capped by a goal's upper bound and
    then by the bounds at and ahead of each knot (the upper bounds win, the hard ones last), non-decreasing,
    ≥ 0.

    The raise stops at the reach because the QP models the limit around ``s_bar``: linearised where the
    vehicle cannot be, on the rising side of a dip, the model falls steeply back towards where the vehicle
    is, and its slack's penalty then pays for driving faster, through the dip, by far more than the limit
    there costs (12 m/s over the limit after two QPs, towards a goal beyond a tight bend)."""
    tables = problem.tables
    if tables.has_lower or tables.has_goal:
        floor = np.maximum.accumulate(np.maximum(tables.lower, tables.goal_lo) - problem.s0)
        s_bar = np.maximum(s_bar, np.minimum(floor, _reach(problem)))
    if tables.has_goal:
        s_bar = np.minimum(s_bar, np.minimum.accumulate((tables.goal_hi - problem.s0)[::-1])[::-1])
    s_bar = np.minimum(s_bar, tables.s_bound - problem.s0)
    s_bar = np.minimum.accumulate(s_bar[::-1])[::-1]
    return np.maximum(s_bar, 0.0)


@dataclass(frozen=True)
class _Pass:
    """A speed along the path and the time it takes: ``speed`` [m/s] at ``sigma = s − s0`` [m] (from 0 to
    ``sigma[-1]``), reached at ``time`` [s]."""

    sigma: FloatArray
    speed: FloatArray
    time: FloatArray

    def positions(self, t: FloatArray) -> FloatArray:
        """``σ`` [m] at the times ``t`` [s]; beyond the pass's end at its last speed."""
        sigma = np.interp(t, self.time, self.sigma)
        beyond = t > self.time[-1]
        sigma[beyond] = self.sigma[-1] + self.speed[-1] * (t[beyond] - self.time[-1])
        return sigma


def _timed_pass(problem: SpeedProblem, v_cap: float, brake: float, accel: float) -> _Pass | None:
    """A forward–backward pass of the limit along the path, timed: along ``σ = s − s0`` the speed
    ``min(v_cap, v_lim)`` (0 at ``s_stop``) lowered to what braking at ``brake`` [m/s², > 0] ahead of
    every point and accelerating at ``accel`` [m/s², > 0] from ``v0`` allow (running minima of ``v² ±
    2aσ``), but not below braking from ``v0`` at ``a_min``. None when the stop is at ``s0``."""
    n, dt = problem.steps, problem.dt
    stop = problem.s_stop - problem.s0
    farthest = n * dt * max(problem.v0, problem.v_target, float(np.max(problem.limit_v))) + 1.0
    end = min(farthest, stop)
    if end <= 1e-6:
        return None
    sigma = np.linspace(0.0, end, _GUESS_POINTS)
    speed_cap = np.minimum(np.interp(problem.s0 + sigma, problem.limit_s, problem.limit_v), v_cap)
    if stop <= farthest:
        speed_cap[-1] = 0.0
    v2 = np.minimum.accumulate((speed_cap**2 + 2 * brake * sigma)[::-1])[::-1] - 2 * brake * sigma
    v2 = np.minimum(v2, np.minimum.accumulate(v2 - 2 * accel * sigma) + 2 * accel * sigma)
    v2 = np.minimum(v2, problem.v0**2 + 2 * accel * sigma)
    v2 = np.maximum(v2, problem.v0**2 + 2 * problem.a_min * sigma)
    speed = np.sqrt(np.maximum(v2, 0.0))
    mean = 0.5 * (speed[1:] + speed[:-1])
    time_of = np.concatenate([[0.0], np.cumsum(np.diff(sigma) / np.maximum(mean, 1e-3))])
    return _Pass(sigma, speed, time_of)


def _reach(problem: SpeedProblem) -> FloatArray:
    """About how far [m] from s0 the vehicle can get by each knot within the limit: the fastest
    :func:`_timed_pass` (``a_max`` and ``a_min`` in full, no target; the jerk limit aside)."""
    fastest = _timed_pass(problem, math.inf, -problem.a_min, max(problem.a_max, 1e-3))
    if fastest is None:
        return np.zeros(problem.steps + 1)
    return fastest.positions(problem.t)


def _cold_start(problem: SpeedProblem) -> tuple[FloatArray, float]:
    """Guesses of ``s_k − s0`` and ``v_N``: :func:`_timed_pass` of ``min(v_target, v_lim)`` braking at
    ``a_min/2`` and accelerating at ``a_max/2``, sampled at ``t_k``."""
    guess = _timed_pass(problem, problem.v_target, -0.5 * problem.a_min, max(0.5 * problem.a_max, 1e-3))
    if guess is None:
        return np.zeros(problem.steps + 1), 0.0
    s_bar = _cap(problem, guess.positions(problem.t))
    v_end = float(np.interp(s_bar[-1], guess.sigma, guess.speed))
    terms = end_terms(problem, problem.s0 + float(s_bar[-1]))
    if terms.rate is not None and terms.bound is not None and problem.s0 + s_bar[-1] >= terms.bound - 1e-6:
        v_end = min(v_end, terms.rate)  # held at the moving bound: its speed
    if s_bar[-1] >= problem.s_stop - problem.s0 - 1e-6:
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
    tables = problem.tables
    return bool(
        np.all(iterate.a[1:] >= tables.a_lo[1:] - tol)
        and np.all(iterate.a[1:] <= tables.a_hi[1:] + tol)
        and np.all(iterate.v >= tables.v_lo - tol)
    )


@dataclass
class _Run:
    """What one SQP run produced."""

    best: _Iterate | None
    #: why it stopped; ``exact``: at a QP that HPIPM solved to its tolerance (``SUCCESS``)
    stop: Stop
    exact: bool
    qp_solves: int
    ipm_iterations: int
    line_search_steps: int
    early_qp_stops: int
    hpipm_status: int
    qp_error: str
    notes: list[str]


def _max_violation(problem: SpeedProblem, iterate: _Iterate) -> float:
    """The largest violation of ``v_lim``, ``v ≥ 0`` and ``s_bound`` by an iterate (not ``s_lower``: this
    decides a restart from a full stop, which rarely keeps ahead of anything)."""
    e_v, e_s, _ = violations(problem, iterate.s + problem.s0, iterate.v)
    return float(max(np.max(e_v), np.max(e_s)))


def _true_limit(problem: SpeedProblem, s: FloatArray) -> FloatArray:
    """The limit rows' true right-hand side at knots ``1 … N`` of ``s`` (relative to s0)."""
    value = np.interp(problem.s0 + s[1:], problem.limit_s, problem.limit_v)
    value[-1] = end_speed_limit(problem, problem.s0 + float(s[-1]))
    return value


class SpeedSolver:
    """Solves :class:`~solvers.speed_problem.SpeedProblem` s by SQP over HPIPM QPs built once per
    ``(N, Δt, weights)``.

    Building a QP takes about 0.1 s (N = 80, ``info.setup_time_ms``); up to ``max_cached`` are kept, least
    recently used dropped first. Not thread-safe: use one solver per thread.

    A result's ``info.extras`` holds ``start`` (``"warm"`` or ``"cold"``), ``qp_solves`` (QPs solved, as
    the result's field), ``line_search_steps`` (halvings of the step, summed), ``early_qp_stops`` (QPs HPIPM
    stopped early whose iterate was used), ``hpipm_status`` (the kept run's last
    :class:`~solvers.speed_qp.HpipmStatus` flag, −1 for none), ``qp_error`` (CasADi's error when a QP
    raised, else empty), ``stop`` (why the kept run stopped: ``converged``, ``max_iterations``,
    ``line_search`` or ``qp_failed``), ``restarts`` (SQP runs from a full stop), ``restarted`` (the profile
    comes from such a run), ``continued`` (the first run, cut short with a violation, got more iterations),
    ``violation_remains`` (a violation more than ``restore_violation`` above a full
    stop's: one the profile did not need) and ``returned`` (``"solution"`` or ``"braking_profile"``).

    Args:
        max_iterations: QPs per SQP run, ≥ 1 (a solve runs up to three times: the first, its continuation
            and the restart from a full stop, each only after a violation the stop would avoid).
        tolerance: agreement of the linearised limit with the limit, wherever the speed is near it, that
            counts as converged [m/s], > 0.
        max_cached: number of built QPs kept, ≥ 1.
        restore_violation: a violation [m/s or m] above which the SQP restarts from a full stop (when
            that violates less by more than this); a caller that checks the profile anyway can save the
            second run by raising it.
        qp_residual: HPIPM's residual tolerance per QP (:class:`~solvers.speed_qp.HpipmSettings`), in (0, 1).
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
        self._hpipm = HpipmSettings(residual=float(qp_residual))
        self._qps: OrderedDict[tuple[int, float, SpeedWeights, bool, bool], SpeedQP] = OrderedDict()
        self._build_count = 0

    @property
    def build_count(self) -> int:
        """How many QPs this solver has built (one per new ``(N, Δt, weights)`` still in the cache, and per
        whether the problem has a lower bound and a goal's bounds)."""
        return self._build_count

    def _qp(self, problem: SpeedProblem) -> tuple[SpeedQP, float]:
        """The QP for ``problem``'s key (built if new) and the time building it took [ms] (0 if cached)."""
        tables = problem.tables
        key = (problem.steps, problem.dt, problem.weights, tables.has_lower, tables.has_goal)
        qp = self._qps.get(key)
        if qp is not None:
            self._qps.move_to_end(key)
            return qp, 0.0
        start = time.perf_counter()
        steps, dt, weights, lower, goal = key
        qp = self._qps[key] = build_speed_qp(steps, dt, weights, lower, self._hpipm, goal=goal)
        self._build_count += 1
        with speed_qp.CASADI_LOCK:  # a dropped QP's CasADi objects die here
            while len(self._qps) > self._max_cached:
                self._qps.popitem(last=False)
        return qp, (time.perf_counter() - start) * 1e3

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
            ValueError: ``problem`` is not a :class:`~solvers.speed_problem.SpeedProblem`, ``warm_start``
                not a :class:`SpeedResult` (or ``None``), or ``shift`` not an integer ≥ 0.
        """
        start = time.perf_counter()
        if not isinstance(problem, SpeedProblem):
            raise ValueError(f"problem: expected SpeedProblem, got {type(problem).__name__}")
        if warm_start is not None and not isinstance(warm_start, SpeedResult):
            raise ValueError(f"warm_start: expected SpeedResult or None, got {type(warm_start).__name__}")
        shift = integer("shift", shift, low=0)

        qp, setup_ms = self._qp(problem)
        if warm_start is not None and warm_start.t.size >= 2:
            (s_bar, v_end), origin = _shifted(problem, warm_start, shift), "warm"
        else:
            (s_bar, v_end), origin = _cold_start(problem), "cold"
        qp.set_bounds(problem)
        first = kept = self._sqp(problem, qp, s_bar, v_end, self._max_iterations)
        runs = [first]
        notes = first.notes
        restarted = continued = violation_remains = False
        if first.best is not None and _max_violation(problem, first.best) > self._restore_violation:
            stop = braking_profile(problem)
            s_stop, v_stop, a_stop = integrate_jerk(problem.dt, 0.0, problem.v0, problem.a0, stop)
            needed = _max_violation(problem, _Iterate(stop, s_stop, v_stop, a_stop, 0.0))
            allowed = needed + self._restore_violation
            if first.stop == "max_iterations" and _max_violation(problem, first.best) > allowed:
                # an unfinished iterate, not a local minimum: it gets the restart's iterations first (judged
                # as it was against a converged run from the stop, it lost to a profile that stops)
                more = self._sqp(problem, qp, first.best.s, 0.0, self._max_iterations, start=first.best)
                runs.append(more)
                kept, continued = more, True
                notes = [*first.notes, *more.notes, f"continued after {first.qp_solves} QPs with a violation"]
            best = kept.best
            assert best is not None  # for mypy: the first run's, or one continued from it
            if _max_violation(problem, best) > allowed:
                # a violation a full stop avoids (or keeps smaller): a local minimum of the penalty
                # function (a sharp V-shaped dip of v_lim can hold one); try again from the full stop
                retry = self._sqp(problem, qp, s_stop, 0.0, self._max_iterations)
                runs.append(retry)
                if retry.best is not None and self._judged(problem, retry.best) < self._judged(problem, best):
                    kept, restarted = retry, True
                    notes = [*retry.notes, "restarted from a full stop after a violation it did not need"]
                assert kept.best is not None  # for mypy: the first run's, or a better one
                excess = _max_violation(problem, kept.best)
                violation_remains = excess > allowed
                if violation_remains:
                    notes.append(f"a violation of {excess:.3g} remains where a full stop needs {needed:.3g}")
        qp_solves = sum(run.qp_solves for run in runs)
        ipm_iterations = sum(run.ipm_iterations for run in runs)

        best = kept.best
        if best is None:
            status = SolverStatus.FAILED
            jerk = braking_profile(problem)
            notes.append("returned the braking profile (not a solution)")
        else:
            if kept.stop == "max_iterations":
                status = SolverStatus.MAX_ITERATIONS
            elif kept.stop == "converged" and kept.exact and not violation_remains:
                status = SolverStatus.SOLVED
            else:
                status = SolverStatus.SOLVED_INACCURATE
            jerk = best.jerk
            if status is not SolverStatus.SOLVED and not notes:
                notes.append(f"the limit's linearisation had not converged after {qp_solves} QPs")
        s, v, a = integrate_jerk(problem.dt, problem.s0, problem.v0, problem.a0, jerk)
        e_v, e_s, e_l = violations(problem, s, v)
        speed_violation, position_violation = float(np.max(e_v)), float(np.max(e_s))
        follower_violation = float(np.max(e_l))
        goal_violation = float(max(np.max(e) for e in goal_excess(problem, s)))
        max_violation = max(speed_violation, position_violation, follower_violation)
        message = f"SQP from a {origin} start: {qp_solves} QPs, {ipm_iterations} HPIPM iterations"
        if best is not None and max(speed_violation, position_violation) > _REPORTED_VIOLATION:
            notes.append(
                f"soft constraints violated by up to {speed_violation:.3g} m/s and {position_violation:.3g} m"
            )
        if best is not None and follower_violation > _REPORTED_VIOLATION:
            notes.append(f"s_lower violated by up to {follower_violation:.3g} m")
        if best is not None and goal_violation > _REPORTED_VIOLATION:
            notes.append(f"the goal's bounds missed by up to {goal_violation:.3g} m")
        if notes:
            message += "; " + "; ".join(notes)
        extras: dict[str, Extra] = {
            "start": origin,
            "qp_solves": qp_solves,
            "line_search_steps": sum(run.line_search_steps for run in runs),
            "early_qp_stops": sum(run.early_qp_stops for run in runs),
            "hpipm_status": kept.hpipm_status,
            "qp_error": kept.qp_error,
            "stop": kept.stop,
            "restarts": len(runs) - 1 - continued,
            "restarted": restarted,
            "continued": continued,
            "violation_remains": violation_remains,
            "returned": "solution" if best is not None else "braking_profile",
        }
        info = SolveInfo(
            status=status,
            iterations=ipm_iterations,
            solve_time_ms=(time.perf_counter() - start) * 1e3 - setup_ms,
            objective=best.merit if best is not None else None,  # J of this very profile
            message=message,
            max_violation=max_violation,
            setup_time_ms=setup_ms,
            extras=extras,
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
            max_violation=max_violation,
            qp_solves=qp_solves,
            follower_violation=follower_violation,
            goal_violation=goal_violation,
        )

    def _sqp(
        self,
        problem: SpeedProblem,
        qp: SpeedQP,
        s_bar: FloatArray,
        v_end: float,
        budget: int,
        start: _Iterate | None = None,
    ) -> _Run:
        """Up to ``budget`` SQP iterations, linearised first at ``(s̄, v̂_N)`` (bounds set in ``qp``); with
        ``start``, an earlier run's best iterate, they continue that run: linearised at it first, and every
        step line-searched from it (``s_bar`` and ``v_end`` unused)."""
        best = start
        if start is not None:
            s_bar = start.s
            v_end = min(float(start.v[-1]), end_speed_limit(problem, problem.s0 + float(start.s[-1])))
        multipliers = np.zeros(PIECES)  # of the end rows in the last QP
        stop: Stop = "max_iterations"
        exact = False
        qp_solves = ipm_iterations = line_search_steps = early_qp_stops = 0
        hpipm_status, qp_error = -1, ""
        notes: list[str] = []
        qp.p[P_V_TARGET] = problem.v_target
        for _ in range(budget):
            e, d, exact_end, inverse = local_model(problem, s_bar, v_end)
            qp.limit_rows[...] = e
            qp.slopes[...] = d
            qp.p[P_END_CURVATURE] = float(np.dot(multipliers, inverse))
            qp.p[P_V_HAT] = v_end
            try:
                flag, iterations = qp.solve()
            except RuntimeError as error:  # CasADi reports a crashed backend this way
                qp_error = str(error).splitlines()[-1][:120]
                notes.append(f"QP {qp_solves + 1} raised: {qp_error}")
                stop = "qp_failed"
                break
            qp_solves += 1
            ipm_iterations += iterations
            hpipm_status = flag
            if flag not in HPIPM_USABLE or not np.all(np.isfinite(qp.jerk)):
                notes.append(f"QP {qp_solves} failed (HPIPM flag {flag})")
                stop = "qp_failed"
                break
            target = _iterate(problem, np.clip(qp.jerk, -problem.jerk_max, problem.jerk_max))
            if flag != HpipmStatus.SUCCESS:
                if not _within_boxes(problem, target):
                    notes.append(f"QP {qp_solves} failed (HPIPM flag {flag}, iterate outside the boxes)")
                    stop = "qp_failed"
                    break
                early_qp_stops += 1
                notes.append(f"QP {qp_solves} stopped early (HPIPM flag {flag}); its iterate was used")
            lam = qp.end_multipliers
            multipliers = np.maximum(np.nan_to_num(lam, nan=0.0, posinf=0.0, neginf=0.0), 0.0)
            no_worse = best is None or target.merit <= best.merit + _MERIT_SLACK * (1 + abs(best.merit))
            if no_worse and self._model_error(problem, e, d, target, exact_end) <= self._tolerance:
                best, stop, exact = target, "converged", flag == HpipmStatus.SUCCESS
                break
            if best is None:
                candidate = target
            else:
                candidate, halvings = self._line_search(problem, best, target)
                line_search_steps += halvings
            if candidate is best:
                notes.append("the line search found no decrease")
                stop = "line_search"
                break
            best, s_bar = candidate, candidate.s
            # linearise v_end next at the boundary point below an over-shooting v_N
            v_end = min(float(candidate.v[-1]), end_speed_limit(problem, problem.s0 + float(candidate.s[-1])))
        return _Run(
            best, stop, exact, qp_solves, ipm_iterations, line_search_steps, early_qp_stops, hpipm_status,
            qp_error, notes,
        )  # fmt: skip

    def _judged(self, problem: SpeedProblem, iterate: _Iterate) -> float:
        """The merit two runs are compared by: the exact penalty function without the horizon-end row's
        excess up to what convergence allows there (``_END_TOLERANCE_FACTOR`` × the tolerance [m/s]).

        That row is a braking margin, and a run converges with up to that much over it; charged at the
        limit's weight, it made a profile that comes to a stop (which never exceeds it) look better than
        one that drives on (Moabit: 1084 against 177, though the crawl's own cost is the higher: 177
        against 109)."""
        excess = max(float(iterate.v[-1]) - end_speed_limit(problem, problem.s0 + float(iterate.s[-1])), 0.0)
        forgiven = min(excess, _END_TOLERANCE_FACTOR * self._tolerance)
        rest = excess - forgiven

        def charge(e: float) -> float:
            return problem.weights.speed_violation * (e + QUADRATIC_SHARE * e * e)

        return iterate.merit - charge(excess) + charge(rest)

    @staticmethod
    def _model_error(
        problem: SpeedProblem, e: FloatArray, d: FloatArray, target: _Iterate, exact_end: bool
    ) -> float:
        """How far the QP's model of the limit was off at ``target``, where the speed is near the limit.

        Knot N, a braking margin rather than a limit, gets ``_END_TOLERANCE_FACTOR`` times the tolerance, and
        where a chord (conservative below 1 m/s) stood in for its tangent only an over-estimate counts.
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
    def _line_search(problem: SpeedProblem, current: _Iterate, target: _Iterate) -> tuple[_Iterate, int]:
        """The longest of ``_STEP_LENGTHS`` towards ``target`` that lowers the merit (``current`` if none),
        and the halvings of the step it took."""
        for halvings, alpha in enumerate(_STEP_LENGTHS):
            if alpha == 1.0:
                trial = target
            else:
                trial = _iterate(problem, current.jerk + alpha * (target.jerk - current.jerk))
            if trial.merit < current.merit:
                return trial, halvings
        return current, len(_STEP_LENGTHS) - 1
