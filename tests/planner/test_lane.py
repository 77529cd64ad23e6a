"""The lane as bounds on the vehicle centre's offset, and the corridor in which obstacles matter."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planner.config import DEFAULT_CONFIG
from planner.lane import corridor_width, lane_bounds
from planner.problem import Ego, Lane, PlanningProblem, Vehicle
from planner.reference import build_reference
from planner.roads import straight

ROAD = straight(100.0, step=10.0)
REF = build_reference(ROAD)


def test_the_bounds_are_the_widths_less_half_the_vehicle_and_the_margin() -> None:
    s = np.linspace(0.0, 100.0, 11)
    bounds = lane_bounds(REF, Lane(3.0, 2.0), s, half_width=0.9, margin=0.2)
    np.testing.assert_allclose(bounds.upper, 1.9)
    np.testing.assert_allclose(bounds.lower, -0.9)
    assert bounds.s is s


def test_where_the_lane_is_too_narrow_both_bounds_meet_in_its_middle() -> None:
    left = np.where(ROAD[:, 0] > 45.0, 0.5, 3.0)  # per reference point
    s = np.array([10.0, 80.0])
    bounds = lane_bounds(REF, Lane(left, 1.0), s, half_width=0.9, margin=0.2)
    np.testing.assert_allclose(bounds.upper, [1.9, -0.25])
    np.testing.assert_allclose(bounds.lower, [-(1.0 - 1.1), -0.25])


def test_the_corridor_is_the_widest_side_the_vehicle_length_and_a_spare() -> None:
    problem = PlanningProblem(
        ROAD, Lane(np.linspace(2.0, 5.0, ROAD.shape[0]), 3.0), Ego(10.0, 0.0, 0.0), (), Vehicle()
    )
    assert corridor_width(problem) == 5.0 + 4.5 + 1.0
    assert corridor_width(problem, replace(DEFAULT_CONFIG, corridor_spare=0.0)) == 5.0 + 4.5
