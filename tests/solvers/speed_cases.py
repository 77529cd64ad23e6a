"""Speed problems and checks shared by the speed tests."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from solvers.speed_cost import speed_limit
from solvers.speed_problem import SpeedProblem, SpeedResult


def make_problem(**kw: Any) -> SpeedProblem:
    """80 steps of 0.1 s, 10 → 15 m/s on a 30 m/s road; ``kw`` overrides."""
    args: dict[str, Any] = {
        "dt": 0.1,
        "steps": 80,
        "v0": 10.0,
        "limit_s": [0.0, 1000.0],
        "limit_v": [30.0, 30.0],
        "v_target": 15.0,
        "a_min": -5.0,
        "a_max": 2.0,
        "jerk_max": 2.0,
    }
    args.update(kw)
    return SpeedProblem(**args)


def assert_valid(problem: SpeedProblem, result: SpeedResult) -> None:
    """NaN-free, shapes, initial state, exact dynamics, jerk and acceleration boxes, speed floor."""
    n, dt = problem.steps, problem.dt
    for name in ("t", "s", "v", "a"):
        values = getattr(result, name)
        assert values.shape == (n + 1,), name
        assert np.all(np.isfinite(values)), name
    assert result.jerk.shape == (n,) and np.all(np.isfinite(result.jerk))
    assert np.allclose(result.t, np.arange(n + 1) * dt)
    s, v, a, j = result.s, result.v, result.a, result.jerk
    assert (s[0], v[0], a[0]) == (problem.s0, problem.v0, problem.a0)
    assert np.max(np.abs(a[1:] - a[:-1] - j * dt)) < 1e-6
    assert np.max(np.abs(v[1:] - v[:-1] - a[:-1] * dt - j * dt**2 / 2)) < 1e-6
    assert np.max(np.abs(s[1:] - s[:-1] - v[:-1] * dt - a[:-1] * dt**2 / 2 - j * dt**3 / 6)) < 1e-6
    assert np.max(np.abs(j)) <= problem.jerk_max * (1 + 1e-9)
    a_lo, a_hi = problem.accel_bounds()
    assert np.all(a[1:] >= a_lo[1:] - 1e-6) and np.all(a[1:] <= a_hi[1:] + 1e-6)
    floor, _ = problem.speed_floor()
    assert np.all(v >= floor - 1e-6)
    assert math.isfinite(result.max_violation) and result.max_violation >= 0
    assert result.max_violation == max(
        result.speed_violation, result.position_violation, result.follower_violation
    )
    if problem.s_lower is None:
        assert result.follower_violation == 0.0
    assert result.info.max_violation == result.max_violation


def limit_excess(problem: SpeedProblem, result: SpeedResult) -> float:
    limit, _ = speed_limit(problem, result.s)
    return float(np.max(result.v[1:] - limit[1:]))
