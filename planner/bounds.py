"""Lateral bounds per knot: lane, obstacles on their decided side, and the κ·d bound.

For knots ``s_i`` [m] along the reference, the planned point's offset (the vehicle's centre, or a
car's rear axle: :class:`planner.problem.Vehicle`) must keep ``lower_i ≤ d_i ≤ upper_i``:

* lane: left and right widths less half the vehicle width and a margin;
* obstacles (Frenet boxes ``[s_min, s_max] × [d_min, d_max]``): where the footprint's extent along
  ``s`` (``[s − L/2 + l_r, s + L/2 + l_r]`` from the planned point, ``l_r`` a car's rear axle offset, 0
  for the point model) overlaps the box, ``d ≥ d_max + w/2 + margin`` when passing on its left,
  ``d ≤ d_min − w/2 − margin`` on its right;
* κ·d in its vehicle-feasible form: an offset path has curvature ``κ/(1 − κ·d)``, so requiring
  ``1 − κ_i·d_i ≥ |κ_i|/κ_max`` (linear in ``d``) keeps ``κ·d < 1`` and the path drivable; where the
  reference is tighter than ``1/κ_max`` it forces the path outwards.

Where ``lower > upper`` the road is blocked (an obstacle across it, a curve too tight, a lane narrower than
the vehicle): :attr:`LateralBounds.blocked` is the first such knot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.collision import (
    LEFT_SIDE,
    RIGHT_SIDE,
    FrenetBoxes,
    footprint_extent,
    outline_offsets,
    outline_points,
)
from planner.frenet import to_cartesian, to_frenet
from planner.lane import lane_bounds
from planner.problem import Lane, Vehicle
from planner.reference import FloatArray, ReferenceLine

#: how far beyond the lane edge [m] a bound outside the lane is kept (it blocks the knot either way)
BEYOND_LANE = 1.0


@dataclass(frozen=True)
class LateralBounds:
    """Bounds on ``d`` [m] at knots ``s`` [m]; ``blocked``: the first knot with ``lower > upper``, or None."""

    s: FloatArray
    lower: FloatArray
    upper: FloatArray
    blocked: int | None


def pass_left(
    boxes: FrenetBoxes, s: FloatArray, d: FloatArray, lower: FloatArray, upper: FloatArray
) -> NDArray[np.bool_]:
    """Decide per obstacle whether a path ``d(s)`` passes on its left (True) or right (False).

    The side of the obstacle's middle on which the path's mean offset over the obstacle's ``s``-range
    lies; where the path has no point there, the side with more room to the lane bounds
    ``lower, upper`` [m].
    """
    out = roomier_left(boxes, s, lower, upper)
    for k in range(boxes.count):  # one decision per obstacle, not per point
        near = (s >= boxes.s_min[k]) & (s <= boxes.s_max[k])
        if near.any():
            out[k] = float(np.mean(d[near])) >= 0.5 * (boxes.d_min[k] + boxes.d_max[k])
    return out


def roomier_left(
    boxes: FrenetBoxes, s: FloatArray, lower: FloatArray, upper: FloatArray
) -> NDArray[np.bool_]:
    """Per obstacle, whether the bounds ``lower, upper`` [m] at knots ``s`` [m] leave more room on its left
    than on its right, at the first knot at or after its start (the last knot when it starts beyond)."""
    at = np.clip(np.searchsorted(s, boxes.s_min), 0, s.shape[0] - 1)
    return np.asarray(upper[at] - boxes.d_max >= boxes.d_min - lower[at], dtype=bool)


@dataclass(frozen=True)
class CornerReach:
    """The footprint's outline when its planned point is on a knot, aligned with the reference, each of shape
    ``(n, 10)`` (its corners, rear right, front right, front left, rear left, then points along its right
    and left sides: :func:`planner.collision.outline_points`): their arc lengths ``s`` [m] on the
    reference and how far [m] each reaches beyond the side it is on (0 where it stays within ``W/2``)."""

    s: FloatArray
    reach: FloatArray

    @property
    def left(self) -> FloatArray:
        """The most any point reaches out on the left, per knot [m]."""
        return np.asarray(self.reach[:, LEFT_SIDE].max(axis=1))

    @property
    def right(self) -> FloatArray:
        """The most any point reaches out on the right, per knot [m]."""
        return np.asarray(self.reach[:, RIGHT_SIDE].max(axis=1))


def curve_bulge(
    ref: ReferenceLine, s: FloatArray, vehicle: Vehicle, d: FloatArray | None = None
) -> CornerReach:
    """The footprint's corners and points along its sides (:func:`planner.collision.outline_points`) at
    knots ``s`` [m], its planned point at offsets ``d`` [m] (default 0) and
    its axis along the reference's heading there, mapped to Frenet coordinates by TransF-κ as the
    trajectory checks map them. The footprint is placed from the planned point along that heading: its
    centre is the point for the point model, ``l_r`` ahead of a car's rear axle.

    The body is straight and the reference bends away from it: on the outside of a curve the front and
    rear corners reach beyond ``W/2`` (by about the sagitta ``κf²/2`` of the front, ``f = L/2 + l_r``
    ahead of the planned point, and ``κb²/2`` of the rear, ``b = L/2 − l_r`` behind it, less where the
    curve tightens under one end only), a left turn to the right and a right turn to the left. And on a
    curve the outer corners lie less than ``f`` ahead of and ``b`` behind the point along the reference
    (about ``f/(1 + |κ|(d + W/2))`` on the outside). On the inside, a side between its corners reaches
    out where the reference bends under it (a body placed ahead of its planned point, as a car's).
    """
    d0 = np.zeros_like(s) if d is None else np.asarray(d, dtype=float)
    point = to_cartesian(ref, s, d0)
    heading = ref.heading_at(s)
    x, y = point[:, 0], point[:, 1]
    offset = vehicle.rear_offset
    if offset:
        x, y = x + offset * np.cos(heading), y + offset * np.sin(heading)
    outline = outline_points(x, y, heading, vehicle.length, vehicle.width)
    count = outline.shape[-2]
    fr = to_frenet(ref, outline.reshape(-1, 2))
    side = np.where(np.isin(np.arange(count), RIGHT_SIDE), -1.0, 1.0)  # the right reaches out to negative d
    reach = side * (fr.d.reshape(-1, count) - d0[:, None]) - 0.5 * vehicle.width
    return CornerReach(s=fr.s.reshape(-1, count), reach=np.maximum(reach, 0.0))


@dataclass(frozen=True)
class KnotGeometry:
    """What :func:`lateral_bounds` at knots ``s`` takes from the reference, the lane and the vehicle alone
    (not from margins, obstacles or sides): the turning limit on ``d`` [m] per knot (``lower``, ``upper``:
    :func:`_turning_limits`) and the footprint's corners at the least offset it leaves (``corners``:
    :func:`curve_bulge`). The same for every set of bounds at those knots in that lane (the lateral
    stage's corridor with and without its lane margin): computed once for both."""

    lower: FloatArray
    upper: FloatArray
    corners: CornerReach


def knot_geometry(ref: ReferenceLine, lane: Lane, s: FloatArray, vehicle: Vehicle) -> KnotGeometry:
    """:class:`KnotGeometry` at knots ``s`` [m] in ``lane``."""
    k_lower, k_upper = _turning_limits(ref, lane, s, vehicle)
    return KnotGeometry(k_lower, k_upper, curve_bulge(ref, s, vehicle, np.clip(0.0, k_lower, k_upper)))


def lateral_bounds(
    ref: ReferenceLine,
    lane: Lane,
    s: FloatArray,
    vehicle: Vehicle,
    *,
    margin: float,
    boxes: FrenetBoxes,
    left_of: NDArray[np.bool_],
    heading_error: FloatArray | None = None,
    lane_margin: float | None = None,
    geometry: KnotGeometry | None = None,
) -> LateralBounds:
    """Bounds at knots ``s`` [m]; ``left_of[k]`` says on which side obstacle ``k`` is passed.

    ``margin`` [m] is kept to the obstacles and, unless ``lane_margin`` [m] is given, to the lane's edges.

    With the path's expected heading error to the reference ``θ`` [rad] per knot, the footprint reaches
    :func:`planner.collision.footprint_extent` to either side rather than ``W/2``: ``L/2·|sin θ| + W/2·cos θ``
    for the point model; for a car (planned at its rear axle) its front swings out by ``(L/2 + l_r)·sin θ``
    to the side it turns to, its rear by ``(L/2 − l_r)·sin θ`` to the other. That is what the obstacles'
    boxes are kept from; against the lane's edges each point of the outline, at ``(u, v)`` on the body
    (:func:`planner.collision.outline_offsets`), reaches ``u·sin θ + v·cos θ`` across where it is.

    ``geometry``: :func:`knot_geometry` of these knots, lane and vehicle where the caller has it
    (computed here otherwise).
    """
    theta = np.zeros_like(s) if heading_error is None else np.asarray(heading_error)
    turned_extent = footprint_extent(theta, vehicle, 0.0)
    ext_right, ext_left = turned_extent.right, turned_extent.left
    ahead, behind, half_w = vehicle.front_extent, vehicle.rear_extent, 0.5 * vehicle.width
    edge = margin if lane_margin is None else lane_margin
    # the turning limit, and the corners where the path is at the least offset it leaves (d = 0 elsewhere)
    geometry = knot_geometry(ref, lane, s, vehicle) if geometry is None else geometry
    k_lower, k_upper, corners = geometry.lower, geometry.upper, geometry.corners

    def obstacle_edges(right: FloatArray | float, left: FloatArray | float) -> tuple[FloatArray, FloatArray]:
        """Lower and upper bound from the obstacles, for footprint half-extents ``right`` and ``left``."""
        if not boxes.count:
            return np.full(s.shape, -np.inf), np.full(s.shape, np.inf)
        overlaps = (s[:, None] + ahead + margin >= boxes.s_min) & (
            s[:, None] - behind - margin <= boxes.s_max
        )
        right_col = np.broadcast_to(right, s.shape)[:, None]
        left_col = np.broadcast_to(left, s.shape)[:, None]
        left_edge = np.where(overlaps & left_of, boxes.d_max + right_col + margin, -np.inf)
        right_edge = np.where(overlaps & ~left_of, boxes.d_min - left_col - margin, np.inf)
        return left_edge.max(axis=1), right_edge.min(axis=1)

    # The footprint aligned with the lane and clear of the obstacles by the margin: the least the bounds
    # keep (where the lane leaves no room for the margin, it is dropped; a lane narrower than the vehicle
    # itself cannot be driven: the road is blocked there, or ends, as where a lane's width falls to zero
    # at its last point).
    straight = lane_bounds(ref, lane, s, half_width=half_w, margin=edge)
    tight = lane_bounds(ref, lane, s, half_width=half_w, margin=0.0)
    narrow = tight.lower > tight.upper - 1e-9
    fits = straight.lower < straight.upper
    lower = np.where(narrow, np.inf, np.where(fits, straight.lower, tight.lower))
    upper = np.where(narrow, -np.inf, np.where(fits, straight.upper, tight.upper))
    obs_lower, obs_upper = obstacle_edges(half_w, half_w)
    lower, upper = np.maximum(lower, obs_lower), np.minimum(upper, obs_upper)
    # Then, wherever it fits with all of the above: the footprint turned by the heading error, and
    # then also with its corners bulging out of curves, towards the obstacles on the outside and the
    # lane's edge: each point of its outline, turned, against the lane's width where it is (a lane
    # flaring out in a turn, or a borrow's ramp opening ahead, gives the front the room it has there,
    # and one narrowing ahead takes it), and the sides abeam the planned point against the width there.
    turned = lane_bounds(ref, lane, s, half_width=0.0, margin=edge)
    abeam = half_w * np.cos(theta)
    lo, up = turned.lower + abeam, turned.upper - abeam
    obs_lo, obs_up = obstacle_edges(ext_right, ext_left)
    lo, up = np.maximum(lo, obs_lo), np.minimum(up, obs_up)
    fits = (lo <= up) & ~narrow
    lower, upper = np.where(fits, lo, lower), np.where(fits, up, upper)
    obs_lo, obs_up = obstacle_edges(ext_right + corners.right, ext_left + corners.left)
    lo, up = np.maximum(lo, obs_lo), np.minimum(up, obs_up)
    # each outline point turned by θ about the planned point: across by u·sin θ + v·cos θ, along by
    # u·(cos θ − 1) − v·sin θ from where the aligned footprint has it
    u, v = outline_offsets(vehicle)
    sin_t, cos_t = np.sin(theta)[:, None], np.cos(theta)[:, None]
    across = u * sin_t + v * cos_t
    # (Behind the first knot, where the vehicle comes from, the lane is taken as wide as at that knot:
    # a reference often starts just behind the vehicle, where the lane's edges may close in.)
    corner_s = np.maximum(corners.s + u * (cos_t - 1.0) - v * sin_t, s[0])
    left_w, right_w = lane.widths(ref, corner_s)
    for c in RIGHT_SIDE:
        lo = np.maximum(lo, -right_w[:, c] + edge - across[:, c] + corners.reach[:, c])
    for c in LEFT_SIDE:
        up = np.minimum(up, left_w[:, c] - edge - across[:, c] - corners.reach[:, c])
    fits = (lo <= up) & ~narrow
    lower, upper = np.where(fits, lo, lower), np.where(fits, up, upper)
    # Last, the turning limit: where the lane leaves no room within it, the road is blocked for this
    # vehicle (a turn tighter than it can drive in the lane).
    lower, upper = np.maximum(lower, k_lower), np.minimum(upper, k_upper)
    blocked_at = np.flatnonzero(lower > upper)
    blocked = int(blocked_at[0]) if blocked_at.size else None
    return LateralBounds(s=s, lower=lower, upper=upper, blocked=blocked)


def _turning_limits(
    ref: ReferenceLine, lane: Lane, s: FloatArray, vehicle: Vehicle
) -> tuple[FloatArray, FloatArray]:
    """The κ·d bound in its vehicle-feasible form, as ``(lower, upper)`` on d [m] at knots ``s``.

    ``1 − κ d ≥ |κ|/κ_max  ⇔  d ≤ 1/κ − 1/κ_max`` (κ > 0), ``d ≥ 1/κ + 1/κ_max`` (κ < 0): the path keeps a
    radius of at least ``1/κ_max`` (``κ_max``: :attr:`~planner.problem.Vehicle.curvature_limit`, for a car
    the path its rear axle drives); ``∓inf`` where the reference is straight. Written so, it stays finite for
    any ``κ_max > 0`` (the quotient form overflowed for a tiny one). Beyond the lane (a vehicle that cannot
    turn that tightly) the knot is blocked whether the bound is a metre outside or 10³⁰⁰ m: it is kept
    within ``BEYOND_LANE`` of the edge, a number the lateral QP can still take as a bound.
    """
    kappa = ref.kappa_at(s)
    curved = np.abs(kappa) > 1e-9
    radius = 1.0 / np.where(curved, kappa, 1.0)
    limit = np.where(curved, radius - np.sign(kappa) / vehicle.curvature_limit, 0.0)
    lane_left, lane_right = lane.widths(ref, s)
    limit = np.clip(limit, -lane_right - BEYOND_LANE, lane_left + BEYOND_LANE)
    return np.where(kappa < -1e-9, limit, -np.inf), np.where(kappa > 1e-9, limit, np.inf)
