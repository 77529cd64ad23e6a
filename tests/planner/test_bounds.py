"""The lateral bounds' footprint (`planner.bounds.lateral_bounds`): turned by the path's heading error, each
point of its outline is held against the lane's width where that point is."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.bounds import lateral_bounds
from planner.collision import FrenetBoxes, outline_points
from planner.frenet import to_frenet
from planner.lane import Corridor
from planner.problem import Road, Vehicle
from planner.reference import build_reference
from planner.roads import straight

REF = build_reference(straight(120.0, step=0.5))
NO_BOXES = FrenetBoxes((), *(np.zeros(0) for _ in range(4)))
MARGIN = 0.2


@settings(max_examples=40, deadline=None)
@given(
    ramp=st.floats(4.0, 20.0),
    theta=st.floats(-0.28, 0.28),  # turned, 4.5 × 1.8 m spans ≤ 3.05 m: fits the lane less margins
    car=st.booleans(),
)
def test_the_turned_footprint_at_its_bound_touches_a_ramp_opening_ahead_without_crossing_it(
    ramp: float, theta: float, car: bool
) -> None:
    """A borrow's corridor on a straight road: the lane (±1.75 m) opens on the left to the road's edge
    (5.25 m) over a ramp of ``ramp`` [m] before s = 60 m. With the footprint turned by ``theta`` [rad],
    the planned point at the upper bound puts no point of the outline beyond the corridor's left edge (less
    the margin), and 0.1 m further out one is beyond it: the bound gives the front the room the ramp has
    where the front is, rather than holding the whole footprint to the width at its narrowest point."""
    vehicle = Vehicle(wheelbase=2.7, rear_axle_offset=1.35) if car else Vehicle()
    corridor = Corridor(1.75, 1.75, Road(5.25, 1.75), "left", 60.0, 70.0, ramp, 10.0)
    s = np.arange(30.0, 75.0, 0.5)
    heading = np.full(s.shape, theta)
    bounds = lateral_bounds(
        REF,
        corridor,
        s,
        vehicle,
        margin=MARGIN,
        boxes=NO_BOXES,
        left_of=np.zeros(0, dtype=bool),
        heading_error=heading,
    )
    assert bounds.blocked is None

    def beyond(d: np.ndarray) -> np.ndarray:
        """Per knot, how far [m] the outline's farthest left point is beyond the edge less the margin."""
        x = s + vehicle.rear_offset * np.cos(theta)  # the centre, l_r ahead of a car's rear axle
        y = d + vehicle.rear_offset * np.sin(theta)
        points = outline_points(x, y, heading, vehicle.length, vehicle.width).reshape(-1, 2)
        fr = to_frenet(REF, points)
        left, _ = corridor.widths(REF, fr.s)
        return np.asarray((fr.d - (left - MARGIN)).reshape(s.shape[0], -1).max(axis=1))

    assert np.all(beyond(bounds.upper) <= 1e-6)
    assert np.all(beyond(bounds.upper + 0.1) > 0.0)
