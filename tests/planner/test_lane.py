"""The lane as bounds on the vehicle centre's offset, and the corridor in which obstacles matter."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planner.config import DEFAULT_CONFIG
from planner.lane import Corridor, corridor_width, lane_bounds
from planner.problem import Ego, Lane, PlanningProblem, Road, Vehicle
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


def test_a_corridor_is_the_road_on_its_side_over_its_stretch_the_lane_elsewhere() -> None:
    road = Road(5.0, 3.0)
    corridor = Corridor(1.5, 1.5, road, "left", start=40.0, end=50.0, ramp_in=10.0, ramp_out=20.0)
    s = np.array([0.0, 29.0, 30.0, 35.0, 40.0, 45.0, 50.0, 60.0, 70.0, 71.0, 100.0])
    left, right = corridor.widths(REF, s)
    np.testing.assert_allclose(left, [1.5, 1.5, 1.5, 3.25, 5.0, 5.0, 5.0, 3.25, 1.5, 1.5, 1.5])
    np.testing.assert_allclose(right, 1.5)  # the other side stays the lane's
    mirrored = replace(corridor, side="right")
    left, right = mirrored.widths(REF, s)
    np.testing.assert_allclose(left, 1.5)
    np.testing.assert_allclose(right[[0, 3, 5, 7, 10]], [1.5, 2.25, 3.0, 2.25, 1.5])
    # a step where a ramp is 0 (an ego already outside its lane)
    step = replace(corridor, ramp_in=0.0)
    np.testing.assert_allclose(step.widths(REF, np.array([39.9, 40.0]))[0], [1.5, 5.0])
    # lane bounds read the corridor as a lane
    bounds = lane_bounds(REF, corridor, np.array([0.0, 45.0]), half_width=0.9, margin=0.2)
    np.testing.assert_allclose(bounds.upper, [0.4, 3.9])


def test_the_corridor_width_reaches_the_road_when_asked() -> None:
    problem = PlanningProblem(ROAD, Lane(1.75, 1.75), Ego(0.0, 0.0, 0.0), road=Road(9.0, 1.75))
    assert corridor_width(problem, road=True) - corridor_width(problem) == pytest.approx(9.0 - 1.75)
