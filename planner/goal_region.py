"""Where a goal's region lies: which points are inside it, and where it lies along the reference and along
a path.

The point that must be inside is the footprint's centre (:mod:`planner.goal`). On the reference
(:func:`on_reference`) the region is mapped by TransF-κ where the centre can be: at knots ``s_i`` [m] over
the region's extent along the reference, the offsets ``d`` [m] of the lane's band for the centre (the lane
less half the vehicle's width and the lateral margin, within the turning limit ``1 − κd ≥ |κ|/κ_max``)
that lie inside the region, as the interval ``[d_low, d_high]`` between the first and the last of them
(the region is taken as convex across the lane), and ``[s_in, s_out]``, the first and last knots with
any. Along a path (:func:`along_path`) it is the first stretch ``[σ_in, σ_out]`` [m] of the path's arc
length over which the centre is inside (for a car, ``l_r`` ahead of the planned rear axle along the
path's heading).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray
from shapely.geometry.base import BaseGeometry

from planner.config import DEFAULT_CONFIG, GoalConfig
from planner.frenet import FrenetPoints, to_cartesian, to_frenet
from planner.goal import GoalCircle, GoalPosition
from planner.lane import lane_bounds
from planner.problem import Lane, Vehicle
from planner.reference import FloatArray, ReferenceLine
from planner.trajectory import Path

#: the region's boundary is sampled this densely [m] (coarser for a long one: :data:`MAX_OUTLINE_POINTS`)
OUTLINE_STEP = 0.5
#: most samples of the region's boundary
MAX_OUTLINE_POINTS = 2000
#: samples along a path are this far apart at most [m] (farther on a long stretch: :data:`MAX_PATH_SAMPLES`)
PATH_STEP = 0.1
#: most samples of a path when it is tested against the region
MAX_PATH_SAMPLES = 2000


def region_shape(position: GoalPosition) -> BaseGeometry:
    """The region as a valid shapely geometry (a disc as a 64-gon inside it: for extents and distances;
    :func:`inside` tests the disc itself)."""
    if isinstance(position, GoalCircle):
        return shapely.Point(position.center).buffer(position.radius, quad_segs=16)
    poly = shapely.Polygon(position.polygon)
    return poly if poly.is_valid else shapely.make_valid(poly)


def inside(position: GoalPosition, x: ArrayLike, y: ArrayLike) -> NDArray[np.bool_]:
    """Whether each point ``(x, y)`` [m] is inside the region, its boundary included."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if isinstance(position, GoalCircle):
        cx, cy = position.center
        return np.asarray(np.hypot(x - cx, y - cy) <= position.radius)
    return np.asarray(shapely.intersects_xy(region_shape(position), x, y))


def distance_to(position: GoalPosition, x: float, y: float) -> float:
    """Distance [m] from the point ``(x, y)`` to the region (0 inside)."""
    if isinstance(position, GoalCircle):
        return max(float(np.hypot(x - position.center[0], y - position.center[1])) - position.radius, 0.0)
    return float(region_shape(position).distance(shapely.Point(x, y)))


@dataclass(frozen=True)
class RegionOnReference:
    """The region on the reference, for the footprint's centre.

    Attributes:
        s_min, s_max: the region's extent along the reference [m] (of its boundary, by TransF-κ).
        s: knots over that extent, clipped to where the centre can be [m] (none when it is all beyond).
        d_low, d_high: per knot, the first and last offset [m] of the lane's band for the centre inside
            the region; NaN where none is.
    """

    s_min: float
    s_max: float
    s: FloatArray
    d_low: FloatArray
    d_high: FloatArray

    @property
    def on_lane(self) -> NDArray[np.bool_]:
        """Which knots have an offset inside the region."""
        return np.asarray(np.isfinite(self.d_low))

    @property
    def reachable(self) -> bool:
        """Whether the centre can be inside the region anywhere within the lane."""
        return bool(self.on_lane.any())

    @property
    def s_in(self) -> float:
        """The first knot with an offset inside the region [m] (NaN when none)."""
        on = np.flatnonzero(self.on_lane)
        return float(self.s[on[0]]) if on.size else math.nan

    @property
    def s_out(self) -> float:
        """The last knot with an offset inside the region [m] (NaN when none)."""
        on = np.flatnonzero(self.on_lane)
        return float(self.s[on[-1]]) if on.size else math.nan


def centre_band(
    ref: ReferenceLine, lane: Lane, s: FloatArray, vehicle: Vehicle, margin: float
) -> tuple[FloatArray, FloatArray]:
    """The offsets [m] the footprint's centre may take at ``s`` [m]: the lane less half the vehicle's width
    and ``margin``, within the turning limit ``1 − κd ≥ |κ|/κ_max`` (:mod:`planner.bounds`)."""
    band = lane_bounds(ref, lane, s, half_width=0.5 * vehicle.width, margin=margin)
    kappa = ref.kappa_at(s)
    with np.errstate(divide="ignore"):
        radius = 1.0 / np.where(np.abs(kappa) > 1e-9, kappa, np.inf)
    turn = 1.0 / vehicle.curvature_limit
    upper = np.where(kappa > 1e-9, np.minimum(band.upper, radius - turn), band.upper)
    lower = np.where(kappa < -1e-9, np.maximum(band.lower, radius + turn), band.lower)
    return lower, np.maximum(upper, lower)


#: the last region mapped by :func:`_mapped_outline`: the reference (kept: its identity is the key) and the
#: region's numbers (as bytes), its outline's points and their TransF-κ coordinates. A closed loop asks
#: for the same region on the same reference (built once: :func:`planner.reference.build_reference` is
#: cached) every cycle.
_LAST_OUTLINE: tuple[ReferenceLine, tuple[bytes, ...], FrenetPoints] | None = None


def _region_key(position: GoalPosition) -> tuple[bytes, ...]:
    """The region's numbers, exactly (bytes: ``-0.0`` is not ``0.0``)."""
    if isinstance(position, GoalCircle):
        return (
            b"circle",
            np.asarray(position.center, dtype=float).tobytes(),
            np.float64(position.radius).tobytes(),
        )
    polygon = np.asarray(position.polygon, dtype=float)
    return (b"polygon", np.asarray(polygon.shape).tobytes(), polygon.tobytes())


def _mapped_outline(ref: ReferenceLine, position: GoalPosition) -> FrenetPoints:
    """TransF-κ coordinates of the region's outline (its boundary segmentized to :data:`OUTLINE_STEP`, at
    most :data:`MAX_OUTLINE_POINTS` steps) and, last, a point inside it; the same region on the same
    reference as last time is not mapped again."""
    global _LAST_OUTLINE
    key = _region_key(position)
    last = _LAST_OUTLINE
    if last is not None and last[0] is ref and last[1] == key:
        return last[2]
    shape = region_shape(position)
    step = max(OUTLINE_STEP, float(shape.length) / MAX_OUTLINE_POINTS)
    outline = np.asarray(shapely.get_coordinates(shapely.segmentize(shape.boundary, step)))
    points = np.vstack((outline, np.asarray(shape.representative_point().coords)))
    fr = to_frenet(ref, points)
    for shared in (fr.s, fr.d, fr.segment, fr.nearest, fr.folded):  # kept for the next plans: never written
        shared.setflags(write=False)
    _LAST_OUTLINE = (ref, key, fr)
    return fr


def on_reference(
    ref: ReferenceLine,
    position: GoalPosition,
    lane: Lane,
    vehicle: Vehicle,
    margin: float,
    s_end: float,
    config: GoalConfig = DEFAULT_CONFIG.goal,
) -> RegionOnReference:
    """The region on the reference (see the module docstring) for a centre at most at ``s_end`` [m].

    The grid of the lane's band (``lateral_samples`` offsets per knot, knots at least 0.5 m apart and at
    most ``max_knots``) is tested against the region, and so is the region's own boundary where it lies in
    the band (a region narrower than the grid's step is found all the same).
    """
    fr = _mapped_outline(ref, position)
    s_min, s_max = float(fr.s.min()), float(fr.s.max())
    low, high = max(s_min, 0.0), min(s_max, s_end)
    if not high >= low:
        empty = np.zeros(0)
        return RegionOnReference(s_min, s_max, empty, empty, empty)
    count = int(np.clip(math.ceil((high - low) / 0.5) + 1, 2, config.max_knots))
    s = np.linspace(low, high, count)
    lower, upper = centre_band(ref, lane, s, vehicle, margin)
    share = np.linspace(0.0, 1.0, config.lateral_samples)
    d = lower[:, None] + (upper - lower)[:, None] * share[None, :]
    grid = to_cartesian(ref, np.repeat(s, share.size), d.ravel())
    hit = inside(position, grid[:, 0], grid[:, 1]).reshape(d.shape)
    d_low = np.where(hit, d, np.inf).min(axis=1)
    d_high = np.where(hit, d, -np.inf).max(axis=1)
    # the region's own samples where they lie in the band, at the nearest knot
    at = np.clip(np.rint((fr.s - low) / max(s[1] - s[0], 1e-9)).astype(np.intp), 0, count - 1)
    own = (fr.s >= low) & (fr.s <= high) & (fr.d >= lower[at]) & (fr.d <= upper[at])
    np.minimum.at(d_low, at[own], fr.d[own])
    np.maximum.at(d_high, at[own], fr.d[own])
    found = np.isfinite(d_low)
    nan = np.full(count, math.nan)
    return RegionOnReference(s_min, s_max, s, np.where(found, d_low, nan), np.where(found, d_high, nan))


def along_path(
    path: Path, position: GoalPosition, vehicle: Vehicle, s_range: tuple[float, float]
) -> tuple[float, float] | None:
    """The first stretch ``(σ_in, σ_out)`` [m] of ``path``'s arc length over which the footprint's centre is
    inside the region, looked for where the centre's ``s`` is within ``s_range`` [m] (the region's extent
    along the reference), or None where it never is."""
    offset = vehicle.rear_offset
    near = np.flatnonzero((path.s + offset >= s_range[0] - 1.0) & (path.s + offset <= s_range[1] + 1.0))
    if near.size == 0:
        return None
    first, last = max(int(near[0]) - 1, 0), min(int(near[-1]) + 1, path.sigma.size - 1)
    start, end = float(path.sigma[first]), float(path.sigma[last])
    count = int(np.clip(math.ceil((end - start) / PATH_STEP) + 1, 2, MAX_PATH_SAMPLES))
    sigma = np.linspace(start, end, count)
    x, y = np.interp(sigma, path.sigma, path.x), np.interp(sigma, path.sigma, path.y)
    if offset:
        heading = np.interp(sigma, path.sigma, np.unwrap(path.heading))
        x, y = x + offset * np.cos(heading), y + offset * np.sin(heading)
    hit = inside(position, x, y)
    if not hit.any():
        return None
    enter = int(np.argmax(hit))
    leave = enter + int(np.argmin(hit[enter:])) if not hit[enter:].all() else hit.size
    return float(sigma[enter]), float(sigma[leave - 1])
