"""Analytic speed profiles: a full stop and keeping the speed, within the jerk limit."""

from __future__ import annotations

import numpy as np
import pytest

from solvers.speed_problem import integrate_jerk
from solvers.speed_profiles import braking_profile, cruise_profile
from tests.solvers.speed_cases import make_problem


@pytest.mark.parametrize(
    ("v0", "a0", "jerk_max", "dt"),
    [
        (20.0, 0.0, 2.0, 0.1),
        (30.0, 1.5, 1.0, 0.2),
        (3.0, -4.5, 6.0, 0.05),
        (0.4, -3.6, 1.0, 0.1),
        (0.0, 0.0, 2.0, 0.1),
    ],
)
def test_braking_profile_stops_within_the_jerk_limit(
    v0: float, a0: float, jerk_max: float, dt: float
) -> None:
    problem = make_problem(v0=v0, a0=a0, jerk_max=jerk_max, dt=dt, steps=400)
    jerk = braking_profile(problem)
    _, v, a = integrate_jerk(dt, 0.0, v0, a0, jerk)
    assert np.max(np.abs(jerk)) <= jerk_max * (1 + 1e-9)
    assert abs(v[-1]) < 1e-9 and abs(a[-1]) < 1e-9
    floor, _ = problem.speed_floor()
    assert np.all(v >= floor - 1e-9)
    if a0 >= 0:
        assert np.all(v >= -1e-9)
    if v0 >= 20:
        assert np.min(a) == pytest.approx(problem.a_min)  # full braking


def test_cruise_profile_releases_the_acceleration_and_keeps_the_speed() -> None:
    problem = make_problem(a0=-3.0, jerk_max=10.0)
    jerk = cruise_profile(problem)
    _, v, a = integrate_jerk(problem.dt, 0.0, problem.v0, problem.a0, jerk)
    assert np.max(np.abs(jerk)) <= problem.jerk_max * (1 + 1e-12)
    assert np.all(a[:3] < 0) and np.all(np.abs(a[3:]) < 1e-12)  # released in 0.3 s at the jerk limit
    assert np.allclose(v[3:], 10.0 - 0.45)
    # releasing the brake would end below standstill: it stops instead
    slow = make_problem(v0=0.3, a0=-3.0, jerk_max=10.0)
    assert np.array_equal(cruise_profile(slow), braking_profile(slow))
