"""The cost of a speed profile: the limit and its slopes, ``v_end`` (tabled, against brute force and a fine
grid), the violations and ``J``."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from solvers.speed_cost import end_speed_limit, end_terms, objective, speed_limit, violations
from solvers.speed_problem import SpeedProblem
from tests.solvers.speed_cases import make_problem


def _reference_end_terms(problem: SpeedProblem, s: float) -> tuple[float | None, float | None, float | None]:
    """``(energy, rate, bound)`` of ``v_end``'s terms at ``s`` by brute force: every candidate ``s′`` ahead
    of ``s`` built and compared on each call (the implementation before the tables)."""
    b = -0.5 * problem.a_min
    c = b * b / (2.0 * problem.jerk_max)
    stop = problem.s_stop
    rate = bound = None
    if problem.s_upper is not None and math.isfinite(problem.s_upper[-1]):
        bound, before = float(problem.s_upper[-1]), float(problem.s_upper[-2])
        rate = max((bound - before) / problem.dt, 0.0) if math.isfinite(before) else 0.0
    if s >= stop:
        return (0.0 + c) ** 2 + 2.0 * b * stop, rate, bound
    xs, ys = problem.limit_s, problem.limit_v
    ahead = (xs > s) & (xs < stop)
    cand_s = [np.array([s]), xs[ahead]]
    cand_v = [np.array([float(np.interp(s, xs, ys))]), ys[ahead]]
    if math.isfinite(stop):
        cand_s.append(np.array([stop]))
        cand_v.append(np.array([0.0]))
    if xs.size >= 2:
        m = np.diff(ys) / np.diff(xs)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            x_star = xs[:-1] + (-b / m - c - ys[:-1]) / m
        inside = (m < 0) & (x_star > np.maximum(xs[:-1], s)) & (x_star < np.minimum(xs[1:], stop))
        cand_s.append(x_star[inside])
        cand_v.append(ys[:-1][inside] + m[inside] * (x_star[inside] - xs[:-1][inside]))
    energy = (np.maximum(np.concatenate(cand_v), 0.0) + c) ** 2 + 2.0 * b * np.concatenate(cand_s)
    best = int(np.argmin(energy))
    return (None if best == 0 else float(energy[best])), rate, bound


def _reference_end_speed_limit(problem: SpeedProblem, s: float) -> float:
    energy, rate, bound = _reference_end_terms(problem, s)
    b = -0.5 * problem.a_min
    c = b * b / (2.0 * problem.jerk_max)
    if energy is None:
        value = float(np.interp(s, problem.limit_s, problem.limit_v))
    else:
        value = math.sqrt(max(energy - 2.0 * b * s, 0.0)) - c
    if rate is not None and bound is not None:
        value = min(value, rate + math.sqrt(c * c + 2.0 * b * max(bound - s, 0.0)) - c)
    return max(value, 0.0)


@st.composite
def limit_problems(draw: st.DrawFn) -> tuple[SpeedProblem, list[float]]:
    """Limits with steep falls (stationary points), flat stretches and zeros; stops and moving bounds; and
    query points off, on and around the breakpoints, the stop and the stationary points."""
    points = draw(st.integers(min_value=1, max_value=10))
    gaps = draw(st.lists(st.floats(0.05, 80.0), min_size=points, max_size=points))
    limit_s = np.cumsum(gaps) - draw(st.floats(0.0, 50.0))
    speeds = st.one_of(st.floats(0.0, 40.0), st.sampled_from([0.0, 5.0, 30.0]))
    limit_v = np.array(draw(st.lists(speeds, min_size=points, max_size=points)))
    kw: dict[str, Any] = {}
    if draw(st.booleans()):
        kw["s_stop"] = draw(st.one_of(st.floats(-60.0, 900.0), st.sampled_from(limit_s.tolist())))
    steps = 20
    if draw(st.booleans()):
        t = np.arange(steps + 1) * 0.1
        s_upper = draw(st.floats(-50.0, 600.0)) + draw(st.floats(0.0, 30.0)) * t
        if draw(st.booleans()):
            s_upper[-2] = np.inf
        kw["s_upper"] = s_upper
    problem = make_problem(
        steps=steps,
        limit_s=limit_s,
        limit_v=limit_v,
        a_min=draw(st.floats(-10.0, -0.5)),
        jerk_max=draw(st.floats(0.2, 40.0)),
        **kw,
    )
    tables = problem.tables
    special = [*limit_s.tolist(), *tables.end_s.tolist(), problem.s_stop]
    special = [x for x in special if math.isfinite(x)]
    near = [x + dx for x in special for dx in (-1e-9, 1e-9)]
    queries = draw(
        st.lists(
            st.one_of(st.floats(-100.0, 1000.0), st.sampled_from(special + near)), min_size=1, max_size=12
        )
    )
    return problem, queries


@settings(max_examples=300, deadline=None)
@given(limit_problems())
def test_property_tabled_limits_equal_the_brute_force_ones(case: tuple[SpeedProblem, list[float]]) -> None:
    problem, queries = case
    b = -0.5 * problem.a_min
    c = b * b / (2.0 * problem.jerk_max)
    for s in queries:
        terms = end_terms(problem, s)
        energy, rate, bound = _reference_end_terms(problem, s)
        assert (terms.energy is None) == (energy is None)
        if energy is not None:
            assert terms.energy == pytest.approx(energy, rel=1e-12, abs=1e-12)
        assert (terms.rate, terms.bound, terms.b, terms.c) == (rate, bound, b, c)
        value = end_speed_limit(problem, s)
        assert value == pytest.approx(_reference_end_speed_limit(problem, s), rel=1e-12, abs=1e-12)
        # and it is the minimum: no s′ ≥ s on a fine grid asks for less (v* = v_lim before s_stop, then 0)
        grid = np.concatenate([[s], np.linspace(s, max(s, problem.limit_s[-1]) + 50.0, 2001)])
        v_star = np.where(grid < problem.s_stop, np.interp(grid, problem.limit_s, problem.limit_v), 0.0)
        if math.isfinite(problem.s_stop) and problem.s_stop >= s:
            grid, v_star = np.append(grid, problem.s_stop), np.append(v_star, 0.0)
        reach = np.sqrt((v_star + c) ** 2 + 2.0 * b * (grid - s)) - c
        assert value <= float(np.min(reach)) + 1e-9 * (1.0 + float(np.min(reach)))
    # the slope of the segment holding each point, 0 beyond the ends (at a breakpoint: the segment ahead)
    xs, ys = problem.limit_s, problem.limit_v
    points = np.array(queries)
    value, slope = speed_limit(problem, points)
    assert np.array_equal(value, np.interp(points, xs, ys))
    if xs.size >= 2:
        segment = np.clip(np.searchsorted(xs, points, side="right") - 1, 0, xs.size - 2)
        expected = (ys[segment + 1] - ys[segment]) / (xs[segment + 1] - xs[segment])
        expected = np.where((points < xs[0]) | (points >= xs[-1]), 0.0, expected)
    else:
        expected = np.zeros_like(points)
    assert np.array_equal(slope, expected)


def test_violations_and_objective_of_a_profile() -> None:
    t = np.arange(81) * 0.1
    problem = make_problem(limit_v=[12.0, 12.0], s_stop=60.0, s_lower=-5.0 + 14.0 * t)
    v = np.full(81, 13.0)  # 1 m/s above the limit throughout
    s = 13.0 * t
    a = np.zeros(81)
    e_v, e_s, e_l = violations(problem, s, v)
    assert e_v[0] == e_s[0] == e_l[0] == 0.0  # the initial state is a measurement
    np.testing.assert_allclose(e_v[1:], 1.0)
    np.testing.assert_allclose(e_s, np.maximum(s - 60.0, 0.0))
    np.testing.assert_allclose(e_l[1:], np.maximum(-5.0 + 14.0 * t[1:] - s[1:], 0.0))
    w = problem.weights
    end = end_speed_limit(problem, float(s[-1]))  # v_end at the horizon's end: 0 past the stop
    e_end = max(13.0 - end, 0.0)
    expected = (
        0.1 * w.speed * 80 * (13.0 - 15.0) ** 2
        + w.speed_violation * (79 * 1.01 + e_end + 0.01 * e_end**2)
        + w.position_violation * np.sum(e_s + 0.01 * e_s**2)
        + w.follower_violation * np.sum(e_l + 0.01 * e_l**2)
    )
    assert objective(problem, s, v, a, np.zeros(80)) == pytest.approx(expected, rel=1e-12)
