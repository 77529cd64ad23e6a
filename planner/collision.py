"""Obstacles and the vehicle's footprint: exact Cartesian geometry (shapely) and Frenet boxes.

* Exact: an obstacle is a shapely polygon (a circle is buffered into one; a dynamic obstacle is its
  ``length × width`` box at the predicted state, interpolated in time). The vehicle's footprint is the
  ``length × width`` rectangle centred on the trajectory point and turned by its heading.
* Frenet boxes, for fast decisions over many candidates: every obstacle outline, densified, is mapped
  by TransF-κ, and its ``[s_min, s_max] × [d_min, d_max]`` box is what candidates and lateral bounds
  are checked against. A vehicle planned at ``(s, d)`` with heading error ``θ`` to the reference covers
  the :class:`Extent` of :func:`footprint_extent` around it: ``|Δs| ≤ L/2·cos θ + W/2·|sin θ|`` and
  ``|Δd| ≤ L/2·|sin θ| + W/2·cos θ`` for the point model, shifted forwards along the heading by the
  rear axle's offset for a car (planned at its rear axle).

A dynamic obstacle whose predicted states move less than :data:`STATIC_MOTION` over the horizon is
treated as static (a parked car given as a prediction); the others are left to the speed profile.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from planner.frenet import to_frenet
from planner.problem import CircleObstacle, DynamicObstacle, Obstacle, PolygonObstacle, Vehicle
from planner.reference import FloatArray, ReferenceLine

#: a dynamic obstacle moving less than this over the horizon is static [m]
STATIC_MOTION = 0.5
#: outline points of obstacles are at most this far apart before projection [m]
OUTLINE_STEP = 0.25
#: outlines longer than this [m] are cut to the corridor around the reference before mapping
CLIP_LENGTH = 200.0
#: most outline points mapped in one call; beyond, the densification step grows with the outlines'
#: total length (a corridor as wide as a 10⁸ m vehicle or lane keeps a 10⁸ m circle whole). The API's
#: outline limit (20 km, plus what cutting to the corridor adds) stays below it.
MAX_OUTLINE_POINTS = 200_000
#: an obstacle dimension below this [m] is zero: a circle is its centre, a box a segment or a point
#: (GEOS buffers a point by a denormal radius into NaN)
POINT_SIZE = 1e-9


#: the corners of a box in units of its length and width, counter-clockwise from the rear right
_CORNERS = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
#: the corners, then the quarter points of the right side from the rear, then those of the left side:
#: a lane's edge that bends into a side between its corners (the inside of a curve) is caught there
_OUTLINE = np.vstack(
    (_CORNERS, [[q, -0.5] for q in (-0.25, 0.0, 0.25)], [[q, 0.5] for q in (-0.25, 0.0, 0.25)])
)
#: the indices of :func:`outline_points` on the right side of the box and on its left
RIGHT_SIDE, LEFT_SIDE = (0, 1, 4, 5, 6), (2, 3, 7, 8, 9)


def _placed(
    unit: FloatArray, x: FloatArray, y: FloatArray, heading: FloatArray, length: float, width: float
) -> FloatArray:
    """Points ``unit`` (in units of length and width, shape (k, 2)) of ``length × width`` [m] boxes centred
    at ``(x, y)`` turned by ``heading`` [rad], shape ``(*x.shape, k, 2)``."""
    c, s = np.cos(heading)[..., None], np.sin(heading)[..., None]
    lx, ly = unit[:, 0] * length, unit[:, 1] * width
    cx = np.asarray(x)[..., None] + lx * c - ly * s
    cy = np.asarray(y)[..., None] + lx * s + ly * c
    return np.stack((cx, cy), axis=-1)


def box_corners(x: FloatArray, y: FloatArray, heading: FloatArray, length: float, width: float) -> FloatArray:
    """Corners of ``length × width`` [m] rectangles centred at ``(x, y)`` turned by ``heading`` [rad].

    Returns shape ``(*x.shape, 4, 2)``, counter-clockwise from the rear right corner.
    """
    return _placed(_CORNERS, x, y, heading, length, width)


def outline_points(
    x: FloatArray, y: FloatArray, heading: FloatArray, length: float, width: float
) -> FloatArray:
    """What the lane checks measure of ``length × width`` [m] rectangles centred at ``(x, y)`` turned by
    ``heading`` [rad]: the corners (:func:`box_corners`' order), then the quarter points of the right side
    from the rear, then those of the left, shape ``(*x.shape, 10, 2)`` (:data:`RIGHT_SIDE`,
    :data:`LEFT_SIDE`).

    The corners alone miss a lane's edge that bends into a side between them: on the inside of a curve of
    radius ``r`` a side of length ``L`` cuts the edge by up to its sagitta ``L²/(8r)`` (0.85 m for a 4.5 m car
    on a 3 m edge) with both its corners inside. Between quarter points what is missed is at most
    ``(L/4)²/(8r)`` (5 cm there; 1 cm on an edge of radius 13 m).
    """
    return _placed(_OUTLINE, x, y, heading, length, width)


def outline_offsets(vehicle: Vehicle) -> tuple[FloatArray, FloatArray]:
    """Where the points of :func:`outline_points` lie on the vehicle's body [m], from its planned point (the
    centre; a car's rear axle, ``l_r`` behind it): along the body (forwards positive) and across it (left
    positive), each of shape (10,)."""
    along = _OUTLINE[:, 0] * vehicle.length + vehicle.rear_offset
    return along, _OUTLINE[:, 1] * vehicle.width


def footprints(x: FloatArray, y: FloatArray, heading: FloatArray, vehicle: Vehicle) -> NDArray[np.object_]:
    """The vehicle's footprint polygons at each trajectory point (shapely, vectorised)."""
    corners = box_corners(np.asarray(x), np.asarray(y), np.asarray(heading), vehicle.length, vehicle.width)
    return np.asarray(shapely.polygons(corners))


def prediction_at(obstacle: DynamicObstacle, t: FloatArray) -> FloatArray:
    """Predicted ``x, y, heading`` at times ``t`` [s], shape (len(t), 3): linear in time, held at the ends."""
    pred = obstacle.prediction
    x = np.interp(t, pred[:, 0], pred[:, 1])
    y = np.interp(t, pred[:, 0], pred[:, 2])
    h = np.interp(t, pred[:, 0], _unwrapped(pred[:, 3]))
    return np.column_stack((x, y, h))


def _unwrapped(heading: FloatArray) -> FloatArray:
    """``np.unwrap(heading)``; the headings themselves where no step reaches π (the common case, where
    ``np.unwrap`` adds only zeros: its Python overhead is most of a prediction's interpolation)."""
    if heading.shape[0] < 2 or bool(np.all(np.abs(np.diff(heading)) < np.pi)):
        return heading
    return np.asarray(np.unwrap(heading))


def is_static(obstacle: Obstacle, horizon: float) -> bool:
    """Whether an obstacle stays put (within :data:`STATIC_MOTION`) over ``[0, horizon]`` [s]."""
    if not isinstance(obstacle, DynamicObstacle):
        return True
    pred = obstacle.prediction
    inside = pred[(pred[:, 0] >= 0.0) & (pred[:, 0] <= horizon)]
    ends = np.array([0.0, horizon])  # the positions of prediction_at, without the heading it needs not
    x = np.concatenate((np.interp(ends, pred[:, 0], pred[:, 1]), inside[:, 1]))
    y = np.concatenate((np.interp(ends, pred[:, 0], pred[:, 2]), inside[:, 2]))
    dx, dy = x - x[0], y - y[0]
    return bool(np.max(np.sqrt(dx * dx + dy * dy)) < STATIC_MOTION)


def obstacle_shape(obstacle: Obstacle, t: float = 0.0) -> BaseGeometry:
    """The obstacle's outline as a shapely geometry (a dynamic one at time ``t`` [s]): a polygon, or
    what is left of one too thin to have an area — a point or a segment, never an empty geometry.

    A circle of radius below :data:`POINT_SIZE`, or below the rounding of its centre's coordinates
    (10⁻⁸ m at 10⁷ m: it buffers to nothing), is its centre. A box with a side below
    :data:`POINT_SIZE` is a segment, with both, a point. A polygon that crosses itself is repaired;
    one without area (collinear points) is its line work.
    """
    if isinstance(obstacle, PolygonObstacle):
        poly = shapely.Polygon(obstacle.polygon)
        return poly if poly.is_valid else _nonempty(shapely.make_valid(poly), obstacle.polygon)
    if isinstance(obstacle, CircleObstacle):
        center = shapely.Point(obstacle.center)
        if obstacle.radius < POINT_SIZE:
            return center
        return _nonempty(center.buffer(obstacle.radius, quad_segs=8), np.asarray(obstacle.center)[None, :])
    state = prediction_at(obstacle, np.array([t]))[0]
    length, width = (size if size >= POINT_SIZE else 0.0 for size in (obstacle.length, obstacle.width))
    corners = box_corners(state[0], state[1], state[2], length, width)
    box = shapely.Polygon(corners)
    return box if box.is_valid and box.area > 0.0 else shapely.MultiPoint(corners).convex_hull


def _nonempty(shape: BaseGeometry, points: FloatArray) -> BaseGeometry:
    """``shape``, or the convex hull of ``points`` (k, 2) [m] where it came out empty."""
    return shape if not shape.is_empty else shapely.MultiPoint(points).convex_hull


@dataclass(frozen=True)
class FrenetBoxes:
    """Obstacles' boxes in the Frenet frame, arrays of shape (K,) [m], in the order of ``ids``."""

    ids: tuple[str, ...]
    s_min: FloatArray
    s_max: FloatArray
    d_min: FloatArray
    d_max: FloatArray

    @property
    def count(self) -> int:
        return len(self.ids)


def frenet_boxes(
    ref: ReferenceLine, shapes: list[tuple[str, BaseGeometry]], *, reach: float | None = None
) -> FrenetBoxes:
    """Map every outline (densified to :data:`OUTLINE_STEP`) with TransF-κ in one call; box each.

    A point or a segment (an obstacle without area, see :func:`obstacle_shape`) is its own outline;
    an empty geometry is left out. With ``reach`` [m], only what lies within ``reach`` of the
    reference line counts: an obstacle farther away is left out, and a long outline (over
    :data:`CLIP_LENGTH`) is cut to that corridor first — the vehicle cannot get there, and mapping
    kilometres of outline would cost seconds. Outlines longer than :data:`MAX_OUTLINE_POINTS` steps
    in all are densified more coarsely.
    """
    shapes = [(ob_id, shape) for ob_id, shape in shapes if not shape.is_empty]
    if reach is not None and shapes:
        line = shapely.LineString(ref.points)
        geoms = np.array([shape for _, shape in shapes], dtype=object)
        near = shapely.dwithin(geoms, line, reach)
        long = shapely.length(geoms) > CLIP_LENGTH
        corridor = line.buffer(reach) if np.any(near & long) else None
        kept: list[tuple[str, BaseGeometry]] = []
        for (ob_id, shape), is_near, is_long in zip(shapes, near, long, strict=True):
            if not is_near:
                continue
            piece = shape.intersection(corridor) if is_long and corridor is not None else shape
            if not piece.is_empty:
                kept.append((ob_id, piece))
        shapes = kept
    if not shapes:
        empty = np.zeros(0)
        return FrenetBoxes((), empty, empty, empty, empty)
    # The boundary of a polygon, the geometry itself for a point or a line: every vertex of the
    # densified geometry (a polygon's holes lie inside its outer ring, so they do not widen its box).
    total = float(np.sum(shapely.length([shape for _, shape in shapes])))
    step = max(OUTLINE_STEP, total / MAX_OUTLINE_POINTS)
    dense = [shapely.segmentize(shape, step) for _, shape in shapes]
    coords = [np.asarray(shapely.get_coordinates(g)) for g in dense]
    sizes = np.array([c.shape[0] for c in coords])
    starts = np.concatenate(([0], np.cumsum(sizes)[:-1]))
    fr = to_frenet(ref, np.vstack(coords))
    return FrenetBoxes(
        ids=tuple(i for i, _ in shapes),
        s_min=np.minimum.reduceat(fr.s, starts),
        s_max=np.maximum.reduceat(fr.s, starts),
        d_min=np.minimum.reduceat(fr.d, starts),
        d_max=np.maximum.reduceat(fr.d, starts),
    )


@dataclass(frozen=True)
class Extent:
    """How far the footprint reaches from the planned point [m], along the reference behind (``back``)
    and ahead (``front``), across it to the right and left; arrays of one shape (or floats)."""

    back: FloatArray
    front: FloatArray
    right: FloatArray
    left: FloatArray

    def column(self) -> Extent:
        """The extent with a trailing axis, to broadcast against a row of obstacles."""
        return Extent(*(np.asarray(a)[..., None] for a in (self.back, self.front, self.right, self.left)))


def footprint_extent(heading_error: FloatArray, vehicle: Vehicle, margin: float) -> Extent:
    """The extent of the footprint turned by ``heading_error`` θ [rad] (|θ| < π/2) from the planned
    point, with ``margin`` [m] around it.

    The footprint spans ``[−b, f]`` along the heading from the planned point and ``±W/2`` across it, with
    ``b = L/2 − l_r`` (:attr:`~planner.problem.Vehicle.rear_extent`) and ``f = L/2 + l_r``
    (:attr:`~planner.problem.Vehicle.front_extent`; ``b = f = L/2`` for the point model, a car's
    rear axle ``l_r`` behind the centre). Turned by θ, its corners ``(u, v)`` lie at
    ``Δs = u cos θ − v sin θ`` and ``Δd = u sin θ + v cos θ``::

        back  = b cos θ + W/2 |sin θ|              front = f cos θ + W/2 |sin θ|
        right = max(b sin θ, −f sin θ) + W/2 cos θ  left  = max(f sin θ, −b sin θ) + W/2 cos θ

    (the point model's ``L/2 cos θ + W/2 |sin θ|`` and ``L/2 |sin θ| + W/2 cos θ`` either way).
    """
    sine = np.sin(heading_error)
    c, s = np.abs(np.cos(heading_error)), np.abs(sine)
    back, front, half_w = vehicle.rear_extent, vehicle.front_extent, 0.5 * vehicle.width
    return Extent(
        back=back * c + half_w * s + margin,
        front=front * c + half_w * s + margin,
        right=np.maximum(back * sine, -front * sine) + half_w * c + margin,
        left=np.maximum(front * sine, -back * sine) + half_w * c + margin,
    )


def box_hits(boxes: FrenetBoxes, s: FloatArray, d: FloatArray, extent: Extent) -> NDArray[np.bool_]:
    """Whether the footprint box at each point overlaps any obstacle box; shape of ``s``."""
    if boxes.count == 0:
        return np.zeros(np.shape(s), dtype=bool)
    s_, d_ = np.asarray(s)[..., None], np.asarray(d)[..., None]
    hit = boxes_overlap(s_, d_, extent.column(), boxes.s_min, boxes.s_max, boxes.d_min, boxes.d_max)
    return np.asarray(hit.any(axis=-1))


def boxes_overlap(
    s: FloatArray,
    d: FloatArray,
    extent: Extent,
    s_min: FloatArray,
    s_max: FloatArray,
    d_min: FloatArray,
    d_max: FloatArray,
) -> NDArray[np.bool_]:
    """Whether footprint boxes ``[s − back, s + front] × [d − right, d + left]`` overlap obstacle boxes
    ``[s_min, s_max] × [d_min, d_max]`` [m] (touching counts), elementwise over the broadcast shapes."""
    hit = (s + extent.front >= s_min) & (s - extent.back <= s_max)
    hit &= (d + extent.left >= d_min) & (d - extent.right <= d_max)
    return np.asarray(hit)
