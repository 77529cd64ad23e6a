"""The speed SQP: tracks the target, keeps limits, stops, follows, reports what it cannot keep (statuses,
violations, extras), warm-starts, raises on misuse, agrees with IPOPT, and every profile meets the dynamics
and the boxes."""

from __future__ import annotations

import json
import math
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from solvers import speed_sqp
from solvers.result import SolverStatus
from solvers.speed_cost import end_speed_limit, objective, speed_limit
from solvers.speed_problem import SpeedProblem, SpeedWeights, integrate_jerk
from solvers.speed_profiles import braking_profile
from solvers.speed_qp import HpipmStatus, SpeedQP
from solvers.speed_sqp import SpeedSolver
from tests.solvers.speed_cases import assert_valid, limit_excess, make_problem

#: a solver shared by the tests (a QP is built once per (N, Δt, weights))
SOLVER = SpeedSolver(max_cached=16)


def test_free_road_reaches_the_target_speed_within_the_limits() -> None:
    problem = make_problem()
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.SOLVED and result.info.usable
    assert result.max_violation == 0.0
    assert abs(result.v[-1] - 15.0) < 0.1
    assert abs(result.a[-1]) < 0.05
    assert np.max(result.a) <= problem.a_max + 1e-9
    assert np.max(result.a) > 1.0  # it does accelerate, not crawl
    assert np.all(np.diff(result.v) >= -1e-9)  # no overshoot-and-return
    assert result.info.objective == pytest.approx(
        objective(problem, result.s, result.v, result.a, result.jerk)
    )


def test_curvature_dip_is_kept_smoothly() -> None:
    # 20 m/s road with an 8 m/s curve between s = 40 and 60 m
    problem = make_problem(v0=15.0, limit_s=[0, 30, 40, 60, 70, 1000], limit_v=[20, 20, 8, 8, 20, 20])
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.SOLVED
    assert limit_excess(problem, result) <= 1e-3
    in_curve = (result.s >= 40) & (result.s <= 60)
    assert in_curve.sum() >= 10
    assert np.all(result.v[in_curve] <= 8 + 1e-3)
    assert np.max(result.v[in_curve]) > 7.5  # not needlessly slow
    assert result.v[-1] > result.v[np.flatnonzero(in_curve)[-1]]  # speeds up again after the curve
    # smooth: the jerk changes sign only a few times (slow down, hold, speed up)
    signs = np.sign(result.jerk[np.abs(result.jerk) > 1e-3])
    assert np.count_nonzero(np.diff(signs)) <= 6


@pytest.mark.parametrize("s_stop", [25.0, 40.0])
def test_stops_before_s_stop(s_stop: float) -> None:
    problem = make_problem(s_stop=s_stop)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.SOLVED
    assert np.max(result.s) <= s_stop + 1e-3
    assert result.s[-1] > s_stop - 1e-2  # it drives up to the stop point (v_target is 15 m/s) …
    assert abs(result.v[-1]) < 1e-2  # … and stops there
    assert np.all(result.v >= -1e-6)
    if s_stop == 25.0:  # within reach: stopped before the end, and stays stopped
        stopped = np.flatnonzero(result.v < 1e-3)
        assert stopped.size >= 3 and np.all(np.abs(result.a[stopped[0] + 1 :]) < 1e-2)


def test_stop_line_holds_against_a_high_target_over_a_long_horizon() -> None:
    # the multipliers grow with v_target and the horizon; the default penalties must stay above them
    problem = make_problem(steps=200, v0=20.0, v_target=40.0, limit_v=[40.0, 40.0], s_stop=120.0)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.SOLVED
    assert result.max_violation <= 1e-6
    assert np.max(result.s) <= 120.0 + 1e-6 and abs(result.v[-1]) < 1e-2


def test_stop_beyond_the_horizon_leaves_room_to_brake() -> None:
    # the stop lies 110 m ahead: out of reach in 8 s at 15 m/s, but the end state must be able to brake
    problem = make_problem(v0=15.0, v_target=20.0, s_stop=130.0)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    b = -problem.a_min / 2
    c = b * b / (2 * problem.jerk_max)
    braking = (result.v[-1] ** 2 + 2 * c * result.v[-1]) / (2 * b)
    assert result.s[-1] + braking <= 130.0 + 0.05  # the end row converges to 100 × the tolerance
    assert result.v[-1] > 5.0  # and it is not stopped early
    assert end_speed_limit(problem, 130.0) == 0.0


def test_follows_a_moving_bound() -> None:
    t = np.arange(81) * 0.1
    s_upper = 20.0 + 8.0 * t  # a leader at 8 m/s, 20 m ahead (gap already subtracted)
    problem = make_problem(v0=12.0, s_upper=s_upper)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.SOLVED
    assert np.all(result.s <= s_upper + 1e-3)
    assert result.max_violation <= 1e-6
    assert abs(result.v[-1] - 8.0) < 0.3  # settles at the leader's speed
    assert s_upper[-1] - result.s[-1] < 5.0  # and close behind


def test_initial_speed_above_the_limit_is_best_effort_with_the_violation_reported() -> None:
    problem = make_problem(v0=25.0, limit_v=[10.0, 10.0])
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable
    assert result.speed_violation == pytest.approx(25.0 - 10.0 - 2.0 * 0.1**2 / 2 * 5, abs=0.1)
    assert result.max_violation == result.speed_violation and result.position_violation == 0.0
    assert np.min(result.a) == pytest.approx(problem.a_min, abs=1e-6)  # full braking
    below = np.flatnonzero(result.v <= 10.0)
    assert below.size and result.v[below[0] - 1] > 10.0 and np.all(np.diff(result.v[: below[0]]) < 0)
    assert result.info.max_violation == result.speed_violation > 14.0  # reported


def test_stop_point_too_close_brakes_fully_and_reports_the_overshoot() -> None:
    problem = make_problem(v0=20.0, s_stop=20.0)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable
    assert np.min(result.a) == pytest.approx(problem.a_min, abs=1e-6)
    brake_s, _, _ = integrate_jerk(problem.dt, 0.0, 20.0, 0.0, braking_profile(problem))
    assert result.s[-1] == pytest.approx(brake_s[-1], abs=0.05)  # as short as full braking gets
    assert result.position_violation == pytest.approx(result.s[-1] - 20.0, abs=1e-9)
    assert abs(result.v[-1]) < 1e-3 and np.all(result.v >= -1e-6)  # stops, never reverses


def test_bound_already_behind_the_vehicle_is_best_effort() -> None:
    t = np.arange(81) * 0.1
    problem = make_problem(s_upper=-5.0 + 3.0 * t)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable and result.position_violation > 0
    assert np.all(result.v >= -1e-6)
    stopped = result.v < 1e-3
    assert np.all(np.abs(result.a[stopped][5:]) < 1e-2)  # stays stopped, no creeping back and forth


def test_acceleration_outside_the_box_is_a_measurement_not_an_error() -> None:
    problem = make_problem(v0=8.0, a0=-7.0, jerk_max=1.0)  # brakes harder than a_min = −5
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable
    assert np.all(result.a[1:] >= problem.a0)  # it can only release at the jerk limit
    assert result.a[-1] >= problem.a_min
    problem = make_problem(v0=0.5, a0=-3.0, jerk_max=1.0)  # a reversal is unavoidable
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable and np.min(result.v) < 0
    floor, _ = problem.speed_floor()
    assert np.min(result.v - floor) >= -1e-6


def test_a_vehicle_stopping_with_a_brake_it_cannot_release_in_time_stands_after_it() -> None:
    # nearly stopped and braking hard (a recorded car): v < 0 is unavoidable for a moment, then it stands
    problem = make_problem(v0=0.346, a0=-4.556, jerk_max=30.0, a_min=-8.0, a_max=3.0, s_stop=0.02)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable and np.min(result.v) < 0
    assert np.all(result.v[5:] >= -1e-6)  # standing (or driving) from 0.5 s on, not drifting backwards
    assert result.s[-1] >= np.max(result.s) - 0.02  # it went back a few millimetres at most


def test_frame_offset_does_not_change_the_profile() -> None:
    base = make_problem(
        v0=15.0, limit_s=[0, 30, 40, 60, 70, 1000], limit_v=[20, 20, 8, 8, 20, 20], s_stop=90.0
    )
    shifted = replace(base, s0=5000.0, limit_s=np.asarray(base.limit_s) + 5000.0, s_stop=5090.0)
    a, b = SOLVER.solve(base), SOLVER.solve(shifted)
    assert np.max(np.abs((b.s - 5000.0) - a.s)) < 1e-6
    assert np.max(np.abs(b.v - a.v)) < 1e-6


def test_agrees_with_ipopt_on_a_smooth_limit() -> None:
    xs = np.arange(0.0, 200.0, 1.0)
    limit = 20 - 12 * np.exp(-(((xs - 60) / 12) ** 2))
    problem = make_problem(dt=0.1, steps=60, v0=15.0, limit_s=xs, limit_v=limit, v_target=18.0, jerk_max=3.0)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.SOLVED

    n, dt, w = problem.steps, problem.dt, problem.weights
    opti = ca.Opti()
    jerk = opti.variable(n)
    s, v, a = [problem.s0], [problem.v0], [problem.a0]
    for k in range(n):
        s.append(s[k] + v[k] * dt + a[k] * dt**2 / 2 + jerk[k] * dt**3 / 6)
        v.append(v[k] + a[k] * dt + jerk[k] * dt**2 / 2)
        a.append(a[k] + jerk[k] * dt)
    v_lim = ca.interpolant("v_lim", "linear", [xs], limit)
    cost = dt * w.jerk * ca.sumsqr(jerk)
    for k in range(1, n + 1):
        cost += dt * (w.speed * (v[k] - problem.v_target) ** 2 + w.acceleration * a[k] ** 2)
        opti.subject_to(v[k] <= v_lim(s[k]))
        opti.subject_to(v[k] >= 0)
        opti.subject_to(opti.bounded(problem.a_min, a[k], problem.a_max))
    opti.subject_to(opti.bounded(-problem.jerk_max, jerk, problem.jerk_max))
    opti.minimize(cost)
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "tol": 1e-10, "sb": "yes"})
    solution = opti.solve()
    v_ipopt = np.array([float(solution.value(x)) for x in v])
    assert result.info.objective == pytest.approx(float(solution.value(cost)), rel=1e-5)
    assert np.max(np.abs(result.v - v_ipopt)) < 1e-3


def test_the_qp_is_built_once_per_size_step_and_weights() -> None:
    solver = SpeedSolver(max_cached=2)
    built = solver.solve(make_problem())
    reused = solver.solve(make_problem(v0=3.0, s_stop=50.0))
    assert solver.build_count == 1
    assert built.info.setup_time_ms > 0.0 and reused.info.setup_time_ms == 0.0
    solver.solve(make_problem(weights=SpeedWeights(jerk=1.0)))
    solver.solve(make_problem(steps=40))  # third key: the least recently used is dropped
    assert solver.build_count == 3
    solver.solve(make_problem(steps=40))
    assert solver.build_count == 3
    solver.solve(make_problem())
    assert solver.build_count == 4


def test_warm_start_from_the_shifted_previous_solution() -> None:
    xs = np.arange(0.0, 400.0, 0.5)
    kappa = np.clip(np.minimum((xs - 60) / 15, (140 - xs) / 15), 0, 1) / 25 + 0.002 * np.sin(xs / 3)
    limit = np.minimum(16.0, np.sqrt(2.0 / np.maximum(np.abs(kappa), 1e-6)))

    def problem_at(travelled: float, v0: float, a0: float) -> SpeedProblem:
        return make_problem(v0=v0, a0=a0, limit_s=xs - travelled, limit_v=limit, jerk_max=3.0, a_min=-4.0)

    solver = SpeedSolver()
    previous = solver.solve(problem_at(0.0, 10.0, 0.0))
    travelled, cold_qps, warm_qps, cold_ms, warm_ms = 0.0, [], [], [], []
    for _ in range(30):  # the vehicle follows the plan for one step, the path is re-anchored at it
        travelled += previous.s[1] - previous.s[0]
        problem = problem_at(travelled, float(previous.v[1]), float(previous.a[1]))
        cold = solver.solve(problem)
        warm = solver.solve(problem, warm_start=previous, shift=1)
        assert_valid(problem, warm)
        assert warm.info.status is SolverStatus.SOLVED and warm.info.extras["start"] == "warm"
        assert cold.info.extras["start"] == "cold"
        # the rippled limit has several local optima; the warm one stays close to the cold one's cost
        assert warm.info.objective is not None and cold.info.objective is not None
        assert warm.info.objective <= 1.02 * cold.info.objective
        cold_qps.append(cold.qp_solves)
        warm_qps.append(warm.qp_solves)
        cold_ms.append(cold.info.solve_time_ms)
        warm_ms.append(warm.info.solve_time_ms)
        previous = warm
    assert sum(warm_qps) <= sum(cold_qps)
    assert max(warm_qps) <= 2
    # not slower (loosely: timing on a shared machine is noisy)
    assert np.median(warm_ms) <= 1.5 * np.median(cold_ms) + 2.0


def test_warm_start_from_the_solution_itself_is_one_qp_to_the_same_profile() -> None:
    problem = make_problem(
        v0=15.0, limit_s=[0, 30, 40, 60, 70, 1000], limit_v=[20, 20, 8, 8, 20, 20], s_stop=150.0
    )
    cold = SOLVER.solve(problem)
    warm = SOLVER.solve(problem, warm_start=cold, shift=0)
    assert warm.qp_solves == 1 and warm.info.status is SolverStatus.SOLVED
    assert np.max(np.abs(warm.v - cold.v)) < 1e-6


def test_warm_start_with_another_horizon_and_no_shift() -> None:
    problem = make_problem(v0=15.0, limit_s=[0, 30, 40, 60, 70, 1000], limit_v=[20, 20, 8, 8, 20, 20])
    first = SOLVER.solve(replace(problem, steps=40, dt=0.2))
    again = SOLVER.solve(problem, warm_start=first, shift=0)
    assert_valid(problem, again)
    assert again.info.status is SolverStatus.SOLVED
    assert limit_excess(problem, again) <= 1e-3


def test_a_failing_qp_returns_the_braking_profile(monkeypatch: pytest.MonkeyPatch) -> None:
    def broken(self: Any) -> tuple[int, int]:
        raise RuntimeError("backend crashed")

    solver = SpeedSolver()
    monkeypatch.setattr(SpeedQP, "solve", broken)
    problem = make_problem(v0=12.0, s_stop=10.0)
    result = solver.solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.FAILED and not result.info.usable
    assert result.info.objective is None
    assert result.info.extras["returned"] == "braking_profile"
    assert result.info.extras["qp_error"] == "backend crashed"
    assert np.allclose(result.jerk, braking_profile(problem))
    assert result.position_violation > 0  # the fallback ignores s_stop, and says so


def test_a_qp_without_a_finite_solution_returns_the_braking_profile(monkeypatch: pytest.MonkeyPatch) -> None:
    def diverging(self: Any) -> tuple[int, int]:
        self.x[:] = np.nan
        self.lam_g[:] = np.nan
        return 3, 7

    monkeypatch.setattr(SpeedQP, "solve", diverging)
    problem = make_problem()
    result = SpeedSolver().solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.FAILED
    assert result.info.extras["hpipm_status"] == HpipmStatus.NAN_SOL
    assert result.info.extras["returned"] == "braking_profile"


def test_solving_again_gives_the_same_profile() -> None:
    problem = make_problem(steps=20)
    first, second = SOLVER.solve(problem), SOLVER.solve(problem)
    assert first.info.usable and second.info.usable
    assert np.allclose(first.v, second.v)


_T = np.arange(81) * 0.1
#: a vehicle from behind at 14 m/s (gap subtracted); the ego drives at 10 m/s with a target of 8
_FOLLOWER = -8.0 + 14.0 * _T


def test_lower_bound_is_met_when_it_can_be() -> None:
    left_alone = SOLVER.solve(make_problem(v_target=8.0))
    assert np.max(_FOLLOWER[1:] - left_alone.s[1:]) > 10.0  # the bound matters
    s_lower = np.concatenate(([50.0], _FOLLOWER[1:]))  # entry 0 (the measured start) is not imposed
    problem = make_problem(v_target=8.0, s_lower=s_lower)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.SOLVED
    assert result.max_violation <= 1e-6 and result.follower_violation <= 1e-6
    assert np.all(result.s[1:] >= _FOLLOWER[1:] - 1e-6)
    assert result.v[-1] > 13.0  # keeps up with it, above its own target
    assert result.info.objective == pytest.approx(
        objective(problem, result.s, result.v, result.a, result.jerk)
    )


@pytest.mark.parametrize("ahead", ["s_stop", "s_upper"])
def test_lower_bound_gives_way_to_a_stop_or_a_bound_ahead(ahead: str) -> None:
    # a block 40 m ahead, or a leader at 10 m/s 15 m ahead (gap subtracted): both conflict with the follower
    upper = {"s_stop": {"s_stop": 40.0}, "s_upper": {"s_upper": 15.0 + 10.0 * _T}}[ahead]
    problem = make_problem(v_target=8.0, s_lower=_FOLLOWER, **upper)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable
    s_bound = problem.s_bound()
    conflict = float(np.max(_FOLLOWER[1:] - s_bound[1:]))
    assert conflict > 5.0
    assert result.position_violation <= 1e-6 and np.all(result.s <= s_bound + 1e-6)  # the bound ahead wins
    assert result.s[-1] > s_bound[-1] - 0.5  # but the vehicle stays as far ahead as it allows
    assert result.follower_violation == pytest.approx(float(np.max(_FOLLOWER[1:] - result.s[1:])))
    assert result.follower_violation >= conflict - 1e-6  # reported
    assert result.max_violation == result.follower_violation
    assert result.info.max_violation == result.follower_violation  # reported


def test_the_weights_decide_which_bound_wins() -> None:
    weights = SpeedWeights(follower_violation=1e5)  # above position_violation: now the follower wins
    problem = make_problem(v_target=8.0, s_lower=_FOLLOWER, s_stop=40.0, weights=weights)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable
    assert result.follower_violation < 0.1 and result.position_violation > 50.0
    assert SpeedWeights().follower_violation < SpeedWeights().position_violation


def test_an_unused_lower_bound_changes_nothing() -> None:
    solver = SpeedSolver()
    plain = make_problem(
        v0=15.0, limit_s=[0, 30, 40, 60, 70, 1000], limit_v=[20, 20, 8, 8, 20, 20], s_stop=90.0
    )
    reference = solver.solve(plain)
    for s_lower in (np.full(81, -math.inf), np.concatenate(([1e3], np.full(80, -math.inf)))):
        # free throughout (entry 0 is not imposed): the same QP, the same profile
        result = solver.solve(replace(plain, s_lower=s_lower))
        assert np.array_equal(result.jerk, reference.jerk) and result.follower_violation == 0.0
    assert solver.build_count == 1
    # finite but never binding: the QP with the slack, the same profile up to its tolerance
    result = solver.solve(replace(plain, s_lower=-100.0 + 0.0 * _T))
    assert solver.build_count == 2
    assert np.max(np.abs(result.s - reference.s)) < 1e-5 and np.max(np.abs(result.v - reference.v)) < 1e-5
    assert result.info.status is reference.info.status and result.follower_violation == 0.0


#: profiles from the solver as it was before s_lower existed (default solver): v every 10th knot, s_N
# fmt: off
_BEFORE_S_LOWER: dict[str, tuple[list[float], float]] = {
    "dip": ([15.0, 14.0002585, 11.40042001, 8.639285418, 7.641071848, 7.796371457, 8.232707938, 10.10185258,
             11.38219043], 80.93727199),
    "stop": ([10.0, 9.000000009, 6.053415074, 3.025398383, 1.309519295, 0.4783183942, 0.1173363461,
              0.005864831569, 0.0], 25.0),
    "leader": ([12.0, 11.58059449, 11.12968481, 10.8511115, 10.64974841, 10.4150186, 10.01287107, 9.250195598,
                8.0], 84.0),
    "dip and leader": ([12.0, 12.2486734, 11.46932561, 8.884404836, 5.875505518, 5.996476259, 5.999999743,
                        6.085807006, 7.441663508], 66.2793169),
}
# fmt: on


def _before_problem(name: str) -> SpeedProblem:
    if name == "dip":
        return make_problem(v0=15.0, limit_s=[0, 30, 40, 60, 70, 1000], limit_v=[20, 20, 8, 8, 20, 20])
    if name == "stop":
        return make_problem(s_stop=25.0)
    if name == "leader":
        return make_problem(v0=12.0, s_upper=20.0 + 8.0 * _T)
    limit_s = np.linspace(0.0, 150.0, 301)  # bench/plan.py's speed problem
    return SpeedProblem(
        dt=0.1,
        steps=80,
        v0=12.0,
        limit_s=limit_s,
        limit_v=np.where((limit_s > 40) & (limit_s < 60), 6.0, 15.0),
        v_target=15.0,
        a_min=-6.0,
        a_max=2.5,
        jerk_max=8.0,
        s_upper=40.0 + 8.0 * _T,
    )


@pytest.mark.parametrize("name", sorted(_BEFORE_S_LOWER))
def test_problems_without_a_lower_bound_are_solved_as_before(name: str) -> None:
    v, s_end = _BEFORE_S_LOWER[name]
    result = SpeedSolver().solve(_before_problem(name))
    assert result.info.status is SolverStatus.SOLVED
    assert np.allclose(result.v[::10], v, rtol=0.0, atol=1e-6)
    assert result.s[-1] == pytest.approx(s_end, abs=1e-6)
    assert result.follower_violation == 0.0


def test_bad_solver_arguments_raise() -> None:
    with pytest.raises(ValueError, match="problem"):
        SOLVER.solve("not a problem")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="warm_start"):
        SOLVER.solve(make_problem(), warm_start=object())  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="shift"):
        SOLVER.solve(make_problem(), shift=-1)
    for kwargs in ({"max_iterations": 0}, {"tolerance": 0.0}, {"max_cached": 0}, {"tolerance": math.nan}):
        with pytest.raises(ValueError):
            SpeedSolver(**kwargs)


@st.composite
def feasible_problems(draw: st.DrawFn) -> SpeedProblem:
    """Random limits, a start below all of them, and stop points and leaders beyond full braking."""
    steps, dt = draw(st.sampled_from([(40, 0.1), (60, 0.2)]))
    points = draw(st.integers(min_value=1, max_value=8))
    gaps = draw(st.lists(st.floats(0.5, 60.0), min_size=points, max_size=points))
    limit_s = np.cumsum(gaps) - draw(st.floats(0.0, 30.0))
    limit_v = np.array(draw(st.lists(st.floats(2.0, 30.0), min_size=points, max_size=points)))
    v0 = draw(st.floats(0.0, 1.0)) * float(np.min(limit_v))
    a_min = draw(st.floats(-8.0, -1.0))
    jerk_max = draw(st.floats(0.5, 8.0))
    # braking now, but no harder than releasing the brake (on the grid too) can undo before v = 0
    a0 = -draw(st.floats(0.0, 1.0)) * min(-0.5 * a_min, 0.5 * math.sqrt(2 * jerk_max * v0))
    if v0 < 0.1:
        a0 = 0.0
    kw: dict[str, Any] = {}
    base = SpeedProblem(
        dt=dt, steps=steps, v0=v0, a0=a0, limit_s=limit_s, limit_v=limit_v, v_target=0.0, a_min=a_min,
        a_max=2.0, jerk_max=jerk_max,
    )  # fmt: skip
    stop_s, _, _ = integrate_jerk(dt, 0.0, v0, a0, braking_profile(base))
    if draw(st.booleans()):
        kw["s_stop"] = float(stop_s[-1] + draw(st.floats(0.5, 100.0)))
    if draw(st.booleans()):
        t = np.arange(steps + 1) * dt
        s_upper = stop_s[-1] + draw(st.floats(0.5, 50.0)) + draw(st.floats(0.0, 20.0)) * t
        kw["s_upper"] = np.where(np.arange(steps + 1) % 7 == 3, np.inf, s_upper)
    return replace(
        base,
        v_target=draw(st.floats(0.0, 35.0)),
        a_max=draw(st.floats(0.5, 3.0)),
        s0=draw(st.floats(-100.0, 100.0)),
        limit_s=limit_s + 0.0,
        **kw,
    )


@settings(max_examples=25, deadline=None)
@given(feasible_problems())
def test_property_feasible_problems_are_solved_within_their_constraints(problem: SpeedProblem) -> None:
    # the frame offset s0 moves everything
    problem = replace(
        problem,
        limit_s=problem.limit_s + problem.s0,
        s_stop=problem.s_stop + problem.s0,
        s_upper=None if problem.s_upper is None else problem.s_upper + problem.s0,
    )
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable, result.info.message
    assert result.info.objective is not None and math.isfinite(result.info.objective)
    if result.info.status is SolverStatus.SOLVED:
        # a full stop meets every constraint here, so "solved" must have met them too; a sharp dip of the
        # limit can hold the SQP in a local minimum with a violation, which is then "solved_inaccurate"
        assert result.max_violation <= 1e-3, result.info.message
        assert limit_excess(problem, result) <= 1e-3
        assert np.all(result.s <= problem.s_bound() + 1e-3)
        assert np.all(result.v >= -1e-6)
    else:
        assert result.info.extras["violation_remains"] or result.max_violation <= 1e-3


def test_random_feasible_problems_are_nearly_all_solved_exactly() -> None:
    rng = np.random.default_rng(7)
    solved = 0
    for _ in range(60):
        points = int(rng.integers(2, 10))
        limit_s = np.sort(rng.uniform(-10.0, 250.0, points))
        limit_s = limit_s[np.concatenate([[True], np.diff(limit_s) > 0.5])]
        limit_v = rng.uniform(3.0, 30.0, limit_s.size)
        v0 = float(rng.uniform(0.0, 1.0) * np.min(limit_v))
        base = make_problem(v0=v0, limit_s=limit_s, limit_v=limit_v, a_min=float(rng.uniform(-6, -2)))
        stop_s, _, _ = integrate_jerk(0.1, 0.0, v0, 0.0, braking_profile(base))
        kw: dict[str, Any] = {}
        if rng.random() < 0.5:
            kw["s_stop"] = float(stop_s[-1] + rng.uniform(0.5, 100.0))
        if rng.random() < 0.5:
            kw["s_upper"] = stop_s[-1] + rng.uniform(0.5, 50.0) + rng.uniform(0.0, 20.0) * np.arange(81) * 0.1
        problem = replace(
            base, v_target=float(rng.uniform(0.0, 35.0)), jerk_max=float(rng.uniform(1, 5)), **kw
        )
        result = SOLVER.solve(problem)
        assert_valid(problem, result)
        assert result.info.usable
        solved += result.info.status is SolverStatus.SOLVED and result.max_violation <= 1e-6
    assert solved >= 54  # 90 %


def test_timing_is_reported() -> None:
    for solver in (SOLVER, SpeedSolver()):  # the QP built before, and built in this solve
        start = time.perf_counter()
        result = solver.solve(make_problem())
        elapsed_ms = (time.perf_counter() - start) * 1e3
        assert result.info.solve_time_ms > 0
        assert result.info.solve_time_ms + result.info.setup_time_ms <= elapsed_ms + 1e-6
        assert result.info.iterations > 0 and result.qp_solves >= 1
        assert result.info.extras["qp_solves"] == result.qp_solves
    assert result.info.setup_time_ms > 0.0


def test_running_out_of_iterations_is_max_iterations() -> None:
    """A sharp convex kink of the limit needs more SQP iterations than one: the best iterate comes back as
    ``max_iterations``, usable but not converged, with its cost and its violations."""
    problem = make_problem(
        limit_s=[0.0, 30.0, 32.0, 200.0], limit_v=[10.0, 10.0, 4.0, 4.0], v0=9.0, jerk_max=8.0, a_min=-8.0
    )
    result = SpeedSolver(max_iterations=1).solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.MAX_ITERATIONS
    assert result.info.usable and not result.info.converged
    assert result.info.extras["stop"] == "max_iterations" and result.info.extras["returned"] == "solution"
    assert result.qp_solves == 1 and result.info.objective is not None
    assert result.info.objective == pytest.approx(
        objective(problem, result.s, result.v, result.a, result.jerk)
    )
    converged = SpeedSolver().solve(problem)
    assert converged.info.status is SolverStatus.SOLVED and converged.info.extras["stop"] == "converged"
    assert converged.qp_solves > 1


def test_a_qp_stopped_early_is_used_but_never_solved(monkeypatch: pytest.MonkeyPatch) -> None:
    solve = SpeedQP.solve

    def early(self: SpeedQP) -> tuple[int, int]:
        return HpipmStatus.MAX_ITER, solve(self)[1]  # HPIPM's iterate, reported as cut short

    monkeypatch.setattr(SpeedQP, "solve", early)
    problem = make_problem()
    result = SpeedSolver().solve(problem)
    assert_valid(problem, result)
    assert result.info.status is SolverStatus.SOLVED_INACCURATE
    assert result.info.extras["early_qp_stops"] == result.qp_solves >= 1
    assert result.info.extras["hpipm_status"] == HpipmStatus.MAX_ITER


def test_looser_qp_residuals_and_restore_threshold_keep_a_valid_profile() -> None:
    """The pipeline's settings (residual 1e-6, no restart below 5 cm/s) still give a profile that meets
    the dynamics and keeps the limit to within that threshold."""
    problem = make_problem(
        limit_s=[0.0, 30.0, 32.0, 200.0], limit_v=[10.0, 10.0, 4.0, 4.0], v0=9.0, jerk_max=8.0, a_min=-8.0
    )
    fast = SpeedSolver(max_iterations=3, tolerance=1e-3, restore_violation=0.05, qp_residual=1e-6)
    result = fast.solve(problem)
    assert result.info.usable
    assert_valid(problem, result)
    assert limit_excess(problem, result) <= 0.05 + 1e-9
    with pytest.raises(ValueError, match="qp_residual"):
        SpeedSolver(qp_residual=0.0)
    with pytest.raises(ValueError, match="restore_violation"):
        SpeedSolver(restore_violation=-1.0)


def _at(k: int, value: float, free: float) -> np.ndarray:
    """A bound on knot ``k`` only (``free`` elsewhere)."""
    bound = np.full(81, free)
    bound[k] = value
    return bound


def test_a_goal_ahead_by_a_time_is_met_above_the_target_within_the_limit() -> None:
    # cruising at the target (10 m/s) is at 60 m at 6 s; the goal wants 85 m by then, the limit is 20
    # (at most about 90 m: a_max = 2, jerk 2)
    plain = make_problem(v0=10.0, v_target=10.0, limit_v=[20.0, 20.0])
    assert SOLVER.solve(plain).s[60] < 85.0 - 20.0
    problem = replace(plain, goal_lower=_at(60, 85.0, -math.inf))
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable and result.goal_violation < 0.05
    assert result.s[60] >= 85.0 - 0.05
    assert result.speed_violation <= 1e-6 and np.max(result.v) <= 20.0 + 1e-6
    assert result.max_violation == max(result.speed_violation, result.position_violation)  # not the goal's
    assert result.info.objective == pytest.approx(
        objective(problem, result.s, result.v, result.a, result.jerk)
    )


def test_a_goal_not_to_be_early_slows_down() -> None:
    # at 10 m/s the vehicle would be at 60 m by 6 s; the goal wants it no farther than 35 m then
    problem = make_problem(v0=10.0, v_target=10.0, goal_upper=_at(60, 35.0, math.inf))
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable and result.s[60] <= 35.0 + 0.05 and result.goal_violation < 0.05


def test_a_goal_out_of_reach_is_missed_and_reported_not_forced() -> None:
    # 200 m in 4 s from 10 m/s with a_max = 2 and a limit of 20 m/s cannot be done
    problem = make_problem(v0=10.0, v_target=10.0, limit_v=[20.0, 20.0], goal_lower=_at(40, 200.0, -math.inf))
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable
    assert result.speed_violation <= 1e-3  # the limit wins
    assert (
        result.goal_violation == pytest.approx(200.0 - result.s[40], abs=1e-6) and result.goal_violation > 100
    )
    assert "goal" in result.info.message


@pytest.mark.parametrize("other", ["s_stop", "s_upper", "s_lower"])
def test_every_other_bound_wins_over_a_goal(other: str) -> None:
    goal = {"goal_lower": _at(60, 95.0, -math.inf)}  # ahead, by 6 s
    if other == "s_lower":  # a follower against a goal not to be early: the follower wins
        goal = {"goal_upper": _at(60, 30.0, math.inf)}
    bound = {
        "s_stop": {"s_stop": 50.0},
        "s_upper": {"s_upper": 20.0 + 5.0 * _T},  # a leader at 5 m/s, 20 m ahead
        "s_lower": {"s_lower": _FOLLOWER},
    }[other]
    problem = make_problem(v0=10.0, v_target=10.0, limit_v=[20.0, 20.0], **bound, **goal)
    result = SOLVER.solve(problem)
    assert_valid(problem, result)
    assert result.info.usable
    assert result.position_violation <= 1e-3 and result.follower_violation <= 1e-3
    assert result.goal_violation > 5.0


def test_an_unused_goal_changes_nothing() -> None:
    solver = SpeedSolver()
    plain = make_problem(v0=15.0, limit_s=[0, 30, 40, 60, 70, 1000], limit_v=[20, 20, 8, 8, 20, 20])
    reference = solver.solve(plain)
    free = replace(plain, goal_lower=np.full(81, -math.inf), goal_upper=np.full(81, math.inf))
    result = solver.solve(free)
    assert np.array_equal(result.jerk, reference.jerk) and result.goal_violation == 0.0
    assert solver.build_count == 1
    loose = replace(plain, goal_lower=_at(80, -100.0, -math.inf))  # finite but never binding
    result = solver.solve(loose)
    assert solver.build_count == 2
    assert np.max(np.abs(result.s - reference.s)) < 1e-3 and result.goal_violation == 0.0  # QP tolerance


def _stop_excess(problem: SpeedProblem) -> float:
    """How far a full stop (:func:`braking_profile`) exceeds the limit [m/s]: no profile has to exceed it
    by more."""
    s, v, _ = integrate_jerk(problem.dt, problem.s0, problem.v0, problem.a0, braking_profile(problem))
    return float(np.max(v[1:] - speed_limit(problem, s[1:])[0]))


#: 20 m/s into a bend of 8 m/s from s = 19 to 45 m, then 23 m/s from 50 m on (the planner's budget: 2 QPs)
_BEND = {
    "v0": 20.0,
    "v_target": 20.0,
    "a_min": -8.0,
    "a_max": 3.0,
    "jerk_max": 30.0,
    "limit_s": [0.0, 15.0, 19.0, 45.0, 50.0, 1000.0],
    "limit_v": [20.0, 20.0, 8.0, 8.0, 23.0, 23.0],
}


@pytest.mark.parametrize(
    "beyond",
    [
        {"goal_lower": _at(20, 49.0, -math.inf)},  # a goal 49 m ahead by 2 s: past the bend, out of reach
        {"goal_lower": _at(20, 60.0, -math.inf)},
        {"s_lower": np.concatenate(([0.0], 20.0 * _T[1:]))},  # a follower that keeps 20 m/s through it
    ],
    ids=["goal-49m", "goal-60m", "follower"],
)
def test_a_lower_bound_out_of_reach_does_not_pull_the_profile_over_the_limit(beyond: dict[str, Any]) -> None:
    """A lower bound beyond a bend the vehicle cannot take at speed: the profile keeps the limit as well as
    a full stop does, within the planner's two QPs (the cold start once linearised the limit at the bound,
    where the vehicle cannot be, and the QP's slack then paid for 12.8 m/s over the limit in the bend)."""
    problem = make_problem(**_BEND, **beyond)
    plain = make_problem(**_BEND)
    for solver in (SpeedSolver(max_iterations=2, tolerance=1e-3, qp_residual=1e-6), SOLVER):
        result = solver.solve(problem)
        assert_valid(problem, result)
        assert result.info.usable
        # the bend's entry cannot be kept (a full stop exceeds the limit there too), but by no more
        assert _stop_excess(problem) > 1.0
        assert result.speed_violation <= _stop_excess(problem) + 1e-3
        assert result.speed_violation <= solver.solve(plain).speed_violation + 1e-3
    assert result.goal_violation > 5.0 or result.follower_violation > 5.0  # missed, and reported


def test_a_violation_a_full_stop_would_avoid_is_never_solved(monkeypatch: pytest.MonkeyPatch) -> None:
    """QPs that keep the speed (zero jerk) into the bend: the model converges at that profile, 12 m/s over
    the limit where a full stop needs 3.5. The SQP restarts from the stop (which cannot keep the limit
    either), and a violation it did not need is reported, never ``solved``."""

    def cruise(self: SpeedQP) -> tuple[int, int]:
        self.x.fill(0.0)
        self.lam_g.fill(0.0)
        return HpipmStatus.SUCCESS, 1

    monkeypatch.setattr(SpeedQP, "solve", cruise)
    problem = make_problem(**_BEND)
    needed = _stop_excess(problem)
    result = SpeedSolver(max_iterations=2).solve(problem)
    assert_valid(problem, result)
    assert np.all(result.jerk == 0.0) and result.speed_violation > needed + 5.0
    assert result.info.extras["stop"] == "converged" and result.info.extras["restarts"] == 1
    assert result.info.status is SolverStatus.SOLVED_INACCURATE and result.info.usable
    assert result.info.extras["violation_remains"] is True
    assert f"a full stop needs {needed:.3g}" in result.info.message


def _recorded(name: str) -> tuple[SpeedProblem, str]:
    """A speed problem a closed loop posed (``tests/data/speed/restarts.json``) and where it came from."""
    case = json.loads((Path(__file__).parents[1] / "data" / "speed" / "restarts.json").read_text())[name]
    fields = dict(case["problem"])
    weights = SpeedWeights(**fields.pop("weights"))
    arrays = {k: np.asarray(v) for k, v in fields.items() if isinstance(v, list)}
    return SpeedProblem(**{**fields, **arrays, "weights": weights}), str(case["what"])


#: the planner's speed solver (planner.config.SpeedConfig: two QPs)
_PLANNER = {"max_iterations": 2, "tolerance": 1e-3, "restore_violation": 0.05, "qp_residual": 1e-6}


def test_an_unfinished_run_is_continued_before_a_full_stop_can_beat_it() -> None:
    """US101 cycle 19: after its two QPs the first run is still on its way (1.1 m/s over the limit where
    a full stop keeps it), not in a local minimum. The restart from the stop converged in one QP to a
    profile that brakes to a standstill on the free road ahead and was kept (57 m in 8 s); the first run,
    given the restart's QPs, converges to one that drives on (86 m, ≥ 3.4 m/s), as eight QPs do. The
    leader's bound it cannot keep (0.47 m, the follower pressing from behind) is still reported."""
    problem, _ = _recorded("us101_cycle19")
    result = SpeedSolver(**_PLANNER).solve(problem)
    long = SpeedSolver(**{**_PLANNER, "max_iterations": 8}).solve(problem)
    assert_valid(problem, result)
    extras = result.info.extras
    assert extras["continued"] is True and extras["restarted"] is False
    assert result.s[-1] >= long.s[-1] - 0.5 and result.s[-1] > 80.0
    assert np.min(result.v[10:]) > 3.0  # no stop, no crawl
    assert result.qp_solves <= 6  # three runs of two QPs at most
    assert result.info.status is not SolverStatus.SOLVED and extras["violation_remains"] is True
    assert result.position_violation == pytest.approx(long.position_violation, abs=1e-3)
    assert result.position_violation > 0.4


def test_runs_are_compared_without_the_horizon_ends_allowance() -> None:
    """Moabit cycle 3: the converged profile (21 m, v_N 3.3 m/s) exceeds the horizon-end row by 0.097 m/s,
    within what convergence allows there; charged at the limit's weight, it made a crawl (8 m, which
    never exceeds the row) the better of the two by the penalty function, though the crawl's own cost is
    the higher. Compared without that allowance, the profile that drives on wins."""
    problem, _ = _recorded("moabit_cycle3")
    solver = SpeedSolver(**_PLANNER)
    drive = SpeedSolver(**{**_PLANNER, "max_iterations": 8}).solve(problem)
    crawl = SpeedSolver(**{**_PLANNER, "max_iterations": 1}).solve(replace(problem, v_target=1.2))
    assert drive.info.status is SolverStatus.SOLVED and drive.s[-1] > 20.0
    assert crawl.s[-1] < 10.0
    drive_it, crawl_it = (speed_sqp._iterate(problem, r.jerk) for r in (drive, crawl))
    assert drive.v[-1] > end_speed_limit(problem, float(drive.s[-1])) + 0.05  # inside the allowance
    assert drive_it.merit > crawl_it.merit  # the bias
    assert solver._judged(problem, drive_it) < solver._judged(problem, crawl_it)
    result = solver.solve(problem)
    assert result.s[-1] >= drive.s[-1] - 0.5 and not result.info.extras["restarted"]
