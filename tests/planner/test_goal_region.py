"""Where a goal's region lies: inside (boundary included), on the reference (the lane's band for the centre,
tiny and far regions, curves) and along a path (a car's centre ahead of its rear axle)."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.frenet import to_frenet
from planner.goal import GoalCircle, GoalPolygon
from planner.goal_region import (
    OUTLINE_STEP,
    _mapped_outline,
    along_path,
    centre_band,
    distance_to,
    inside,
    on_reference,
    region_shape,
)
from planner.problem import Lane, Vehicle
from planner.reference import build_reference
from planner.roads import arc, straight
from planner.trajectory import frenet_path
from tests.planner.goal_cases import box, inside_convex

STRAIGHT = build_reference(straight(200.0, step=5.0))
LANE = Lane(3.5, 3.5)


def test_inside_counts_the_boundary() -> None:
    square = box(0.0, 2.0, 0.0, 2.0)
    x = np.array([1.0, 0.0, 2.0, 2.0 + 1e-9, 1.0, 3.0])
    y = np.array([1.0, 1.0, 2.0, 1.0, -1e-9, 3.0])
    assert inside(square, x, y).tolist() == [True, True, True, False, False, False]
    disc = GoalCircle(np.array([5.0, 5.0]), 2.0)
    assert inside(disc, [5.0, 7.0, 7.0 + 1e-9], [5.0, 5.0, 5.0]).tolist() == [True, True, False]
    assert distance_to(disc, 10.0, 5.0) == pytest.approx(3.0)
    assert distance_to(square, 1.0, 1.0) == 0.0 and distance_to(square, 5.0, 1.0) == pytest.approx(3.0)


def test_a_self_crossing_outline_is_repaired_not_refused() -> None:
    # two unequal lobes crossing at (4/3, 2/3)
    bow_tie = GoalPolygon(np.array([[0.0, 0.0], [4.0, 2.0], [4.0, 0.0], [0.0, 1.0]]))
    assert inside(bow_tie, [0.3, 3.5, 1.0], [0.5, 1.0, 1.5]).tolist() == [True, True, False]


@settings(max_examples=60, deadline=None)
@given(
    x0=st.floats(-5.0, 5.0),
    width=st.floats(0.1, 8.0),
    y0=st.floats(-5.0, 5.0),
    height=st.floats(0.1, 8.0),
    points=st.lists(st.tuples(st.floats(-15.0, 15.0), st.floats(-15.0, 15.0)), min_size=1, max_size=20),
)
def test_inside_agrees_with_an_independent_test_on_boxes(
    x0: float, width: float, y0: float, height: float, points: list[tuple[float, float]]
) -> None:
    region = box(x0, x0 + width, y0, y0 + height)
    x, y = np.array(points).T
    clear = np.minimum.reduce(
        [np.abs(x - x0), np.abs(x - x0 - width), np.abs(y - y0), np.abs(y - y0 - height)]
    )
    decided = clear > 1e-6  # on the boundary within rounding either answer is fine
    assert np.array_equal(inside(region, x, y)[decided], inside_convex(region.polygon, x, y)[decided])


def test_a_region_across_the_lane_is_mapped_to_the_band_for_the_centre() -> None:
    region = on_reference(STRAIGHT, box(60.0, 70.0, -10.0, 10.0), LANE, Vehicle(), 0.2, 190.0)
    assert (region.s_min, region.s_max) == pytest.approx((60.0, 70.0))
    assert region.reachable and region.s_in == pytest.approx(60.0) and region.s_out == pytest.approx(70.0)
    band = 3.5 - 0.9 - 0.2  # the lane less half the width and the margin
    np.testing.assert_allclose(region.d_low, -band)
    np.testing.assert_allclose(region.d_high, band)


def test_a_region_beside_the_reference_keeps_its_own_offsets() -> None:
    region = on_reference(STRAIGHT, box(60.0, 70.0, 1.0, 5.0), LANE, Vehicle(), 0.2, 190.0)
    on = region.on_lane
    assert on.all()
    assert np.all(region.d_low[on] >= 1.0 - 1e-9) and np.all(region.d_low[on] <= 1.0 + 0.1)  # the grid's step
    np.testing.assert_allclose(region.d_high[on], 2.4)


def test_a_tiny_region_in_the_lane_is_found_and_one_outside_it_is_not() -> None:
    tiny = on_reference(STRAIGHT, GoalCircle(np.array([80.0, 1.03]), 0.01), LANE, Vehicle(), 0.2, 190.0)
    assert tiny.reachable and np.all(np.abs(tiny.d_low[tiny.on_lane] - 1.03) <= 0.011)
    for centre in ([80.0, 8.0], [80.0, 2.6], [195.0, 0.0]):  # off the lane, beyond the band, past the end
        far = on_reference(STRAIGHT, GoalCircle(np.array(centre), 0.1), LANE, Vehicle(), 0.2, 190.0)
        assert not far.reachable, centre
        assert np.isnan(far.s_in) and np.isnan(far.s_out)


def test_on_a_curve_the_band_keeps_the_turning_limit() -> None:
    ref = build_reference(arc(6.0, np.pi, step=0.5))  # a left half-circle of radius 6 m
    wide = Lane(left_width=8.0, right_width=3.0)
    vehicle = Vehicle(max_curvature=0.25)  # turns on 4 m at least
    s = np.linspace(2.0, 16.0, 8)
    lower, upper = centre_band(ref, wide, s, vehicle, 0.2)
    assert np.all(upper <= 6.0 - 4.0 + 5e-3)  # d ≤ 1/κ − 1/κ_max (κ of the fitted spline)
    np.testing.assert_allclose(lower, -(3.0 - 0.9 - 0.2))
    region = on_reference(ref, GoalCircle(np.array([0.0, 6.0]), 1.0), wide, vehicle, 0.2, ref.length)
    assert not region.reachable  # the centre of the circle: the vehicle cannot turn that tightly


def test_the_first_stretch_of_a_path_inside_is_the_centres() -> None:
    s = np.linspace(0.0, 100.0, 201)
    path = frenet_path(STRAIGHT, s, 0 * s, 0 * s, 0 * s)
    region = box(40.0, 50.0, -1.0, 1.0)
    assert along_path(path, region, Vehicle(), (40.0, 50.0)) == pytest.approx((40.0, 50.0), abs=0.06)
    car = Vehicle(wheelbase=2.7, rear_axle_offset=1.35)  # the centre 1.35 m ahead of the rear axle
    assert along_path(path, region, car, (40.0, 50.0)) == pytest.approx((40.0 - 1.35, 50.0 - 1.35), abs=0.06)
    assert along_path(path, box(40.0, 50.0, 2.0, 3.0), Vehicle(), (40.0, 50.0)) is None  # beside it
    assert along_path(path, box(140.0, 150.0, -1.0, 1.0), Vehicle(), (140.0, 150.0)) is None  # beyond it


def test_the_same_region_on_the_same_reference_is_mapped_once_and_exactly_as_anew() -> None:
    """A closed loop asks for the same region on the same (cached) reference every cycle: its outline's
    TransF-κ coordinates are kept, the same numbers as mapped anew; any other region (a centre of -0.0
    rather than 0.0 included) or reference is mapped again."""
    ref = build_reference(arc(40.0, 1.0, step=2.0))
    circle = GoalCircle(np.array([0.0, 40.0]), 2.0)
    first = _mapped_outline(ref, circle)
    again = _mapped_outline(ref, GoalCircle(np.array([0.0, 40.0]), 2.0))  # another object, same numbers
    assert again is first
    shape = region_shape(circle)
    outline = shapely.get_coordinates(shapely.segmentize(shape.boundary, OUTLINE_STEP))
    anew = to_frenet(ref, np.vstack((outline, np.asarray(shape.representative_point().coords))))
    assert np.array_equal(first.s, anew.s) and np.array_equal(first.d, anew.d)
    assert not first.s.flags.writeable
    assert _mapped_outline(ref, GoalCircle(np.array([-0.0, 40.0]), 2.0)) is not first
    assert _mapped_outline(STRAIGHT, circle) is not _mapped_outline(ref, circle)
    polygon = GoalPolygon(np.array([[10.0, -1.0], [14.0, -1.0], [14.0, 1.0], [10.0, 1.0]]))
    moved = GoalPolygon(np.array([[10.0, -1.0], [14.0, -1.0], [14.0, 1.5], [10.0, 1.0]]))
    assert _mapped_outline(STRAIGHT, polygon) is _mapped_outline(STRAIGHT, polygon)
    assert not np.array_equal(_mapped_outline(STRAIGHT, moved).d, _mapped_outline(STRAIGHT, polygon).d)
