"""Lateral piecewise-jerk QP: constraints hold (exactly where OSQP's polishing succeeds, to the ADMM
tolerance and reported where it fails), references are tracked, bounds push the path, infeasibility is a
status, misuse is a ValueError, set-ups are reused, and another QP backend agrees."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest
import qpsolvers
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from solvers.conic_qp import solve_conic_qp
from solvers.lateral_qp import (
    LateralQPProblem,
    LateralQPResult,
    LateralQPSolver,
    LateralWeights,
    build_qp_matrices,
    objective,
)
from solvers.lateral_qp_problem import reach_gap
from solvers.result import SolverStatus

TOL = 1e-4
#: OSQP's default tolerances, as the solver's (``eps_abs``, ``eps_rel``)
EPS = 1e-3


def _smoothstep(t: np.ndarray) -> np.ndarray:
    t = np.clip(t, 0.0, 1.0)
    return t**3 * (10 - 15 * t + 6 * t**2)


def _lane_change(n: int = 200, ds: float = 0.5, **kw: Any) -> LateralQPProblem:
    """A 1.5 m lane change between s = 20 m and s = 60 m inside ±2 m."""
    s = np.arange(n) * ds
    args: dict[str, Any] = {
        "ds": ds,
        "d_lower": np.full(n, -2.0),
        "d_upper": np.full(n, 2.0),
        "d_ref": 1.5 * _smoothstep((s - 20.0) / 40.0),
        "jerk_max": 0.5,
    }
    args.update(kw)
    return LateralQPProblem(**args)


def _violations(problem: LateralQPProblem, result: LateralQPResult) -> dict[str, float]:
    """Largest violation of each constraint group (0 when satisfied)."""
    d, dd, ddd, ds = result.d, result.dd, result.ddd, problem.ds
    inf = np.inf
    n = problem.n

    def box(x: np.ndarray, lo: np.ndarray | None, hi: np.ndarray | None) -> float:
        lo = np.full(n, -inf) if lo is None else lo
        hi = np.full(n, inf) if hi is None else hi
        return float(max(np.max(lo[1:] - x[1:]), np.max(x[1:] - hi[1:]), 0.0))

    return {
        "initial": float(max(abs(d[0] - problem.d0), abs(dd[0] - problem.dd0), abs(ddd[0] - problem.ddd0))),
        "d_bounds": box(d, problem.d_lower, problem.d_upper),
        "dd_bounds": box(dd, problem.dd_lower, problem.dd_upper),
        "ddd_bounds": box(ddd, problem.ddd_lower, problem.ddd_upper),
        "jerk": float(
            max(
                np.max(ds * problem.jerk_bounds()[0] - np.diff(ddd)),
                np.max(np.diff(ddd) - ds * problem.jerk_bounds()[1]),
                0.0,
            )
        ),
        "slope_integration": float(np.max(np.abs(dd[1:] - dd[:-1] - ds * (ddd[:-1] + ddd[1:]) / 2))),
        "offset_integration": float(
            np.max(np.abs(d[1:] - d[:-1] - ds * dd[:-1] - ds**2 / 3 * ddd[:-1] - ds**2 / 6 * ddd[1:]))
        ),
    }


def _assert_feasible(problem: LateralQPProblem, result: LateralQPResult, tol: float = TOL) -> None:
    bad = {k: v for k, v in _violations(problem, result).items() if v > tol}
    assert not bad, f"constraints violated: {bad} ({result.info})"


def _assert_reported(problem: LateralQPProblem, result: LateralQPResult) -> None:
    """``info.max_violation`` is the largest violation of any constraint, measured here independently."""
    assert max(_violations(problem, result).values()) == pytest.approx(result.info.max_violation, abs=1e-12)


def _admm_tol(result: LateralQPResult) -> float:
    """How far an ADMM iterate may miss a constraint: OSQP's primal residual test, ``‖Ax − z‖∞ ≤ eps_abs +
    eps_rel·max(‖Ax‖∞, ‖z‖∞)``, with ``‖Ax‖∞ = ‖x‖∞`` here (the box rows; the others are near 0), and
    ten times that when OSQP reports ``solved inaccurate`` (its documented looser test)."""
    loose = 10.0 if result.info.extras["backend_status"] == "solved inaccurate" else 1.0
    return loose * EPS * (1.0 + float(np.max(np.abs(result.x))))


def _assert_solved_or_reported(problem: LateralQPProblem, result: LateralQPResult, polished: bool) -> None:
    """Polished: OSQP's ``solved``, every constraint to ``TOL``. Not: OSQP's ADMM iterate is
    ``solved_inaccurate`` with its violation (below the ADMM tolerance) reported truthfully, and the second
    backend's exact solution is returned with it as ``first``."""
    assert result.info.extras["polished"] is polished and result.info.extras["returned"] == "solution"
    _assert_reported(problem, result)
    assert result.info.status is SolverStatus.SOLVED, result.info
    _assert_feasible(problem, result)
    if polished:
        assert result.info.extras["backend"] == "osqp" and result.first is None
    else:
        assert result.info.extras["backend"] == "clarabel" and result.first is not None
        first = result.first
        assert first.info.status is SolverStatus.SOLVED_INACCURATE, first.info
        _assert_reported(problem, first)
        assert 1e-6 < first.info.max_violation <= _admm_tol(first)


# --------------------------------------------------------------------------------------------------------
# Solutions


#: the active-bound cases where OSQP's polishing finds the active set (elsewhere a bound is pressed over a
#: stretch: the optimum touches it at a few knots only, and the ADMM iterate cannot tell which)
_POLISHED = {"offset": True, "slope": False, "curvature": True, "jerk": True, "all": False}


def _active_cases() -> dict[str, tuple[LateralQPProblem, str]]:
    """Problems whose solution presses each kind of bound, with the group that must be active."""
    n, ds = 120, 0.5
    s = np.arange(n) * ds
    return {
        "offset": (
            _lane_change(
                n=n, d_lower=np.where((s > 20) & (s < 30), 0.8, -2.0), d_ref=np.zeros(n), jerk_max=0.1
            ),
            "d",
        ),
        "slope": (
            _lane_change(
                n=n, d_upper=np.full(n, 1.0), dd_lower=np.full(n, -0.05), dd_upper=np.full(n, 0.05), d0=0.5
            ),
            "dd",
        ),
        "curvature": (
            _lane_change(n=n, ddd_lower=np.full(n, -0.01), ddd_upper=np.full(n, 0.01), d0=-0.5),
            "ddd",
        ),
        "jerk": (_lane_change(n=n, jerk_max=0.002, d0=-0.5), "jerk"),
        "all": (
            LateralQPProblem(
                ds=ds,
                d_lower=np.full(n, -1.0),
                d_upper=np.where((s > 15) & (s < 35), 0.4, 1.5),  # pushes down mid-way
                d_ref=np.full(n, 1.2),  # wants to sit above the squeeze
                jerk_max=0.01,
                d0=0.3,
                dd0=0.08,  # heading up, must turn round
                ddd0=-0.01,
                dd_lower=np.full(n, -0.1),
                dd_upper=np.full(n, 0.1),
                ddd_lower=np.full(n, -0.02),
                ddd_upper=np.full(n, 0.02),
                weights=LateralWeights(offset=0.0),
            ),
            "d",
        ),
    }


def _slack(problem: LateralQPProblem, result: LateralQPResult, group: str) -> float:
    """Smallest distance of the solution to a bound of ``group`` (knots 1 … n−1)."""
    if group == "jerk":
        return float(np.min(problem.ds * problem.jerk_max - np.abs(np.diff(result.ddd))))
    value = {"d": result.d, "dd": result.dd, "ddd": result.ddd}[group][1:]
    lower = getattr(problem, f"{group}_lower")[1:]
    upper = getattr(problem, f"{group}_upper")[1:]
    return float(np.min(np.minimum(value - lower, upper - value)))


@pytest.mark.parametrize("case", ["offset", "slope", "curvature", "jerk", "all"])
def test_solution_satisfies_all_constraints_with_active_bounds(case: str) -> None:
    problem, group = _active_cases()[case]
    solver = LateralQPSolver()
    result = solver.solve(problem)
    _assert_solved_or_reported(problem, result, _POLISHED[case])
    assert result.info.converged and result.info.objective is not None
    # the bound really is active, so the test checks something
    assert abs(_slack(problem, result, group)) <= 1e-6
    assert np.all(np.isfinite(result.x)) and result.x.shape == (3 * problem.n,)


def test_tracks_a_feasible_smooth_reference() -> None:
    """Without the pull to the centre the path follows the lane change; the smoothing terms cost a few
    centimetres at most (length scale ≈ 3 m against a 40 m manoeuvre) and vanish with a heavy ``ref``."""
    problem = _lane_change(weights=LateralWeights(offset=0.0))
    result = LateralQPSolver().solve(problem)
    assert result.info.status is SolverStatus.SOLVED
    _assert_feasible(problem, result)
    assert np.max(np.abs(result.d - problem.d_ref)) < 0.06
    assert result.d[-1] == pytest.approx(1.5, abs=1e-3)

    heavy = replace(problem, weights=LateralWeights(ref=100.0, offset=0.0))
    tight = LateralQPSolver().solve(heavy)
    assert tight.info.status is SolverStatus.SOLVED
    _assert_feasible(heavy, tight)
    assert np.max(np.abs(tight.d - problem.d_ref)) < 0.005


def test_default_offset_weight_shrinks_towards_the_reference_line() -> None:
    """Documented behaviour: on a long constant stretch d → d_ref·w_ref/(w_ref + w_offset)."""
    n = 200
    problem = _lane_change(n=n, d_ref=np.full(n, 1.0), d0=1.0)
    result = LateralQPSolver().solve(problem)
    assert result.info.converged
    middle = result.d[n // 4 : 3 * n // 4]
    np.testing.assert_allclose(middle, 1.0 / 1.1, atol=1e-3)


def test_step_in_lower_bound_is_respected_smoothly() -> None:
    """An obstacle on the right between s = 40 m and 60 m: d ≥ 1 there; the path anticipates it."""
    n, ds = 200, 0.5
    s = np.arange(n) * ds
    blocked = (s >= 40.0) & (s <= 60.0)
    problem = LateralQPProblem(
        ds=ds,
        d_lower=np.where(blocked, 1.0, -2.0),
        d_upper=np.full(n, 2.0),
        d_ref=np.zeros(n),
        jerk_max=0.1,
    )
    result = LateralQPSolver().solve(problem)
    _assert_solved_or_reported(problem, result, polished=False)  # pressed over the whole stretch
    assert np.min(result.d[blocked]) >= 1.0 - result.info.max_violation
    # smooth: jerk within its bound (checked above), bounded curvature, and it rises *before* the step
    assert np.max(np.abs(result.ddd)) < 0.1
    assert result.d[np.searchsorted(s, 35.0)] > 0.3
    # and comes back afterwards
    assert abs(result.d[-1]) < 0.05


def test_objective_matches_the_matrices() -> None:
    problem = _lane_change(n=60, end_d=1.0, d0=-0.3, dd0=0.02)
    result = LateralQPSolver().solve(problem)
    P, q, _, _, _ = build_qp_matrices(problem)
    x = result.x
    full = P + sp.triu(P, 1).T
    constant = problem.weights.ref * np.sum(problem.d_ref**2) + problem.weights.end_target * 1.0**2
    assert 0.5 * x @ (full @ x) + q @ x + constant == pytest.approx(result.info.objective, rel=1e-9)
    assert objective(problem, result.d, result.dd, result.ddd) == pytest.approx(result.info.objective)


def test_matrices_are_in_osqp_form() -> None:
    problem = _lane_change(n=10)
    P, q, A, lower, upper = build_qp_matrices(problem)
    assert P.format == "csc" and A.format == "csc"
    assert lower[0] == upper[0] == problem.d0  # knot 0 pinned
    assert sp.tril(P, -1).nnz == 0
    assert P.shape == (30, 30) and A.shape == (6 * 10 - 3, 30)
    assert q.shape == (30,) and lower.shape == upper.shape == (57,)
    assert np.all(lower <= upper)


# --------------------------------------------------------------------------------------------------------
# Failures are statuses


def _unreachable(n: int = 60) -> LateralQPProblem:
    """The ego starts 3 m to the left of a ±0.5 m corridor; a 0.05 1/m² jerk limit cannot bring it in."""
    return LateralQPProblem(
        ds=0.5,
        d_lower=np.full(n, -0.5),
        d_upper=np.full(n, 0.5),
        d_ref=np.zeros(n),
        jerk_max=0.05,
        d0=3.0,
    )


def test_unreachable_corridor_is_infeasible_not_an_exception() -> None:
    """Without relaxation (``relax=False``) OSQP's proof comes back as ``infeasible`` with the reference
    clipped to the bounds."""
    solver = LateralQPSolver()
    problem = _unreachable()
    result = solver.solve(problem, relax=False)
    assert result.info.status is SolverStatus.INFEASIBLE
    assert not result.info.usable and result.info.objective is None
    assert result.info.extras["returned"] == "clipped_reference"
    _assert_reported(problem, result)
    for arr in (result.d, result.dd, result.ddd, result.x):
        assert np.all(np.isfinite(arr))
    # the fallback is the reference clipped to the bounds, starting at the ego
    assert result.d[0] == 3.0
    np.testing.assert_allclose(result.d[1:], 0.0)
    # the same workspace recovers on a feasible problem afterwards
    wider = replace(problem, d_upper=np.full(problem.n, 4.0))
    again = solver.solve(wider)
    assert again.info.status is SolverStatus.SOLVED
    _assert_feasible(wider, again)
    assert solver.setup_count == 1


def test_iteration_limit_is_a_status_with_a_finite_path() -> None:
    problem = _lane_change()
    result = LateralQPSolver(second_backend=False).solve(problem, max_iter=1)
    assert result.info.status is SolverStatus.MAX_ITERATIONS
    assert not result.info.converged and result.info.iterations == 1 and result.info.objective is None
    assert np.all(np.isfinite(result.x))
    assert np.all(result.d[1:] >= problem.d_lower[1:]) and np.all(result.d[1:] <= problem.d_upper[1:])


def test_a_cut_short_iterate_is_a_consistent_path_the_caller_may_use() -> None:
    """Out of iterations, the last iterate's d″ integrated from the initial state: usable (not converged),
    the initial state and the integration rows exact, its violation of the bounds reported."""
    problem = _active_cases()["offset"][0]
    result = LateralQPSolver(second_backend=False).solve(problem, max_iter=50)
    assert result.info.status is SolverStatus.MAX_ITERATIONS and result.info.iterations == 50
    assert result.info.usable and not result.info.converged
    assert result.info.extras["returned"] == "integrated_iterate"
    violations = _violations(problem, result)
    assert max(violations[k] for k in ("initial", "jerk", "slope_integration", "offset_integration")) < 1e-9
    _assert_reported(problem, result)


# --------------------------------------------------------------------------------------------------------
# The second backend


def test_what_osqp_does_not_finish_clarabel_solves() -> None:
    """Out of OSQP iterations, the same QP goes to Clarabel: its solution, exact, says which backend."""
    problem = _active_cases()["offset"][0]
    exact = LateralQPSolver().solve(problem)  # OSQP, converged and polished
    assert exact.info.status is SolverStatus.SOLVED and exact.info.extras["backend"] == "osqp"
    assert exact.info.extras["second_status"] == ""
    result = LateralQPSolver().solve(problem, max_iter=50)
    assert result.info.status is SolverStatus.SOLVED and result.info.converged
    extras = result.info.extras
    assert (extras["backend"], extras["backend_status"], extras["second_status"]) == (
        "clarabel",
        "Solved",
        "Solved",
    )
    assert (extras["osqp_status"], extras["returned"], result.info.iterations) == (
        "maximum iterations reached",
        "solution",
        50,
    )
    _assert_feasible(problem, result, tol=1e-6)
    _assert_reported(problem, result)
    np.testing.assert_allclose(result.x, exact.x, atol=1e-5)
    # OSQP's own unfinished iterate comes along, for a caller whose own checks prefer it
    assert result.first is not None and exact.first is None
    assert result.first.info.status is SolverStatus.MAX_ITERATIONS and result.first.info.usable
    assert (result.first.info.extras["backend"], result.first.info.extras["returned"]) == (
        "osqp",
        "integrated_iterate",
    )
    assert result.info.objective == pytest.approx(exact.info.objective, rel=1e-6)


def test_a_solve_may_keep_osqps_answer_from_the_second_backend() -> None:
    """``second_backend=False`` for one call: OSQP's unfinished answer as it is, no hand-over; the next call
    hands over again."""
    problem = _active_cases()["offset"][0]
    solver = LateralQPSolver()
    alone = solver.solve(problem, max_iter=50, warm_start=False, second_backend=False)
    assert alone.info.status is SolverStatus.MAX_ITERATIONS and not alone.info.converged
    assert (alone.info.extras["backend"], alone.info.extras["second_status"]) == ("osqp", "")
    assert alone.first is None
    again = solver.solve(problem, max_iter=50, warm_start=False)
    assert again.info.converged and again.info.extras["backend"] == "clarabel"


def test_the_second_backend_gives_the_same_answer_every_time() -> None:
    problem = _active_cases()["all"][0]
    first = LateralQPSolver().solve(problem, max_iter=10, warm_start=False)
    solver = LateralQPSolver()
    solver.solve(_lane_change(n=problem.n), max_iter=10)  # something else first
    again = solver.solve(problem, max_iter=10, warm_start=False)
    assert first.info.extras["backend"] == again.info.extras["backend"] == "clarabel"
    assert np.array_equal(first.x, again.x)


def _pinched(n: int = 60) -> LateralQPProblem:
    """A corridor that jumps 4 m sideways within one knot (0.5 m) halfway: each side is within reach of the
    start, but no path of slope ≤ 2.5 (what the 0.05 1/m² jerk limit gives in 10 m) makes the jump."""
    d_lower, d_upper = np.full(n, -5.0), np.full(n, 5.0)
    d_lower[20], d_upper[21] = 2.0, -2.0
    return LateralQPProblem(ds=0.5, d_lower=d_lower, d_upper=d_upper, d_ref=np.zeros(n), jerk_max=0.05)


def test_the_reach_of_the_start_proves_infeasibility_without_a_solve() -> None:
    """``reach_gap``: from 3 m outside a ±0.5 m corridor, turning back at the jerk limit from rest gives
    ``d = 3 − j·s³/6``, which misses the bound most at the first knot; a pinched corridor within reach of
    the start on either side is not proven (the offset bounds are not propagated), nor is a feasible one."""
    problem = _unreachable()
    assert reach_gap(problem) == pytest.approx(3.0 - 0.05 * 0.5**3 / 6.0 - 0.5, abs=1e-12)
    assert reach_gap(_pinched()) == 0.0
    assert reach_gap(_lane_change()) == 0.0
    # no jerk limit: nothing is out of reach
    assert reach_gap(replace(problem, jerk_max=np.inf)) == 0.0


@pytest.mark.parametrize("case", ["unreachable", "pinched"])
def test_an_infeasible_problem_osqp_did_not_finish_gets_the_path_breaking_its_bounds_least(case: str) -> None:
    """No solution: the elastic problem's path, usable (``relaxed``), consistent, its relaxation reported;
    OSQP's own iterate beside it. The proof is the start's reach where it misses the bounds (no second
    backend's solve for it), else the second backend's."""
    problem = _unreachable() if case == "unreachable" else _pinched()
    result = LateralQPSolver().solve(problem, max_iter=5)
    assert result.info.status is SolverStatus.RELAXED and result.info.usable and not result.info.converged
    extras = result.info.extras
    if case == "unreachable":
        assert extras["second_status"] == ""
        assert "the initial state misses the bounds by" in result.info.message
    else:  # Clarabel proves the QP infeasible, then solves its elastic problem
        assert extras["second_status"] == "PrimalInfeasible"
    assert (extras["backend"], extras["backend_status"]) == ("clarabel", "Solved")
    assert extras["returned"] == "relaxed"
    assert "the bounds relaxed by up to" in result.info.message
    violations = _violations(problem, result)
    assert max(violations[k] for k in ("initial", "jerk", "slope_integration", "offset_integration")) < 1e-6
    _assert_reported(problem, result)
    assert result.first is not None and result.first.info.status is SolverStatus.MAX_ITERATIONS
    if case == "unreachable":
        # it turns back towards the corridor as hard as the jerk limit allows: never farther out than at first
        assert np.all(result.d <= problem.d0 + 1e-9) and result.d[-1] < problem.d0 - 0.5


def test_an_infeasible_problem_gets_the_same_path_whoever_proves_it() -> None:
    """OSQP's own certificate of infeasibility goes straight to the elastic problem (no second opinion on
    the QP): the same ``relaxed`` path as where OSQP ran out of iterations and Clarabel proved it, so the
    answer does not depend on how far OSQP got; OSQP's result beside it."""
    problem = _unreachable()
    proved = LateralQPSolver().solve(problem)
    unfinished = LateralQPSolver().solve(problem, max_iter=5)
    assert proved.info.extras["osqp_status"] == "primal infeasible"
    assert unfinished.info.extras["osqp_status"] == "maximum iterations reached"
    for result in (proved, unfinished):
        assert result.info.status is SolverStatus.RELAXED and result.info.extras["returned"] == "relaxed"
        _assert_reported(problem, result)
    np.testing.assert_allclose(proved.x, unfinished.x, atol=1e-9)
    assert proved.info.extras["second_status"] == ""  # Clarabel solved the elastic problem only
    assert proved.first is not None and proved.first.info.status is SolverStatus.INFEASIBLE
    assert proved.first.info.extras["returned"] == "clipped_reference"
    # an optional solve (no second backend) keeps OSQP's verdict
    alone = LateralQPSolver().solve(problem, second_backend=False)
    assert alone.info.status is SolverStatus.INFEASIBLE and alone.first is None


def test_no_second_backend_when_osqp_proved_infeasibility_or_ran_out_of_time() -> None:
    result = LateralQPSolver().solve(_unreachable(), relax=False)
    assert result.info.status is SolverStatus.INFEASIBLE and result.info.extras["second_status"] == ""
    out_of_time = LateralQPSolver().solve(_active_cases()["all"][0], time_limit_s=1e-9)
    assert out_of_time.info.status is SolverStatus.TIME_LIMIT
    assert out_of_time.info.extras["second_status"] == ""


# --------------------------------------------------------------------------------------------------------
# Misuse raises


def _kwargs(n: int = 10) -> dict[str, Any]:
    return {
        "ds": 0.5,
        "d_lower": np.full(n, -1.0),
        "d_upper": np.full(n, 1.0),
        "d_ref": np.zeros(n),
        "jerk_max": 1.0,
    }


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"d_upper": np.ones(9)}, "d_upper"),
        ({"d_ref": np.zeros(2), "d_lower": -np.ones(2), "d_upper": np.ones(2)}, "at least 3"),
        ({"d_ref": np.zeros((10, 1))}, "d_ref"),
        ({"d_ref": np.r_[np.zeros(9), np.nan]}, "d_ref"),
        ({"d_ref": np.r_[np.zeros(9), np.inf]}, "d_ref"),
        ({"d_lower": np.r_[np.full(9, -1.0), np.nan]}, "d_lower"),
        ({"d_lower": np.r_[np.full(9, -1.0), np.inf]}, "d_lower"),
        ({"d_lower": np.r_[np.full(5, -1.0), np.full(5, 2.0)]}, "d_lower > d_upper at knot 5"),
        ({"dd_lower": np.full(9, -1.0)}, "dd_lower"),
        ({"dd_lower": np.full(10, 0.2), "dd_upper": np.full(10, 0.1)}, "dd_lower > dd_upper"),
        ({"ddd_upper": np.full(10, -np.inf)}, "ddd_upper"),
        ({"ds": 0.0}, "ds"),
        ({"ds": np.nan}, "ds"),
        ({"jerk_max": 0.0}, "jerk_max"),
        ({"jerk_max": np.nan}, "jerk_max"),
        ({"d0": np.nan}, "d0"),
        ({"dd0": np.inf}, "dd0"),
        ({"end_d": np.nan}, "end_d"),
        ({"d_ref": ["a"] * 10}, "d_ref"),
        ({"jerk_lower": np.full(10, -1.0)}, "jerk_lower"),
        ({"jerk_upper": np.r_[np.ones(8), np.nan]}, "jerk_upper"),
        ({"jerk_lower": np.full(9, 0.2), "jerk_upper": np.full(9, 0.1)}, "jerk_lower > jerk_upper"),
        ({"jerk_ref": np.zeros(10)}, "jerk_ref"),
    ],
)
def test_misuse_raises_value_error(change: dict[str, Any], match: str) -> None:
    args = _kwargs()
    args.update(change)
    with pytest.raises(ValueError, match=match):
        LateralQPProblem(**args)


def test_bad_weights_and_limits_raise() -> None:
    with pytest.raises(ValueError, match=r"weights\.jerk"):
        LateralWeights(jerk=-1.0)
    with pytest.raises(ValueError, match=r"weights\.ref"):
        LateralWeights(ref=np.nan)
    problem = LateralQPProblem(**_kwargs())
    solver = LateralQPSolver()
    with pytest.raises(ValueError, match="max_iter"):
        solver.solve(problem, max_iter=0)
    with pytest.raises(ValueError, match="time_limit_s"):
        solver.solve(problem, time_limit_s=-1.0)
    with pytest.raises(ValueError, match="problem"):
        solver.solve(_kwargs())  # type: ignore[arg-type]


def test_jerk_bounds_per_interval_hold_where_they_are_given() -> None:
    """A lane change whose jerk is bounded tighter over its first half (as a car's steering rate bounds
    it at speed) and forced off 0 further on (a reference's ripple to undo): the solution keeps each
    interval's bounds where the free solution breaks them."""
    base = _lane_change()
    n = base.n
    lower, upper = np.full(n - 1, -0.5), np.full(n - 1, 0.5)
    lower[: n // 2], upper[: n // 2] = -5e-4, 5e-4
    lower[150:160], upper[150:160] = 1e-3, 2e-3
    problem = replace(base, jerk_lower=lower, jerk_upper=upper)
    result = LateralQPSolver().solve(problem)
    assert result.info.converged, result.info
    _assert_feasible(problem, result, tol=EPS)
    jerk = np.diff(result.ddd) / problem.ds
    assert np.all(jerk >= lower - 1e-5) and np.all(jerk <= upper + 1e-5)
    free = np.diff(LateralQPSolver().solve(base).ddd) / base.ds
    assert np.abs(free[: n // 2]).max() > 5e-4 and free[150:160].min() < 1e-3  # the bounds bind
    # the same bounds as ±jerk_max give the same problem as jerk_max itself
    same = replace(base, jerk_lower=np.full(n - 1, -0.5), jerk_upper=np.full(n - 1, 0.5))
    np.testing.assert_array_equal(build_qp_matrices(same)[3], build_qp_matrices(base)[3])
    np.testing.assert_array_equal(build_qp_matrices(same)[4], build_qp_matrices(base)[4])


def test_a_jerk_reference_pulls_the_jerk_term_towards_it() -> None:
    """``jerk_ref`` changes only ``q`` (the set-up is reused) and the objective counts ``d‴ − r``."""
    base = _lane_change(n=40)
    ref = np.full(base.n - 1, 0.01)
    pulled = replace(base, jerk_ref=ref)
    P0, q0, A0, l0, _ = build_qp_matrices(base)
    P1, q1, A1, l1, _ = build_qp_matrices(pulled)
    assert (P0 != P1).nnz == 0 and (A0 != A1).nnz == 0
    np.testing.assert_array_equal(l0, l1)
    assert not np.array_equal(q0, q1)
    result = LateralQPSolver().solve(pulled)
    assert result.info.converged
    x = result.x
    value = 0.5 * x @ (P1 + sp.triu(P1, 1).T) @ x + q1 @ x
    constant = base.weights.ref * np.sum(base.d_ref**2) + base.weights.jerk * np.sum(ref**2)
    assert objective(pulled, result.d, result.dd, result.ddd) == pytest.approx(value + constant, rel=1e-6)
    jerk = np.diff(result.ddd) / base.ds
    free = np.diff(LateralQPSolver().solve(base).ddd) / base.ds
    assert np.mean(jerk) > np.mean(free)  # pulled towards 0.01


def test_infinite_bounds_and_jerk_are_allowed() -> None:
    n = 30
    problem = LateralQPProblem(
        ds=0.5,
        d_lower=np.full(n, -np.inf),
        d_upper=np.full(n, np.inf),
        d_ref=np.linspace(0.0, 1.0, n),
        jerk_max=np.inf,
        dd_upper=np.full(n, np.inf),
    )
    result = LateralQPSolver().solve(problem)
    assert result.info.status is SolverStatus.SOLVED
    _assert_feasible(problem, result)


def test_problem_arrays_are_read_only_copies() -> None:
    d_ref = np.zeros(10)
    problem = LateralQPProblem(**{**_kwargs(), "d_ref": d_ref})
    d_ref[0] = 5.0
    assert problem.d_ref[0] == 0.0
    with pytest.raises(ValueError):
        problem.d_ref[0] = 1.0


# --------------------------------------------------------------------------------------------------------
# Reuse and warm start


def test_warm_start_reuses_the_setup_and_needs_no_more_iterations() -> None:
    solver = LateralQPSolver()
    first = solver.solve(_lane_change(d0=0.1))
    s = np.arange(200) * 0.5
    changed = _lane_change(d0=0.12, dd0=0.005, d_ref=1.5 * _smoothstep((s - 21.0) / 40.0))
    second = solver.solve(changed)
    assert first.info.status is second.info.status is SolverStatus.SOLVED
    assert solver.setup_count == 1
    assert second.info.iterations <= first.info.iterations
    _assert_feasible(changed, second)

    solver.solve(_lane_change(n=100))  # another size: a second set-up
    assert solver.setup_count == 2
    solver.solve(_lane_change(weights=LateralWeights(jerk=500.0)))  # other weights: a third
    assert solver.setup_count == 3
    solver.solve(_lane_change(end_d=1.0))  # an end target changes P: a fourth
    assert solver.setup_count == 4
    solver.solve(_lane_change(d0=0.3))  # back to the first key: reused
    assert solver.setup_count == 4


def test_setups_beyond_the_cache_are_dropped_least_recently_used_first() -> None:
    solver = LateralQPSolver(max_cached=2)
    new_setup = []
    for n in (20, 30, 20, 40, 20, 30):
        result = solver.solve(_lane_change(n=n))
        assert result.info.converged
        new_setup.append(result.info.setup_time_ms > 0.0)
    # 20 (set up), 30 (set up), 20 (reused), 40 (set up, drops 30), 20 (reused), 30 (set up again)
    assert solver.setup_count == 4
    assert new_setup == [True, True, False, True, False, True]


# --------------------------------------------------------------------------------------------------------
# Cross-check against another QP backend


def _other_backend() -> str | None:
    preferred = ["clarabel", "proxqp", "piqp", "highs", "daqp", "cvxopt", "quadprog", "scs"]
    available = [s for s in preferred if s in qpsolvers.available_solvers]
    return available[0] if available else None


def _solve_with(
    backend: str, P: Any, q: np.ndarray, A: Any, lower: np.ndarray, upper: np.ndarray
) -> np.ndarray:
    """Solve ``min ½xᵀPx + qᵀx, l ≤ Ax ≤ u`` (``P`` upper triangle) through ``qpsolvers``."""
    nx = P.shape[0]
    full = (P + sp.triu(P, 1).T).tocsc()
    box = slice(0, nx)  # the first rows of A are the identity
    rows = np.arange(nx, A.shape[0])
    equal = rows[lower[rows] == upper[rows]]
    ranged = rows[lower[rows] < upper[rows]]
    A_rng = A[ranged]
    finite_u, finite_l = np.isfinite(upper[ranged]), np.isfinite(lower[ranged])
    G = sp.vstack([A_rng[finite_u], -A_rng[finite_l]]).tocsc()
    h = np.concatenate([upper[ranged][finite_u], -lower[ranged][finite_l]])
    x = qpsolvers.solve_qp(
        full, q, G=G, h=h, A=A[equal].tocsc(), b=lower[equal], lb=lower[box], ub=upper[box], solver=backend
    )
    assert x is not None, f"{backend} failed"
    return np.asarray(x)


@pytest.mark.skipif(
    _other_backend() is None, reason="no QP backend besides OSQP installed (dev extra: clarabel)"
)
@pytest.mark.parametrize("case", ["lane_change", "offset", "slope", "curvature", "jerk", "all"])
def test_agrees_with_another_backend(case: str) -> None:
    """The same QP (``build_qp_matrices``) through another solver gives the same path."""
    if case == "lane_change":
        problem = _lane_change(n=120, d0=0.2, dd0=-0.01, end_d=1.4)
    else:
        problem = _active_cases()[case][0]
    result = LateralQPSolver().solve(problem)
    polished = case == "lane_change" or _POLISHED[case]
    _assert_solved_or_reported(problem, result, polished)
    backend = _other_backend()
    assert backend is not None
    n = problem.n
    x = _solve_with(backend, *build_qp_matrices(problem))
    atol = 1e-3 if polished else 5e-3  # the ADMM iterate where polishing fails (stopped at eps 1e-3)
    np.testing.assert_allclose(result.d, x[:n], atol=atol)
    np.testing.assert_allclose(result.dd, x[n : 2 * n], atol=atol)
    assert objective(problem, x[:n], x[n : 2 * n], x[2 * n :]) == pytest.approx(
        result.info.objective, rel=1e-4 if polished else 1e-2
    )


# --------------------------------------------------------------------------------------------------------
# Property: feasible problems solve and satisfy their constraints


def _feasible_path(
    rng: np.random.Generator, n: int, ds: float, jerk_max: float, start: tuple[float, float, float]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A piecewise-jerk path (exact integration, ``|jerk| ≤ jerk_max``) that follows a random smooth target
    of a few metres: each jerk is a clipped stable feedback (triple pole at ``−a``, ``a·Δs ≤ 0.3``)."""
    s = np.arange(n) * ds
    target = sum(
        rng.uniform(-1.0, 1.0) * np.sin(2 * np.pi * s / rng.uniform(20.0, 80.0) + rng.uniform(0, 2 * np.pi))
        for _ in range(3)
    )
    a = min(0.3 / ds, rng.uniform(0.1, 0.5))
    d, dd, ddd = np.empty(n), np.empty(n), np.empty(n)
    d[0], dd[0], ddd[0] = start
    for i in range(n - 1):
        j = -(a**3) * (d[i] - target[i]) - 3 * a**2 * dd[i] - 3 * a * ddd[i]
        j = float(np.clip(j, -jerk_max, jerk_max))
        ddd[i + 1] = ddd[i] + ds * j
        dd[i + 1] = dd[i] + ds * ddd[i] + ds**2 * j / 2
        d[i + 1] = d[i] + ds * dd[i] + ds**2 * ddd[i] / 2 + ds**3 * j / 6
    return d, dd, ddd


@st.composite
def feasible_problems(draw: st.DrawFn) -> LateralQPProblem:
    """Bounds drawn around a feasible path of a few metres, and a smooth reference that may leave them."""
    n = draw(st.integers(min_value=5, max_value=150))
    ds = draw(st.floats(min_value=0.2, max_value=1.0))
    jerk_max = draw(st.floats(min_value=0.01, max_value=1.0))
    seed = draw(st.integers(min_value=0, max_value=2**32 - 1))
    rng = np.random.default_rng(seed)
    start = (rng.uniform(-1.0, 1.0), rng.uniform(-0.1, 0.1), rng.uniform(-0.02, 0.02))
    d, dd, ddd = _feasible_path(rng, n, ds, jerk_max, start)
    s = np.arange(n) * ds
    kwargs: dict[str, Any] = {}
    if draw(st.booleans()):
        kwargs["dd_lower"], kwargs["dd_upper"] = (
            dd - rng.uniform(0.01, 0.2, n),
            dd + rng.uniform(0.01, 0.2, n),
        )
    if draw(st.booleans()):
        kwargs["ddd_lower"] = ddd - rng.uniform(0.005, 0.05, n)
        kwargs["ddd_upper"] = ddd + rng.uniform(0.005, 0.05, n)
    amplitude, wavelength, phase = rng.uniform(0, 2), rng.uniform(10, 60), rng.uniform(0, 2 * np.pi)
    return LateralQPProblem(
        ds=ds,
        d_lower=d - rng.uniform(0.02, 1.5, n),
        d_upper=d + rng.uniform(0.02, 1.5, n),
        d_ref=d + amplitude * np.sin(2 * np.pi * s / wavelength + phase),
        jerk_max=jerk_max,
        d0=start[0],
        dd0=start[1],
        ddd0=start[2],
        end_d=draw(st.none() | st.floats(min_value=-2.0, max_value=2.0)),
        **kwargs,
    )


@settings(max_examples=30, deadline=None)
@given(feasible_problems())
def test_property_feasible_problems_solve_within_their_constraints(problem: LateralQPProblem) -> None:
    result = LateralQPSolver().solve(problem)
    # Where polishing fails the ADMM iterate comes back, solved_inaccurate when it misses a constraint by
    # more than the feasibility tolerance; in a rare case (about 1 in 2000 draws) OSQP runs out of
    # iterations and the integrated iterate comes back. Whatever comes back, its violation is reported.
    assert result.info.usable, result.info
    _assert_reported(problem, result)
    if result.info.status is SolverStatus.SOLVED:
        _assert_feasible(problem, result)
    elif result.info.status is SolverStatus.SOLVED_INACCURATE:
        assert result.info.max_violation <= _admm_tol(result)


@settings(max_examples=60, deadline=None)
@given(feasible_problems())
def test_property_the_reach_of_the_start_never_refutes_a_feasible_problem(problem: LateralQPProblem) -> None:
    """``reach_gap`` proves infeasibility only: a problem built round a feasible path gets 0."""
    assert reach_gap(problem) == 0.0


@settings(max_examples=60, deadline=None)
@given(
    feasible_problems(), st.floats(min_value=-4.0, max_value=4.0), st.floats(min_value=-0.5, max_value=0.5)
)
def test_property_what_the_reach_of_the_start_refutes_the_second_backend_finds_infeasible(
    problem: LateralQPProblem, shift: float, turn: float
) -> None:
    """Moved off its feasible path at the start (offset and slope), a problem the start's reach proves
    infeasible is infeasible for Clarabel too."""
    moved = replace(problem, d0=problem.d0 + shift, dd0=problem.dd0 + turn)
    gap = reach_gap(moved)
    if gap > 1e-6:
        P, q, A, lower, upper = build_qp_matrices(moved)
        assert solve_conic_qp(P, q, A, lower, upper, max_iter=200).info.status is SolverStatus.INFEASIBLE


def test_a_cold_solve_after_another_reuses_the_setup_and_gives_the_first_answer_bit_for_bit() -> None:
    """A cold solve's answer does not depend on what the solver solved before: where OSQP adapted its
    ``rho`` then, the set-up goes back to the initial ``rho`` (no new set-up) and the answer, iterations
    included, is a fresh solver's."""
    cases = _active_cases()
    problem, other = cases["slope"][0], cases["jerk"][0]  # the same n, Δs, weights and end
    fresh = LateralQPSolver().solve(problem, warm_start=False)
    solver = LateralQPSolver()
    solver.solve(other, warm_start=False)
    assert any(w.rho_adapted for w in solver._workspaces.values())  # the case this is about
    again = solver.solve(problem, warm_start=False)
    assert solver.setup_count == 1
    assert again.info.iterations == fresh.info.iterations
    assert again.info.status is fresh.info.status
    assert np.array_equal(again.x, fresh.x)


def test_the_matrices_of_a_key_are_built_once_and_shared() -> None:
    problem = _lane_change(n=50)
    P, _, A, _, _ = build_qp_matrices(problem)
    P2, _, A2, _, _ = build_qp_matrices(_lane_change(n=50, d0=0.4))
    assert P is P2 and A is A2
    P3, _, _, _, _ = build_qp_matrices(_lane_change(n=50, ds=0.25))
    assert P3 is not P and P3.shape == P.shape and not np.array_equal(P3.toarray(), P.toarray())
