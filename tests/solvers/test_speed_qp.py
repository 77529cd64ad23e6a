"""The QP of one SQP iteration: the buffered evaluation equals CasADi's call, the named columns are the
state and inputs they say, HPIPM's flags are named."""

from __future__ import annotations

import multiprocessing
import threading
from typing import Any

import casadi as ca
import numpy as np
import pytest

from solvers.speed_problem import PIECES, SpeedProblem, SpeedWeights
from solvers.speed_qp import (
    CASADI_LOCK,
    COL_A,
    COL_JERK,
    COL_S,
    COL_SIGMA_S,
    COL_V,
    P_END_CURVATURE,
    P_V_HAT,
    P_V_TARGET,
    ROW_LIMIT,
    HpipmSettings,
    HpipmStatus,
    SpeedQP,
    build_speed_qp,
    local_model,
)
from tests.solvers.speed_cases import make_problem

_LIMIT = {"limit_s": [0, 30, 40, 60, 70, 1000], "limit_v": [20, 20, 8, 8, 20, 20]}


def _qp(problem: SpeedProblem, settings: HpipmSettings | None = None) -> SpeedQP:
    tables = problem.tables
    qp = build_speed_qp(
        problem.steps, problem.dt, problem.weights, tables.has_lower, settings, goal=tables.has_goal
    )
    qp.set_bounds(problem)
    qp.p[P_V_TARGET] = problem.v_target
    return qp


def _guess(problem: SpeedProblem) -> np.ndarray:
    """``s − s0`` of cruising at ``v0``, held at the stop (a point to linearise at)."""
    return np.minimum(problem.v0 * problem.t, problem.s_stop - problem.s0)


@pytest.mark.parametrize(("lower", "goal"), [(False, False), (True, False), (False, True), (True, True)])
def test_qps_on_bound_arrays_agree_with_casadis_ordinary_call(lower: bool, goal: bool) -> None:
    """One QP after another through the buffer, as the SQP does, against CasADi's call with the same
    numbers (a buffer evaluated again can carry state over: CasADi 3.8.0 summed the solutions); with a
    lower bound or a goal's bounds, the QP with their slacks."""
    s_lower = -10.0 + 14.0 * np.arange(81) * 0.1 if lower else None
    goal_lower = goal_upper = None
    if goal:
        goal_lower, goal_upper = np.full(81, -np.inf), np.full(81, np.inf)
        goal_lower[60], goal_upper[30] = 100.0, 40.0
    problem = make_problem(
        v0=15.0, s_stop=120.0, s_lower=s_lower, goal_lower=goal_lower, goal_upper=goal_upper, **_LIMIT
    )
    qp = _qp(problem)
    s_bar, v_end = _guess(problem), problem.v0
    for shift, curvature in ((0.0, 0.0), (5.0, 0.3), (0.0, 0.0)):
        e, d, _, _ = local_model(problem, s_bar + shift, v_end)
        qp.limit_rows[...] = e
        qp.slopes[...] = d
        qp.p[P_END_CURVATURE], qp.p[P_V_HAT] = curvature, v_end
        flag, iterations = qp.solve()
        assert qp.x.size == (6 + lower + 2 * goal) * problem.steps + 3
        inputs = {name: getattr(qp, name).copy() for name in ("p", "lbx", "ubx", "lbg", "ubg")}
        reference = qp.function(**inputs)
        stats = qp.function.stats()
        assert (flag, iterations) == (stats["return_status"], stats["iter_count"])
        assert flag == HpipmStatus.SUCCESS
        assert np.array_equal(qp.x, reference["x"].full().ravel())
        assert np.array_equal(qp.lam_g, reference["lam_g"].full().ravel())


def _solved_at_guess(problem: SpeedProblem) -> SpeedQP:
    """The problem's QP solved once, linearised at :func:`_guess` (it must succeed)."""
    qp = _qp(problem)
    e, d, _, _ = local_model(problem, _guess(problem), problem.v0)
    qp.limit_rows[...] = e
    qp.slopes[...] = d
    qp.p[P_V_HAT] = problem.v0
    flag, _ = qp.solve()
    assert flag == HpipmStatus.SUCCESS
    return qp


def test_named_columns_and_rows_are_what_they_say() -> None:
    problem = make_problem(v0=15.0, s_stop=60.0, **_LIMIT)
    qp = _solved_at_guess(problem)
    n, dt = problem.steps, problem.dt
    stages = np.vstack([qp.x[: qp.width * n].reshape(n, qp.width), np.append(qp.x[-3:], [0.0] * 3)])
    s, v, a, j = (stages[:, col] for col in (COL_S, COL_V, COL_A, COL_JERK))
    assert (s[0], v[0], a[0]) == pytest.approx((0.0, problem.v0, problem.a0), abs=1e-9)
    np.testing.assert_allclose(a[1:], a[:-1] + j[:-1] * dt, atol=1e-6)  # the dynamics, column by column
    np.testing.assert_allclose(v[1:], v[:-1] + a[:-1] * dt + j[:-1] * dt**2 / 2, atol=1e-6)
    np.testing.assert_allclose(
        s[1:], s[:-1] + v[:-1] * dt + a[:-1] * dt**2 / 2 + j[:-1] * dt**3 / 6, atol=1e-6
    )
    assert np.max(s) <= 60.0 + np.max(stages[:, COL_SIGMA_S]) + 1e-6  # the stop, with its slack
    np.testing.assert_array_equal(qp.jerk, j[:-1])
    end = qp.rows * (n - 1) + ROW_LIMIT
    np.testing.assert_array_equal(qp.end_multipliers, qp.lam_g[end : end + PIECES])


@pytest.mark.parametrize("aim", ["early", "late"])
def test_the_goal_slack_columns_measure_what_the_goal_rows_miss(aim: str) -> None:
    # on a free road: not past 27 m at 3 s (knot 30), which can be kept; or at least 150 m at 8 s, which
    # cannot (a_max = 2, jerk 2)
    upper, lower = np.full(81, np.inf), np.full(81, -np.inf)
    if aim == "early":
        upper[30] = 27.0
    else:
        lower[80] = 150.0
    problem = make_problem(v0=10.0, v_target=10.0, goal_upper=upper, goal_lower=lower)
    qp = _solved_at_guess(problem)
    assert qp.col_goal == qp.width - 2 and qp.row_goal == qp.rows - 2
    n = problem.steps
    stages = qp.x[: qp.width * n].reshape(n, qp.width)  # stage k holds the slacks of knot k + 1
    s = np.append(stages[:, COL_S], qp.x[-3])
    late, early = stages[:, qp.col_goal], stages[:, qp.col_goal + 1]
    assert np.all(late >= -1e-9) and np.all(early >= -1e-9)
    if aim == "early":
        assert s[30] <= 27.0 + 1e-3 and np.max(early) < 1e-3 and np.max(late) < 1e-6  # kept
    else:
        assert s[80] < 150.0 - 10.0 and late[79] == pytest.approx(150.0 - s[80], abs=1e-4)  # missed
        assert np.max(early) < 1e-6


def test_an_iteration_cap_is_hpipms_max_iter_flag() -> None:
    problem = make_problem(v0=15.0, s_stop=60.0, **_LIMIT)
    qp = _qp(problem, HpipmSettings(iter_max=2))
    e, d, _, _ = local_model(problem, _guess(problem), problem.v0)
    qp.limit_rows[...] = e
    qp.slopes[...] = d
    flag, iterations = qp.solve()
    assert (flag, iterations) == (HpipmStatus.MAX_ITER, 2)


def test_casadi_qps_are_built_holding_the_lock(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """CasADi's symbols and the making of its functions are not thread-safe (two threads building QPs at
    once crashed the process): a QP is built holding ``CASADI_LOCK``, which another thread then cannot
    take; once built and solved, the lock is free."""
    taken: list[bool] = []

    def other_thread_takes() -> None:
        def attempt() -> None:
            got = CASADI_LOCK.acquire(blocking=False)
            taken.append(got)
            if got:
                CASADI_LOCK.release()

        thread = threading.Thread(target=attempt)
        thread.start()
        thread.join()

    qpsol = ca.qpsol

    def watched(*args: Any, **kwargs: Any) -> Any:
        other_thread_takes()
        return qpsol(*args, **kwargs)

    monkeypatch.setattr(ca, "qpsol", watched)
    qp = build_speed_qp(10, 0.1, SpeedWeights())
    assert taken == [False]
    qp.solve()
    other_thread_takes()
    assert taken == [False, True]


def test_a_process_forked_while_another_thread_builds_can_build() -> None:
    """A fork copies ``CASADI_LOCK`` held by another thread, not the thread that would release it: the
    child gets a free lock (else its first build would wait for ever)."""
    held, release = threading.Event(), threading.Event()

    def holder() -> None:
        with CASADI_LOCK:
            held.set()
            release.wait(timeout=60)

    thread = threading.Thread(target=holder)
    thread.start()
    try:
        assert held.wait(timeout=10)
        child = multiprocessing.get_context("fork").Process(
            target=lambda: build_speed_qp(5, 0.1, SpeedWeights()).solve()
        )
        child.start()
        child.join(timeout=60)
        if child.exitcode is None:
            child.kill()
        assert child.exitcode == 0
    finally:
        release.set()
        thread.join()
