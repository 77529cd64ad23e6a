"""The speed problem: misuse is a ValueError naming the field, arrays are read-only copies, the boxes and
the speed floor follow the measured initial state, and the tables are computed once."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from solvers.speed_problem import MAX_STEPS, SpeedWeights
from tests.solvers.speed_cases import make_problem


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"dt": -0.1}, "dt"),
        ({"dt": 0.0}, "dt"),
        ({"dt": math.inf}, "dt"),
        ({"dt": "0.1"}, "dt"),
        ({"steps": 0}, "steps"),
        ({"steps": 10.0}, "steps"),
        ({"steps": True}, "steps"),
        ({"steps": MAX_STEPS + 1}, "steps"),
        ({"v0": -1.0}, "v0"),
        ({"v0": math.nan}, "v0"),
        ({"a0": math.inf}, "a0"),
        ({"s0": math.nan}, "s0"),
        ({"v_target": -1.0}, "v_target"),
        ({"a_min": 0.0}, "a_min"),
        ({"a_max": -1.0}, "a_max"),
        ({"jerk_max": 0.0}, "jerk_max"),
        ({"jerk_max": math.inf}, "jerk_max"),
        ({"s_stop": math.nan}, "s_stop"),
        ({"s_stop": -math.inf}, "s_stop"),
        ({"limit_s": []}, "limit_s"),
        ({"limit_s": [0.0, 0.0]}, "limit_s"),
        ({"limit_s": [[0.0, 1.0]]}, "limit_s"),
        ({"limit_s": [0.0, math.inf]}, "limit_s"),
        ({"limit_v": [30.0]}, "limit_v"),
        ({"limit_v": [30.0, math.nan]}, "limit_v"),
        ({"limit_v": [30.0, -1.0]}, "limit_v"),
        ({"limit_v": ["a", "b"]}, "limit_v"),
        ({"s_upper": np.zeros(80)}, "s_upper"),
        ({"s_upper": np.full(81, -math.inf)}, "s_upper"),
        ({"s_upper": np.full(81, math.nan)}, "s_upper"),
        ({"s_lower": np.zeros(80)}, "s_lower"),
        ({"s_lower": np.full(81, math.inf)}, "s_lower"),
        ({"s_lower": np.full(81, math.nan)}, "s_lower"),
        ({"s_lower": [[0.0] * 81]}, "s_lower"),
        ({"goal_lower": np.full(81, math.inf)}, "goal_lower"),
        ({"goal_upper": np.full(81, -math.inf)}, "goal_upper"),
        ({"goal_upper": np.full(80, 1.0)}, "goal_upper"),
        ({"goal_lower": np.full(81, 5.0), "goal_upper": np.full(81, 4.0)}, "goal_lower: above goal_upper"),
        ({"weights": {"speed": 1.0}}, "weights"),
    ],
)
def test_misuse_raises_value_error(change: dict[str, Any], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        make_problem(**change)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"speed": 0.0},
        {"jerk": -1.0},
        {"acceleration": math.nan},
        {"speed_violation": 0.0},
        {"jerk": True},
        {"follower_violation": 0.0},
        {"goal_late_violation": -1.0},
        {"goal_early_violation": 0.0},
    ],
)
def test_bad_weights_raise(kwargs: dict[str, Any]) -> None:
    with pytest.raises(ValueError, match="weights"):
        SpeedWeights(**kwargs)


def test_problem_arrays_are_read_only_copies() -> None:
    limit_v = np.array([30.0, 30.0])
    problem = make_problem(limit_v=limit_v, s_upper=np.full(81, np.inf))
    limit_v[0] = 1.0
    assert problem.limit_v[0] == 30.0
    with pytest.raises(ValueError):
        problem.limit_v[0] = 2.0
    assert problem.s_upper is not None and not problem.s_upper.flags.writeable


def test_boxes_open_only_as_far_as_an_outside_initial_acceleration_forces() -> None:
    problem = make_problem(a0=-7.0, jerk_max=1.0, steps=40)  # brakes harder than a_min = −5
    a_lo, a_hi = problem.accel_bounds()
    np.testing.assert_allclose(a_lo, np.minimum(-5.0, -7.0 + problem.t))
    np.testing.assert_allclose(a_hi, 2.0)
    v_lo, v_half = problem.speed_floor()
    assert v_lo.shape == (41,) and v_half.shape == (40,) and np.all(v_lo <= 0) and np.all(v_half <= 0)
    assert np.all(make_problem().speed_floor()[0] == 0.0)  # no reversing unless a0 < 0 forces it
    stops = make_problem(v0=0.5, a0=-3.0, jerk_max=1.0)  # a reversal is unavoidable
    assert np.min(stops.speed_floor()[0]) < 0


@pytest.mark.parametrize(
    ("v0", "a0", "jerk_max", "a_max"),
    [(0.5, -3.0, 1.0, 2.0), (0.346, -4.556, 30.0, 3.0), (0.0, -8.0, 30.0, 0.5), (0.05, -0.5, 2.0, 2.0)],
)
def test_a_forced_reversal_is_stopped_as_soon_as_the_limits_allow(
    v0: float, a0: float, jerk_max: float, a_max: float
) -> None:
    # the floor gives way to a0 < 0 only until the backward motion can be stopped: a floor that kept the
    # lowest speed let a stopped vehicle drift backwards for the rest of the horizon (0.2 m in 6 s at
    # 0.037 m/s, then the planned positions disagreed with the speeds)
    problem = make_problem(v0=v0, a0=a0, jerk_max=jerk_max, a_max=a_max, a_min=-8.0, steps=200)
    v_lo, v_half = problem.speed_floor()
    standing = np.abs(v_lo) <= 1e-9
    assert np.min(v_lo) < 0 and standing[-1] and abs(v_half[-1]) <= 1e-9
    # the release, then the push back to standstill: 0 from there on
    zero = int(np.argmax(standing & (np.arange(v_lo.size) > np.argmin(v_lo))))
    assert np.all(standing[zero:]) and np.all(np.abs(v_half[zero:]) <= 1e-9)
    # as soon as the limits allow: the continuous bang-bang return from the lowest speed, a grid step or two
    lowest = -float(np.min(v_lo))
    peak = min(math.sqrt(lowest * jerk_max), a_max)
    back = 2 * peak / jerk_max + max(lowest - peak**2 / jerk_max, 0.0) / peak
    assert problem.t[zero] - problem.t[int(np.argmin(v_lo))] <= back + 3 * problem.dt


def test_tables_are_computed_once_and_read_only() -> None:
    problem = make_problem(s_stop=50.0, s_lower=np.full(81, -math.inf))
    tables = problem.tables
    assert problem.tables is tables
    assert not tables.has_lower  # −inf everywhere: no lower bound
    np.testing.assert_array_equal(tables.s_bound, problem.s_bound())
    assert not tables.slopes.flags.writeable and not tables.piece_e.flags.writeable
    assert make_problem(s_lower=np.concatenate(([0.0], np.full(80, -1.0)))).tables.has_lower


def test_a_goal_is_in_the_tables_only_where_it_bounds() -> None:
    free = make_problem(goal_lower=np.full(81, -math.inf), goal_upper=np.full(81, math.inf))
    assert not free.tables.has_goal
    at_start = np.concatenate(([7.0], np.full(80, -math.inf)))  # entry 0 is not imposed
    assert not make_problem(goal_lower=at_start).tables.has_goal
    upper = np.full(81, math.inf)
    upper[60] = 70.0
    tables = make_problem(goal_upper=upper).tables
    assert tables.has_goal and tables.goal_hi[60] == 70.0 and np.all(np.isneginf(tables.goal_lo))
    assert not tables.goal_hi.flags.writeable
