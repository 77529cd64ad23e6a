"""CommonRoad scenarios as planning requests (the converter behind ``kappa-planner commonroad``).

A CommonRoad scenario (XML: lanelet network, obstacles, planning problems) is reduced to one route and
written in the service's request contract (:class:`app.models.planning.PlanningRequest`):

* **route** — the lanelets from the ego's lanelet to a goal lanelet: a shortest path (networkx) over
  successor edges weighted by length and same-direction lane changes weighted by
  :data:`LANE_CHANGE_COST`; without a goal position, the ego's lanelet's first successors, as
  commonroad-route-planner's survival planner does. Predecessors are prepended until the route starts
  :data:`BEHIND_EGO` behind the ego; successors appended until it ends :data:`BEYOND_GOAL` past the goal
  lanelet (at most :data:`MAX_AHEAD` ahead of the ego).
* **reference line** — the lanelets' centre lines joined (a lane change blends linearly from one
  centre line to the other over the lanelet where it happens), resampled every :data:`SPACING`,
  smoothed by a Gaussian of :data:`SMOOTHING_SIGMA` and cut to ``[s_ego − BEHIND_EGO, …]``. Where the
  route ends at the map's edge and recorded traffic drives off it there (:func:`_road_goes_on`), the
  line goes on straight for :data:`MAP_EDGE_EXTENSION` with the last point's lane and road widths
  (``info["map_edge_extension_m"]``): the map is a cut-out of a road that goes on, as its traffic does
  (:func:`continued_predictions`); a reference that ended there would be a stop, and the planner would
  brake for the edge of the map in front of the traffic behind. A route that ends where no traffic
  leaves (a loading bay), or whose straight continuation would run into another part of the map, ends
  as it does.
* **lane widths** — per reference point, the distance to the left edge of the leftmost and to the right
  edge of the rightmost same-direction lanelet beside the route's lanelet there, along the reference's
  normal as the planner reads a width (:func:`boundary_widths`, :func:`along_normal`: never less than the
  nearest distance, lowered where an edge's vertex would fall outside the widths interpolated between
  two points; the edges are extended as rays, so end points get real widths). The nearest distance
  alone narrowed the inside of tight corners to the corner's vertex: by up to 0.49 m in DEU_Lohmar-26's
  right angle, too tight there for a car.
* **road widths** (``road``) — per reference point, how far the drivable surface reaches on each side
  along the reference's normal, without a gap, at least the lane and at most :data:`ROAD_BEYOND` beyond
  it (:func:`surface_widths`): the surface is the union of the lanelets a vehicle may drive on (every type
  but :data:`NOT_DRIVABLE`), so adjacent lanelets of either direction count, and where lanelets meet
  without an adjacency (a junction) their areas too.
* **obstacles** — static ones as polygons (circles as circles); dynamic ones as ``length × width``
  boxes with a ``prediction`` of their recorded states (t relative to the ego's initial time step,
  box centres — CommonRoad states may sit off the centre by ``origin_x_shift``); a set-based
  prediction becomes a constant-velocity one over its time span.
* **ego, vehicle, options** — the planning problem's initial state; the options of the shared requests
  (``target_speed``: the larger of the ego's speed, the middle of the goal's speed interval and
  :data:`MIN_TARGET_SPEED`) and their vehicle's limits, as the car of CommonRoad's vehicle type
  :data:`VEHICLE_TYPE` (:func:`vehicle_type_car`: footprint, wheelbase, rear axle, steering limits).
* **goal** (not part of the request) — ``s_min``, the arc length of the goal region's centroid on the
  reference (at most the reference's length less a vehicle length), for :class:`planner_tools.sim.Goal`;
  ``None`` for a goal given by time only (the simulator then drives to the reference's end). The
  goal's time window is recorded but not enforced.

The driven motion of a run becomes a CommonRoad solution (:func:`write_solution`: commonroad-io's
solution writer, kinematic single-track model, vehicle type :data:`VEHICLE_TYPE`), whose transitions
commonroad-drivability-checker's feasibility checker judges (:func:`feasible_transitions`).

commonroad-io is imported lazily (the optional extra ``commonroad``): everything that needs no
scenario file — :func:`resample`, :func:`smooth`, :func:`boundary_widths`, :func:`prediction_rows`,
:func:`constant_velocity_rows`, :func:`target_speed`, :func:`request_from_reduced` — works without it.
Units: metres [m], seconds [s], radians [rad].
"""

from __future__ import annotations

import contextlib
import copy
import gzip
import io
import itertools
import json
import logging
import math
import shutil
import tempfile
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import gaussian_filter1d, grey_closing

from planner.collision import STATIC_MOTION
from planner.kinematics import lateral_curvature
from planner.problem import CAR_FIELDS, Vehicle
from planner.reference import FloatArray
from planner_tools.extras import COMMONROAD, MissingExtraError

#: spacing of the reference line's points [m]
SPACING = 1.0
#: standard deviation of the Gaussian smoothing the joined centre lines [m]
SMOOTHING_SIGMA = 1.5
#: the route starts this far behind the ego [m]
BEHIND_EGO = 10.0
#: successors are appended until the route ends this far past the goal lanelet [m]
BEYOND_GOAL = 30.0
#: the route ends at most this far ahead of the ego [m]
MAX_AHEAD = 500.0
#: a route that ends at the map's edge where recorded traffic drives off it goes on straight this far
#: [m] (:func:`_road_goes_on`): 31 m/s over the 8 s horizon
MAP_EDGE_EXTENSION = 250.0
#: a vehicle that leaves the recorded area (:func:`continued_predictions`) this near the route's end
#: [m], heading along it (within :data:`LEAVING_HEADING` [rad]), drove off the map there
LEAVING_REACH, LEAVING_HEADING = 20.0, 0.45
#: the straight continuation (as wide as :data:`EDGE_CLEARANCE` [m] either side) meets no lanelet off the
#: route beyond its first :data:`EDGE_START` [m]
EDGE_CLEARANCE, EDGE_START = 1.5, 5.0
#: most lanelets a survival route (no goal position) follows, as commonroad-route-planner
SURVIVAL_LANELETS = 20
#: cost of a lane change in the route search [m]
LANE_CHANGE_COST = 50.0
#: lane edges are extended by rays this long at both ends before measuring widths [m]
EDGE_EXTENSION = 5.0
#: smallest target speed written into a request [m/s]
MIN_TARGET_SPEED = 5.0
#: the road reaches at most this far beyond the lane on each side [m] (two lanes)
ROAD_BEYOND = 7.5
#: step of the scan along the normal for the road's widths [m]
ROAD_STEP = 0.1
#: lanelets closer than twice this are one surface (their shared edges do not meet exactly) [m]
SURFACE_GAP = 0.25
#: a road narrower than its neighbours on either side at this many consecutive points or fewer is a
#: sliver of the map between lanelets, not a narrowing: it takes the narrower neighbour's width
ROAD_SLIVER = 2
#: lanelet types a vehicle does not drive on: they are not part of the road
NOT_DRIVABLE = frozenset({"sidewalk", "crosswalk", "bicycleLane", "border", "restricted", "restricted_area"})
#: vehicle of the shared requests
VEHICLE: dict[str, float] = {
    "length": 4.508,
    "width": 1.61,
    "max_speed": 40.0,
    "max_acceleration": 3.0,
    "max_deceleration": 8.0,
    "max_lateral_acceleration": 4.0,
    "max_curvature": 0.3,
}
#: CommonRoad's vehicle type of the converted car and of the solutions (2: BMW 320i)
VEHICLE_TYPE = 2
#: planning horizon and step of the shared requests [s]
HORIZON_TIME, DT = 8.0, 0.1
#: most predicted states per obstacle (the request's limit)
MAX_STATES = 2000


class CommonRoadError(Exception):
    """A scenario that cannot be converted (no route, no lanelet under the ego, unreadable file)."""


# --------------------------------------------------------------------------------------------------
# Pure geometry (no commonroad-io)
# --------------------------------------------------------------------------------------------------


def arc_length(points: ArrayLike) -> FloatArray:
    """Cumulative chord length of a polyline (n, 2) [m], shape (n,)."""
    p = np.asarray(points, dtype=float)
    return np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))))


def resample(points: ArrayLike, spacing: float = SPACING) -> tuple[FloatArray, FloatArray]:
    """Points every ``spacing`` [m] of arc length along a polyline (n, 2), the last one kept.

    Returns ``(points (m, 2), s (m,))`` with ``s`` the arc length of each resampled point on the input.
    Consecutive duplicate input points are ignored.
    """
    p = np.asarray(points, dtype=float)
    s = arc_length(p)
    keep = np.concatenate(([True], np.diff(s) > 1e-9))
    p, s = p[keep], s[keep]
    if p.shape[0] < 2:
        raise ValueError("a polyline needs two distinct points")
    n = max(1, int(np.ceil(s[-1] / spacing - 1e-9)))
    t = np.linspace(0.0, s[-1], n + 1)
    return np.column_stack((np.interp(t, s, p[:, 0]), np.interp(t, s, p[:, 1]))), t


def _end_direction(points: FloatArray) -> FloatArray:
    """The unit direction of a polyline's (n, 2) last segment."""
    step = points[-1] - points[-2]
    return np.asarray(step / np.hypot(*step))


def _road_goes_on(
    network: Any, route: list[int], points: FloatArray, obstacles: Sequence[dict[str, Any]]
) -> bool:
    """Whether the road goes on straight past the route's end (``points``: the reference's, (n, 2)): the
    route's last lanelet has no successor (the map ends there), a vehicle of the request's ``obstacles``
    left the recorded area there (one :func:`continued_predictions` drives on past its recording, whose
    last recorded state lies near the end, heading along it), and the straight continuation meets no
    other lanelet (it leaves the map, it does not run into another part of it)."""
    if network.find_lanelet_by_id(route[-1]).successor:
        return False
    end, direction = points[-1], _end_direction(points)
    heading = math.atan2(direction[1], direction[0])
    _, leaves = continued_predictions(obstacles, HORIZON_TIME)
    lasts = [ob["prediction"][-1] for ob in obstacles if str(ob["id"]) in leaves]
    if not any(
        math.hypot(float(st["x"]) - end[0], float(st["y"]) - end[1]) <= LEAVING_REACH
        and abs(_wrap(float(st["heading"]) - heading)) <= LEAVING_HEADING
        for st in lasts
    ):
        return False
    far = end + np.outer(np.linspace(EDGE_START, MAP_EDGE_EXTENSION, 2), direction)
    corridor = shapely.LineString(far).buffer(EDGE_CLEARANCE)
    on_route = set(route)
    return not any(
        la.polygon.shapely_object.intersects(corridor)
        for la in network.lanelets
        if la.lanelet_id not in on_route
    )


def continued_straight(
    points: FloatArray, widths: tuple[FloatArray, ...], length: float, spacing: float = SPACING
) -> tuple[FloatArray, tuple[FloatArray, ...]]:
    """A polyline (n, 2) continued straight along its last segment's direction by ``length`` [m], a point
    every ``spacing`` [m], and the per-point ``widths`` (each (n,)) continued with their last values."""
    p = np.asarray(points, dtype=float)
    direction = _end_direction(p)
    n = max(1, int(np.ceil(length / spacing - 1e-9)))
    more = p[-1] + np.linspace(length / n, length, n)[:, None] * direction
    kept = tuple(np.concatenate((w, np.full(n, w[-1]))) for w in widths)
    return np.vstack((p, more)), kept


def smooth(points: ArrayLike, sigma: float = SMOOTHING_SIGMA, spacing: float = SPACING) -> FloatArray:
    """Gaussian smoothing (``sigma`` [m]) of uniformly spaced points (spacing [m]), end points kept.

    The ends are padded by reflecting the polyline through its end points, so a straight end stays
    straight and the first and last points do not move.
    """
    p = np.asarray(points, dtype=float)
    if sigma <= 0.0 or p.shape[0] < 3:
        return p.copy()
    pad = int(np.ceil(4 * sigma / spacing))
    head = 2 * p[0] - p[1 : pad + 1][::-1]
    tail = 2 * p[-1] - p[-pad - 1 : -1][::-1]
    ext = np.vstack((head, p, tail))
    out = gaussian_filter1d(ext, sigma / spacing, axis=0, mode="nearest")[pad : pad + p.shape[0]]
    out[0], out[-1] = p[0], p[-1]
    return np.asarray(out)


def _extend(line: FloatArray, length: float) -> FloatArray:
    """A polyline with rays of ``length`` [m] added before its first and after its last point, along
    the chord to the first vertex at least 1 m from the end (a tiny hook at an end is ignored)."""
    s = arc_length(line)
    i0 = min(int(np.searchsorted(s, 1.0)), line.shape[0] - 1)
    i1 = max(int(np.searchsorted(s, s[-1] - 1.0, side="right")) - 1, 0)
    d0 = line[i0] - line[0]
    d1 = line[-1] - line[i1]
    d0 /= max(float(np.hypot(*d0)), 1e-12)
    d1 /= max(float(np.hypot(*d1)), 1e-12)
    return np.vstack((line[0] - length * d0, line, line[-1] + length * d1))


#: a lane edge vertex where the edge turns by more than this is a spike of the map and dropped [rad]
SPIKE_TURN = math.radians(120.0)


def clean_edge(line: ArrayLike) -> FloatArray:
    """A lane edge polyline without repeated points and without spikes (vertices where it turns back
    by more than :data:`SPIKE_TURN`, an artefact of some converted maps)."""
    arr = np.asarray(line, dtype=float).reshape(-1, 2)
    for _ in range(arr.shape[0]):
        arr = arr[np.concatenate(([True], np.hypot(*np.diff(arr, axis=0).T) > 1e-9))]
        if arr.shape[0] < 3:
            break
        e = np.diff(arr, axis=0)
        turn = np.abs(
            np.arctan2(e[:-1, 0] * e[1:, 1] - e[:-1, 1] * e[1:, 0], np.einsum("ij,ij->i", e[:-1], e[1:]))
        )
        spikes = np.flatnonzero(turn > SPIKE_TURN)
        if spikes.size == 0:
            break
        arr = np.delete(arr, spikes[:1] + 1, axis=0)
    if arr.shape[0] < 2:
        raise ValueError("a lane edge needs two distinct points")
    return arr


def boundary_widths(
    points: ArrayLike,
    left_edge: ArrayLike,
    right_edge: ArrayLike,
    *,
    extension: float = EDGE_EXTENSION,
    normals: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Lane widths [m] left and right of each reference point (n, 2): its distance to the left and
    right edge polylines (both in driving order).

    Both edges are extended by rays of ``extension`` [m] at their ends, so a point beside an end is
    measured sideways, not to the end point. A point outside the lane (the polygon the two edges
    enclose) gets width 0 on the side of the nearer edge — the side it has crossed.

    With the points' left ``normals`` (unit, (n, 2)), the distance is measured along the normal, as the
    planner offsets the reference (:func:`along_normal`); else it is the nearest distance, which on the
    inside of a tight corner is the corner's vertex, well short of the edge along the normal.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    left_line = _extend(clean_edge(left_edge), extension)
    right_line = _extend(clean_edge(right_edge), extension)
    left = shapely.LineString(left_line)
    right = shapely.LineString(right_line)
    geoms = shapely.points(pts)
    d_left = np.asarray(shapely.distance(geoms, left), dtype=float)
    d_right = np.asarray(shapely.distance(geoms, right), dtype=float)
    if normals is not None:
        normal = np.asarray(normals, dtype=float).reshape(-1, 2)
        d_left = along_normal(pts, normal, left_line, d_left)
        d_right = along_normal(pts, -normal, right_line, d_right)
    ring = np.vstack((shapely.get_coordinates(left), shapely.get_coordinates(right)[::-1]))
    lane = shapely.make_valid(shapely.Polygon(ring))
    inside = np.asarray(shapely.contains_xy(lane, pts[:, 0], pts[:, 1]), dtype=bool)
    out_left = ~inside & (d_left <= d_right)
    out_right = ~inside & ~out_left
    return np.where(out_left, 0.0, d_left), np.where(out_right, 0.0, d_right)


def left_normals(points: FloatArray) -> FloatArray:
    """The unit normals (n, 2), pointing left, of a polyline (n, 2) in driving order (central
    differences)."""
    tangent = np.gradient(points, axis=0)
    tangent /= np.maximum(np.hypot(tangent[:, 0], tangent[:, 1]), 1e-12)[:, None]
    return np.column_stack((-tangent[:, 1], tangent[:, 0]))


#: a width along the normal exceeds the nearest distance to the edge by at most this [m] (a ray that
#: grazes an edge meets it far away)
NORMAL_EXCESS = 1.0


def along_normal(
    points: FloatArray, directions: FloatArray, edge: FloatArray, nearest: FloatArray
) -> FloatArray:
    """How far each point (n, 2) may go along its unit direction (n, 2) before it meets ``edge`` (a
    polyline), as the planner's lane model reads a width — from a point of the reference, along its normal
    — at least the ``nearest`` distance to the edge and at most :data:`NORMAL_EXCESS` beyond it.

    Between two points the planner interpolates the widths linearly; where a vertex of the edge (the
    inside of a corner) lies between the two points' normals, closer to the line they span than the
    interpolation, both points' widths are lowered to the vertex's distance from that line, so that the
    interpolated edge never passes beyond the vertex (but never below ``nearest``)."""
    start, seg = edge[:-1], np.diff(edge, axis=0)
    gap = start[None, :, :] - points[:, None, :]  # (n, m, 2)
    den = directions[:, None, 0] * seg[None, :, 1] - directions[:, None, 1] * seg[None, :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (gap[..., 0] * seg[None, :, 1] - gap[..., 1] * seg[None, :, 0]) / den
        u = (gap[..., 0] * directions[:, None, 1] - gap[..., 1] * directions[:, None, 0]) / den
    hit = np.isfinite(t) & (t > 0.0) & (u >= 0.0) & (u <= 1.0)
    reach = np.min(np.where(hit, t, np.inf), axis=1)
    width = np.clip(np.where(np.isfinite(reach), reach, nearest), nearest, nearest + NORMAL_EXCESS)
    if points.shape[0] < 2:
        return width
    # vertices between two points' normals, on their side, closer to the chord than the widths
    chord = np.diff(points, axis=0)
    length = np.maximum(np.hypot(chord[:, 0], chord[:, 1]), 1e-12)
    rel = edge[:, None, :] - points[None, :-1, :]  # (v, n − 1, 2)
    along = (rel[..., 0] * chord[:, 0] + rel[..., 1] * chord[:, 1]) / length**2
    side = directions[:-1, 0] * rel[..., 0] + directions[:-1, 1] * rel[..., 1]  # the offset on the chord
    between = (along > 0.0) & (along < 1.0) & (side > 0.0)
    cap = np.min(np.where(between, side, np.inf), axis=0)
    width[:-1] = np.maximum(np.minimum(width[:-1], cap), nearest[:-1])
    width[1:] = np.maximum(np.minimum(width[1:], cap), nearest[1:])
    return width


def surface_widths(
    points: ArrayLike,
    left: ArrayLike,
    right: ArrayLike,
    surface: Any,
    *,
    beyond: float = ROAD_BEYOND,
    step: float = ROAD_STEP,
) -> tuple[FloatArray, FloatArray]:
    """Road widths [m] left and right of each point (n, 2) of a line in driving order with lane widths
    ``left``, ``right`` [m]: from the lane's edge outwards along the line's normal, as far as ``surface``
    (a shapely geometry, the drivable area) goes on without a gap, at most ``beyond`` [m] beyond the
    lane; never less than the lane. A dip at :data:`ROAD_SLIVER` points or fewer between wider
    neighbours is filled (a morphological closing along the line)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    normal = left_normals(pts)
    offsets = np.arange(1, int(np.ceil(beyond / step)) + 1) * step  # beyond the lane's edge
    shapely.prepare(surface)
    out = []
    for sign, lane in ((1.0, np.asarray(left, dtype=float)), (-1.0, np.asarray(right, dtype=float))):
        reach = lane[:, None] + offsets[None, :]
        xy = pts[:, None, :] + sign * reach[..., None] * normal[:, None, :]
        inside = shapely.contains_xy(surface, xy[..., 0], xy[..., 1])
        gap = np.where(inside.all(axis=1), offsets.shape[0], np.argmin(inside, axis=1))  # first off it
        extra = np.where(gap > 0, offsets[np.maximum(gap - 1, 0)], 0.0)
        extra = grey_closing(np.asarray(extra, dtype=float), size=(ROAD_SLIVER + 2,), mode="nearest")
        out.append(lane + extra)
    return out[0], out[1]


def drivable_surface(network: Any) -> Any:
    """The union of the lanelets a vehicle may drive on (see :data:`NOT_DRIVABLE`), closed by
    :data:`SURFACE_GAP` (grown, then shrunk back) so that neighbours touch."""
    polygons = []
    for la in network.lanelets:
        kinds = {getattr(k, "value", str(k)) for k in (la.lanelet_type or set())}
        if kinds & NOT_DRIVABLE:
            continue
        ring = np.vstack((la.left_vertices, la.right_vertices[::-1]))
        polygons.append(shapely.make_valid(shapely.Polygon(ring)).buffer(SURFACE_GAP))
    return shapely.unary_union(polygons).buffer(-SURFACE_GAP)


def prediction_rows(
    time_steps: ArrayLike,
    positions: ArrayLike,
    orientations: ArrayLike,
    *,
    dt: float,
    t0_step: int = 0,
    offset: tuple[float, float] = (0.0, 0.0),
) -> FloatArray:
    """Recorded states → prediction rows ``t, x, y, heading`` (k, 4) of a box's centre.

    Args:
        time_steps: CommonRoad time steps (k,), increasing.
        positions: state positions (k, 2) [m].
        orientations: headings (k,) [rad]; continuous in the output, the first in (−π, π].
        dt: the scenario's time step [s].
        t0_step: the ego's initial time step: ``t = (time_step − t0_step)·dt``; earlier states dropped.
        offset: the box centre in the obstacle's frame relative to its state position [m] (CommonRoad's
            ``(−origin_x_shift, 0)``).
    """
    k = np.asarray(time_steps, dtype=float)
    xy = np.asarray(positions, dtype=float).reshape(-1, 2)
    heading = np.unwrap(np.asarray(orientations, dtype=float))
    if heading.size:  # continuous, starting in (−π, π]
        heading = heading + (_wrap(float(heading[0])) - heading[0])
    c, s = np.cos(heading), np.sin(heading)
    cx = xy[:, 0] + offset[0] * c - offset[1] * s
    cy = xy[:, 1] + offset[0] * s + offset[1] * c
    rows = np.column_stack(((k - t0_step) * dt, cx, cy, heading))
    rows = rows[rows[:, 0] >= -1e-9]
    if rows.shape[0] > MAX_STATES:
        rows = rows[np.linspace(0, rows.shape[0] - 1, MAX_STATES).round().astype(int)]
    return np.asarray(rows)


#: a recording that ends less than this before the latest one ends with it [s]
_END_TOLERANCE = 1e-6


def constant_velocity_rows(
    t_start: float, t_end: float, position: ArrayLike, heading: float, speed: float, step: float
) -> FloatArray:
    """Prediction rows ``t, x, y, heading`` from ``t_start`` to ``t_end`` [s] every ``step`` [s] of a
    centre moving straight at ``speed`` [m/s] from ``position`` [m] at ``t_start``."""
    n = max(1, int(np.ceil((t_end - t_start) / step - 1e-9)))
    t = t_start + np.arange(n + 1) * step
    t[-1] = max(t_end, t_start + step)
    p = np.asarray(position, dtype=float)
    dist = speed * (t - t_start)
    return np.column_stack(
        (t, p[0] + dist * math.cos(heading), p[1] + dist * math.sin(heading), np.full_like(t, heading))
    )


def continued_predictions(
    obstacles: Sequence[dict[str, Any]], seconds: float
) -> tuple[list[dict[str, Any]], dict[str, float]]:
    """The request's obstacles with each recorded vehicle that leaves the recorded area driving on past
    the end of its recording, and when each such recording ends.

    CommonRoad's obstacles exist only over their recorded time span: a vehicle whose trajectory ends
    before the recording does has left the recorded area (a highway's measured stretch, a map's edge),
    it has not stopped. A request's prediction is held at its last state (:func:`planner.collision.
    prediction_at`), so as it stands such a vehicle would stop dead where its recording ends — a
    phantom wall across the road that the planner brakes for, steers round and stops before.

    The recording's end is the latest last state of a moving vehicle (one whose last two states move
    apart by more than :data:`planner.collision.STATIC_MOTION` over ``seconds``); a moving vehicle whose
    prediction ends before it gets one more state ``seconds`` [s] later, straight on at its last
    velocity and heading (the prediction is linear between states: constant velocity), as the shared
    requests already do for set-based predictions. Vehicles that stand, and those recorded to the end
    (whose recording stops with the scenario, not because they left), are as they were.

    Returns:
        the obstacles (the input not modified) and, for each continued vehicle, the time [s] of its
        last recorded state: after it the vehicle is no longer in the scene
        (:func:`planner_tools.sim.simulate`'s ``leaves``).
    """
    moving: dict[int, tuple[float, float, float]] = {}  # index → (last t, vx, vy)
    for i, ob in enumerate(obstacles):
        pred = ob.get("prediction")
        if not pred or len(pred) < 2:
            continue
        a, b = pred[-2], pred[-1]
        step = float(b["t"]) - float(a["t"])
        vx, vy = (float(b["x"]) - float(a["x"])) / step, (float(b["y"]) - float(a["y"])) / step
        if math.hypot(vx, vy) * seconds > STATIC_MOTION:
            moving[i] = (float(b["t"]), vx, vy)
    if not moving:
        return list(obstacles), {}
    recorded = max(end for end, _, _ in moving.values())
    out: list[dict[str, Any]] = []
    leaves: dict[str, float] = {}
    for i, ob in enumerate(obstacles):
        if i not in moving or not moving[i][0] < recorded - _END_TOLERANCE:
            out.append(ob)
            continue
        end, vx, vy = moving[i]
        last = ob["prediction"][-1]
        on = {
            "t": _r(end + seconds, 4),
            "x": _r(float(last["x"]) + vx * seconds),
            "y": _r(float(last["y"]) + vy * seconds),
            "heading": last["heading"],
        }
        out.append({**ob, "prediction": [*ob["prediction"], on]})
        leaves[str(ob["id"])] = end
    return out, leaves


def target_speed(ego_speed: float, goal_speed: tuple[float, float] | None = None) -> float:
    """The request's target speed [m/s]: the largest of the ego's speed, the middle of the goal's
    speed interval (its negative part ignored) and :data:`MIN_TARGET_SPEED`, to 0.01 m/s."""
    candidates = [ego_speed, MIN_TARGET_SPEED]
    if goal_speed is not None:
        lo, hi = max(goal_speed[0], 0.0), max(goal_speed[1], 0.0)
        candidates.append(0.5 * (lo + hi))
    return round(max(candidates), 2)


def _wrap(angle: float) -> float:
    return math.atan2(math.sin(angle), math.cos(angle))


def _r(value: float, digits: int = 3) -> float:
    return round(float(value), digits)


def _rows_json(rows: FloatArray) -> list[dict[str, float]]:
    return [{"t": _r(t, 4), "x": _r(x), "y": _r(y), "heading": _r(h, 5)} for t, x, y, h in rows.tolist()]


def _points_json(points: ArrayLike) -> list[list[float]]:
    return [[_r(x), _r(y)] for x, y in np.asarray(points, dtype=float).tolist()]


# --------------------------------------------------------------------------------------------------
# The result
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Conversion:
    """A scenario in the service's terms.

    Attributes:
        name: scenario name (file stem).
        request: the planning request (JSON data of :class:`app.models.planning.PlanningRequest`).
        goal: ``s_min`` [m] on the reference or ``None``; ``time`` window [s] or ``None``; ``region``
            polygon [[x, y], …] or ``None`` (informative).
        info: route lanelet ids, length, obstacle counts, … (informative).
    """

    name: str
    request: dict[str, Any]
    goal: dict[str, Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)

    def sim_goal(self) -> Any:
        """The :class:`planner_tools.sim.Goal` of ``goal`` (``None``: the simulator's default)."""
        from planner_tools.sim import Goal

        s_min = self.goal.get("s_min")
        return None if s_min is None else Goal(s_min=float(s_min))

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "request": self.request, "goal": self.goal, "info": self.info}


# --------------------------------------------------------------------------------------------------
# JSON inputs: a request (with an index.json beside it) or a reduced scenario
# --------------------------------------------------------------------------------------------------


def _repair_end_widths(width: list[float]) -> list[float]:
    """A 0 width at the first or last point next to a positive one is a conversion artefact: take
    the neighbour's."""
    w = list(width)
    if len(w) >= 2 and w[0] == 0.0 < w[1]:
        w[0] = w[1]
    if len(w) >= 2 and w[-1] == 0.0 < w[-2]:
        w[-1] = w[-2]
    return w


def request_from_reduced(data: dict[str, Any]) -> Conversion:
    """A reduced scenario (``commonroad-json/*.json``: ``reference_line``, ``left_width``/``right_width``,
    obstacles with ``trajectory``, ``ego``, ``goal``) as a :class:`Conversion` (widths repaired at the
    ends, see :func:`_repair_end_widths`)."""
    obstacles: list[dict[str, Any]] = []
    for ob in data.get("obstacles", []):
        traj = ob.get("trajectory") or []
        if ob.get("kind") == "dynamic" and traj:
            obstacles.append(
                {
                    "id": str(ob["id"]),
                    "length": float(ob["length"]),
                    "width": float(ob["width"]),
                    "prediction": [{k: float(st[k]) for k in ("t", "x", "y", "heading")} for st in traj],
                }
            )
        elif ob.get("polygon"):
            obstacles.append(
                {"id": str(ob["id"]), "polygon": [[float(x), float(y)] for x, y in ob["polygon"]]}
            )
    ego = data["ego"]
    goal = data.get("goal") or {}
    speeds = [st.get("velocity") for st in goal.get("states", []) if st.get("velocity")]
    request = {
        "reference_line": data["reference_line"],
        "lane": {
            "left_width": _repair_end_widths(data["left_width"]),
            "right_width": _repair_end_widths(data["right_width"]),
        },
        "obstacles": obstacles,
        "ego": {
            "x": float(ego["x"]),
            "y": float(ego["y"]),
            "heading": _wrap(float(ego["heading"])),
            "speed": float(ego.get("speed", 0.0)),
            "acceleration": 0.0,
        },
        "vehicle": dict(VEHICLE),
        "options": {
            "horizon_time": HORIZON_TIME,
            "dt": DT,
            "target_speed": target_speed(float(ego.get("speed", 0.0)), tuple(speeds[0]) if speeds else None),
        },
    }
    name = str(data.get("name") or data.get("scenario_id") or "scenario")
    return Conversion(name, request, {"s_min": goal.get("s_goal")}, {"source": "reduced json"})


def load_json(path: str | Path) -> Conversion:
    """A request JSON (goal from an ``index.json`` beside it, by name, if there is one) or a reduced
    scenario JSON."""
    p = Path(path)
    data = json.loads(p.read_text())
    if "lane" in data:
        goal: dict[str, Any] = {"s_min": None}
        index = p.parent / "index.json"
        if index.exists():
            for entry in json.loads(index.read_text()):
                if entry.get("name") == p.stem:
                    goal = {"s_min": (entry.get("goal") or {}).get("s_goal")}
        return Conversion(p.stem, data, goal, {"source": "request json"})
    if "left_width" in data:
        conv = request_from_reduced(data)
        return Conversion(p.stem, conv.request, conv.goal, conv.info)
    raise CommonRoadError(f"{p}: neither a planning request nor a reduced CommonRoad scenario")


# --------------------------------------------------------------------------------------------------
# CommonRoad XML (needs commonroad-io)
# --------------------------------------------------------------------------------------------------


def _require_commonroad() -> None:
    try:
        COMMONROAD.require("reading CommonRoad XML")
    except MissingExtraError as exc:
        raise CommonRoadError(str(exc)) from exc


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Silence commonroad-io's warnings about old file formats while reading."""
    logger = logging.getLogger("commonroad")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()):
            warnings.simplefilter("ignore")
            yield
    finally:
        logger.setLevel(level)


def scenario_name(path: str | Path) -> str:
    """A scenario file's name without its suffixes ``.xml``, ``.xml.gz``, ``.json``."""
    name = Path(path).name
    for suffix in (".xml.gz", ".xml", ".json"):
        if name.lower().endswith(suffix):
            return name[: -len(suffix)]
    return Path(path).stem


@contextlib.contextmanager
def _xml_file(path: str | Path) -> Iterator[str]:
    """A path commonroad-io can open: ``path`` itself, or a gzip-compressed ``*.xml.gz`` decompressed
    to a temporary file (deleted afterwards)."""
    if not str(path).lower().endswith(".gz"):
        yield str(path)
        return
    with tempfile.TemporaryDirectory(prefix="kappa-cr-") as tmp:
        out = Path(tmp) / f"{scenario_name(path)}.xml"
        try:
            with gzip.open(path, "rb") as src, out.open("wb") as dst:
                shutil.copyfileobj(src, dst)
        except (OSError, EOFError) as exc:
            raise CommonRoadError(f"{path}: not a readable gzip file ({exc})") from exc
        yield str(out)


def read_scenario(path: str | Path, planning_problem_id: int | None = None) -> tuple[Any, Any]:
    """``(scenario, planning problem)`` of a CommonRoad XML file, plain or gzip-compressed
    (``*.xml.gz``), the planning problem with the smallest id unless ``planning_problem_id`` is given."""
    _require_commonroad()
    from commonroad.common.file_reader import CommonRoadFileReader

    try:
        with _xml_file(path) as xml, _quiet():
            scenario, problems = CommonRoadFileReader(xml).open()
    except CommonRoadError:
        raise
    except Exception as exc:  # commonroad-io raises anything on a broken file
        raise CommonRoadError(f"{path}: not a readable CommonRoad scenario ({exc})") from exc
    found = problems.planning_problem_dict
    if not found:
        raise CommonRoadError(f"{path}: the scenario has no planning problem")
    pid = min(found) if planning_problem_id is None else planning_problem_id
    if pid not in found:
        raise CommonRoadError(f"{path}: no planning problem {pid} (there are {sorted(found)})")
    return scenario, found[pid]


def _shapely(occupancy: Any) -> Any:
    """The shapely geometry of a commonroad-io occupancy / shape (any version)."""
    geom = getattr(occupancy, "shapely_object", None)
    if geom is None and hasattr(occupancy, "shape"):
        geom = occupancy.shape.shapely_object
    if geom is None:
        raise CommonRoadError(f"cannot read the geometry of {type(occupancy).__name__}")
    return geom


def _interval(value: Any) -> tuple[float, float] | None:
    if value is None:
        return None
    if hasattr(value, "start") and hasattr(value, "end"):
        return float(value.start), float(value.end)
    return float(value), float(value)


def _xy(position: Any) -> FloatArray:
    """A state's position [m]: a point, or the centroid of an uncertain position (a shape)."""
    if isinstance(position, np.ndarray | list | tuple):
        return np.asarray(position, dtype=float).reshape(2)
    return np.asarray(_shapely(position).centroid.coords[0], dtype=float)


def _angle(orientation: Any) -> float:
    """A state's orientation [rad]: a number, or the middle of an uncertain one (an interval)."""
    span = _interval(orientation)
    return 0.0 if span is None else 0.5 * (span[0] + span[1])


def _heading_ok(lanelet: Any, position: FloatArray, heading: float) -> bool:
    try:
        along = float(lanelet.orientation_by_position(position))
    except Exception:  # position beyond the lanelet's ends
        return True
    return abs(_wrap(along - heading)) < 0.5 * math.pi


def _lanelet_length(lanelet: Any) -> float:
    return float(arc_length(lanelet.center_vertices)[-1])


def _side_chain(network: Any, lanelet: Any, side: str) -> Any:
    """The outermost same-direction lanelet beside ``lanelet`` on ``side`` (``left``/``right``)."""
    seen = {lanelet.lanelet_id}
    current = lanelet
    while True:
        adj = getattr(current, f"adj_{side}")
        same = getattr(current, f"adj_{side}_same_direction")
        if adj is None or not same or adj in seen:
            return current
        nxt = network.find_lanelet_by_id(adj)
        if nxt is None:
            return current
        seen.add(adj)
        current = nxt


def _route_graph(network: Any) -> Any:
    import networkx as nx

    graph = nx.DiGraph()
    for la in network.lanelets:
        graph.add_node(la.lanelet_id)
        length = _lanelet_length(la)
        for succ in la.successor:
            graph.add_edge(la.lanelet_id, succ, weight=length, kind="successor")
        for side in ("left", "right"):
            adj = getattr(la, f"adj_{side}")
            if adj is not None and getattr(la, f"adj_{side}_same_direction"):
                graph.add_edge(la.lanelet_id, adj, weight=LANE_CHANGE_COST, kind="change")
    return graph


@dataclass(frozen=True)
class _GoalRegion:
    shape: Any | None
    lanelets: tuple[int, ...]
    time: tuple[float, float] | None
    speed: tuple[float, float] | None


def _goal_region(network: Any, problem: Any, dt: float, t0_step: int) -> _GoalRegion:
    goal = problem.goal
    shapes: list[Any] = []
    times: list[tuple[float, float]] = []
    speed = None
    orient: tuple[float, float] | None = None
    for st in goal.state_list:
        if getattr(st, "position", None) is not None:
            shapes.append(_shapely(st.position))
        t = _interval(getattr(st, "time_step", None))
        if t is not None:
            times.append(((t[0] - t0_step) * dt, (t[1] - t0_step) * dt))
        if getattr(st, "velocity", None) is not None and speed is None:
            speed = _interval(st.velocity)
        if getattr(st, "orientation", None) is not None and orient is None:
            orient = _interval(st.orientation)
    lanelets: list[int] = []
    by_goal = goal.lanelets_of_goal_position or {}
    for ids in by_goal.values():
        lanelets.extend(int(i) for i in ids)
    shape = shapely.unary_union(shapes) if shapes else None
    if shape is None and lanelets:
        shape = shapely.unary_union([_shapely(network.find_lanelet_by_id(i).polygon) for i in lanelets])
    if shape is not None and not lanelets:
        # the lanelets under the goal's centroid, else every lanelet the goal region touches
        centroid = np.asarray(shape.centroid.coords[0])
        lanelets = [int(i) for i in network.find_lanelet_by_position([centroid])[0]]
        lanelets = lanelets or [int(i) for i in network.find_lanelet_by_shapely_shape(shape)]
        if orient is not None:
            mid = 0.5 * (orient[0] + orient[1])
            centre = np.asarray(shape.centroid.coords[0])
            lanelets = [
                i for i in lanelets if _heading_ok(network.find_lanelet_by_id(i), centre, mid)
            ] or lanelets
    time_window = (min(t[0] for t in times), max(t[1] for t in times)) if times else None
    return _GoalRegion(shape, tuple(lanelets), time_window, speed)


def _route(network: Any, start: list[int], goal: _GoalRegion) -> list[int]:
    """Lanelet ids from a start lanelet to a goal lanelet (or a survival route)."""
    import networkx as nx

    if not goal.lanelets:
        lanelet = network.find_lanelet_by_id(start[0])
        route = [lanelet.lanelet_id]
        while lanelet.successor and len(route) < SURVIVAL_LANELETS:
            nxt = lanelet.successor[0]
            if nxt in route:
                break
            route.append(nxt)
            lanelet = network.find_lanelet_by_id(nxt)
        return route
    graph = _route_graph(network)
    best: tuple[float, list[int]] | None = None
    for s in start:
        try:
            lengths, paths = nx.single_source_dijkstra(graph, s, weight="weight")
        except nx.NodeNotFound:
            continue
        for g in goal.lanelets:
            if g in lengths and (best is None or lengths[g] < best[0]):
                best = (float(lengths[g]), list(paths[g]))
    if best is None:
        raise CommonRoadError(
            f"no route from lanelet(s) {start} to the goal lanelet(s) {list(goal.lanelets)}"
        )
    return best[1]


def _extend_route(network: Any, route: list[int], behind: float, beyond: float) -> tuple[list[int], int]:
    """Prepend first predecessors until ``behind`` [m] is covered, append first successors until
    ``beyond`` [m] is. Returns the route and how many lanelets were prepended."""
    out = list(route)
    covered, added = 0.0, 0
    while covered < behind:
        pred = network.find_lanelet_by_id(out[0]).predecessor
        if not pred or pred[0] in out:
            break
        out.insert(0, pred[0])
        covered += _lanelet_length(network.find_lanelet_by_id(pred[0]))
        added += 1
    covered = 0.0
    while covered < beyond:
        succ = network.find_lanelet_by_id(out[-1]).successor
        if not succ or succ[0] in out:
            break
        out.append(succ[0])
        covered += _lanelet_length(network.find_lanelet_by_id(succ[0]))
    return out, added


def _centerline(network: Any, route: list[int]) -> tuple[FloatArray, list[FloatArray], list[int]]:
    """Joined centre line of a route (n, 2), its driven stretches' centre lines, and the lanelet whose
    lane edges hold on each stretch. A lane change (a lanelet followed by its neighbour) is one
    stretch, blended from the first centre line to the last."""
    stretches: list[list[int]] = []
    beside = {
        la.lanelet_id: {a for a in (la.adj_left, la.adj_right) if a is not None} for la in network.lanelets
    }
    for lid in route:
        if stretches and lid in beside.get(stretches[-1][-1], set()):
            stretches[-1].append(lid)
        else:
            stretches.append([lid])
    pieces: list[FloatArray] = []
    owners: list[int] = []
    for group in stretches:
        first = np.asarray(network.find_lanelet_by_id(group[0]).center_vertices, dtype=float)
        piece = first
        if len(group) > 1:
            last = np.asarray(network.find_lanelet_by_id(group[-1]).center_vertices, dtype=float)
            n = max(first.shape[0], last.shape[0], 20)
            a, _ = resample(first, arc_length(first)[-1] / (n - 1))
            b, _ = resample(last, arc_length(last)[-1] / (n - 1))
            m = min(a.shape[0], b.shape[0])
            w = 0.5 - 0.5 * np.cos(np.linspace(0.0, math.pi, m))
            piece = (1.0 - w)[:, None] * a[:m] + w[:, None] * b[:m]
        pieces.append(piece)
        owners.append(group[-1])
    rest = [p[1:] if np.hypot(*(p[0] - q[-1])) < 1e-6 else p for q, p in itertools.pairwise(pieces)]
    joined = np.vstack([pieces[0], *rest])
    return joined, pieces, owners


def assign_pieces(
    points: ArrayLike, pieces: Sequence[ArrayLike], *, window: float = 15.0
) -> NDArray[np.intp]:
    """Index of the piece (a polyline of consecutive pieces of one line) nearest to each point (n, 2)
    of a line that follows the pieces, among those within ``window`` [m] of arc length of the point,
    so that a neighbouring leg of a hairpin is never chosen."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    s = arc_length(pts)
    lengths = np.array([arc_length(np.asarray(p, dtype=float))[-1] for p in pieces])
    ends = np.cumsum(lengths)
    starts = ends - lengths
    scale = s[-1] / max(float(ends[-1]), 1e-9)
    geoms = shapely.points(pts)
    dist = np.full((pts.shape[0], len(pieces)), np.inf)
    for k, piece in enumerate(pieces):
        arr = np.asarray(piece, dtype=float)
        line = shapely.LineString(arr) if arr.shape[0] > 1 else shapely.Point(arr[0])
        near = (s >= starts[k] * scale - window) & (s <= ends[k] * scale + window)
        dist[near, k] = shapely.distance(geoms[near], line)
    return np.asarray(np.argmin(dist, axis=1), dtype=np.intp)


def join_edges(edges: Sequence[ArrayLike], k: int, *, tolerance: float = 0.1) -> FloatArray:
    """Edge ``k`` of consecutive lane edges (polylines in driving order) joined with its neighbours
    ``k − 1`` and ``k + 1`` where they continue it (end and start within ``tolerance`` [m]), so that a
    point near a short lanelet is measured against the edge around it, not a ray off its end."""
    out = np.asarray(edges[k], dtype=float)
    if k > 0:
        before = np.asarray(edges[k - 1], dtype=float)
        if np.hypot(*(before[-1] - out[0])) <= tolerance:
            out = np.vstack((before[:-1], out))
    if k + 1 < len(edges):
        after = np.asarray(edges[k + 1], dtype=float)
        if np.hypot(*(after[0] - out[-1])) <= tolerance:
            out = np.vstack((out, after[1:]))
    return out


def _widths(
    network: Any, points: FloatArray, owner: NDArray[np.intp], lanelets: list[int]
) -> tuple[FloatArray, FloatArray]:
    lefts, rights = [], []
    for lid in lanelets:
        la = network.find_lanelet_by_id(lid)
        lefts.append(np.asarray(_side_chain(network, la, "left").left_vertices, dtype=float))
        rights.append(np.asarray(_side_chain(network, la, "right").right_vertices, dtype=float))
    left = np.zeros(points.shape[0])
    right = np.zeros(points.shape[0])
    normal = left_normals(points)
    for k in range(len(lanelets)):
        mask = owner == k
        if mask.any():
            left[mask], right[mask] = boundary_widths(
                points[mask], join_edges(lefts, k), join_edges(rights, k), normals=normal[mask]
            )
    return left, right


def _obstacle_offset(obstacle: Any, step: int) -> tuple[float, float, float, float]:
    """``(length, width, centre x, centre y)`` of an obstacle's shape in its own frame [m]: a
    rectangle's own size and ``origin_x_shift``, a circle's bounding square, else the box around its
    occupancy at ``step``."""
    shape = obstacle.obstacle_shape
    if hasattr(shape, "length") and hasattr(shape, "width") and not hasattr(shape, "total_length"):
        return float(shape.length), float(shape.width), -float(getattr(shape, "origin_x_shift", 0.0)), 0.0
    if hasattr(shape, "radius"):
        return 2.0 * float(shape.radius), 2.0 * float(shape.radius), 0.0, 0.0
    state = obstacle.state_at_time(step) or obstacle.initial_state
    geom = _shapely(obstacle.occupancy_at_time(state.time_step))
    pos = _xy(state.position)
    h = _angle(state.orientation)
    coords = shapely.get_coordinates(geom) - pos
    c, s = math.cos(h), math.sin(h)
    local = np.column_stack((coords[:, 0] * c + coords[:, 1] * s, -coords[:, 0] * s + coords[:, 1] * c))
    lo, hi = local.min(axis=0), local.max(axis=0)
    centre = 0.5 * (lo + hi)
    return float(hi[0] - lo[0]), float(hi[1] - lo[1]), float(centre[0]), float(centre[1])


def _obstacles(scenario: Any, t0_step: int) -> tuple[list[dict[str, Any]], int, int]:
    dt = float(scenario.dt)
    out: list[dict[str, Any]] = []
    n_static = n_dynamic = 0
    for ob in scenario.static_obstacles:
        geom = _shapely(ob.occupancy_at_time(ob.initial_state.time_step))
        parts = list(getattr(geom, "geoms", [geom]))
        for k, part in enumerate(parts):
            oid = str(ob.obstacle_id) if len(parts) == 1 else f"{ob.obstacle_id}.{k}"
            radius = getattr(ob.obstacle_shape, "radius", None)
            if radius is not None:
                c = part.centroid
                out.append({"id": oid, "circle": {"center": [_r(c.x), _r(c.y)], "radius": _r(radius)}})
            else:
                ring = np.asarray(part.exterior.coords)[:-1]
                out.append({"id": oid, "polygon": _points_json(ring)})
        n_static += 1
    for ob in scenario.dynamic_obstacles:
        init = ob.initial_state
        length, width, cx, cy = _obstacle_offset(ob, init.time_step)
        pred = ob.prediction
        states = [init]
        trajectory = getattr(pred, "trajectory", None)
        if trajectory is not None:
            states += [st for st in trajectory.state_list if st.time_step > init.time_step]
            steps = np.array([st.time_step for st in states], dtype=float)
            xy = np.array([_xy(st.position) for st in states], dtype=float)
            heading = np.array([_angle(st.orientation) for st in states], dtype=float)
            rows = prediction_rows(steps, xy, heading, dt=dt, t0_step=t0_step, offset=(cx, cy))
        else:  # set-based or none: constant velocity over the prediction's span
            end = getattr(pred, "final_time_step", init.time_step) if pred is not None else init.time_step
            t_start = (init.time_step - t0_step) * dt
            centre = prediction_rows(
                [init.time_step],
                [_xy(init.position)],
                [_angle(init.orientation)],
                dt=dt,
                t0_step=t0_step,
                offset=(cx, cy),
            )
            if centre.shape[0] == 0:
                continue
            rows = constant_velocity_rows(
                t_start,
                (int(end) - t0_step) * dt,
                centre[0, 1:3],
                _angle(init.orientation),
                _angle(getattr(init, "velocity", 0.0) or 0.0),
                max(dt, 0.1),
            )
        if rows.shape[0] == 0:
            continue
        out.append(
            {
                "id": str(ob.obstacle_id),
                "length": _r(length),
                "width": _r(width),
                "prediction": _rows_json(rows),
            }
        )
        n_dynamic += 1
    return out, n_static, n_dynamic


def convert_scenario(path: str | Path, *, planning_problem_id: int | None = None) -> Conversion:
    """A CommonRoad XML scenario and one of its planning problems as a :class:`Conversion`."""
    from planner.frenet import to_frenet
    from planner.reference import build_reference

    scenario, problem = read_scenario(path, planning_problem_id)
    network = scenario.lanelet_network
    dt = float(scenario.dt)
    init = problem.initial_state
    t0_step = int(init.time_step.start if hasattr(init.time_step, "start") else init.time_step)
    ego_xy = _xy(init.position)
    ego_heading = _wrap(_angle(init.orientation))
    ego_speed = float(getattr(init, "velocity", 0.0) or 0.0)

    found = network.find_lanelet_by_position([ego_xy])[0]
    if not found:
        raise CommonRoadError(f"{path}: the ego at {ego_xy.tolist()} is on no lanelet")
    start = [i for i in found if _heading_ok(network.find_lanelet_by_id(i), ego_xy, ego_heading)]
    if not start:
        # a route along them would run against the ego's heading: the planner refuses such a request
        raise CommonRoadError(
            f"{path}: the ego at {ego_xy.tolist()} heading {ego_heading:.2f} rad drives against every "
            f"lanelet there ({', '.join(map(str, found))}): no route in its direction"
        )
    goal = _goal_region(network, problem, dt, t0_step)
    core = _route(network, start, goal)
    route, _ = _extend_route(network, core, BEHIND_EGO + 5.0, BEYOND_GOAL if goal.lanelets else 0.0)

    raw, pieces, owners = _centerline(network, route)
    pts, _ = resample(raw, SPACING)
    pts = smooth(pts, SMOOTHING_SIGMA, SPACING)
    s_pts = arc_length(pts)
    ref = build_reference(pts)
    ego_s = float(to_frenet(ref, ego_xy[None, :]).s[0])
    keep = (s_pts >= ego_s - BEHIND_EGO - 1e-6) & (s_pts <= ego_s + MAX_AHEAD)
    owner = assign_pieces(pts, pieces)
    pts, owner = pts[keep], owner[keep]
    left, right = _widths(network, pts, owner, owners)
    road_left, road_right = surface_widths(pts, left, right, drivable_surface(network))
    obstacles, n_static, n_dynamic = _obstacles(scenario, t0_step)
    extension = 0.0
    if bool(keep[-1]) and _road_goes_on(network, route, pts, obstacles):
        extension = MAP_EDGE_EXTENSION
        pts, (left, right, road_left, road_right) = continued_straight(
            pts, (left, right, road_left, road_right), extension, SPACING
        )

    ref = build_reference(pts)
    ego_s = float(to_frenet(ref, ego_xy[None, :]).s[0])
    s_goal = None
    region = None
    if goal.shape is not None and not goal.shape.is_empty:
        centroid = np.asarray(goal.shape.centroid.coords[0])
        s_goal = float(to_frenet(ref, centroid[None, :]).s[0])
        s_goal = min(max(s_goal, ego_s), ref.length - VEHICLE["length"])
        hull = goal.shape if goal.shape.geom_type == "Polygon" else goal.shape.convex_hull
        region = _points_json(np.asarray(hull.exterior.coords)[:-1])

    accel = getattr(init, "acceleration", 0.0)
    vehicle = {**VEHICLE, **vehicle_type_car()}
    curvature = initial_curvature(getattr(init, "yaw_rate", None), ego_speed, vehicle)
    request = {
        "reference_line": _points_json(pts),
        "lane": {"left_width": [_r(w) for w in left], "right_width": [_r(w) for w in right]},
        "road": {"left_width": [_r(w) for w in road_left], "right_width": [_r(w) for w in road_right]},
        "obstacles": obstacles,
        "ego": {
            "x": _r(ego_xy[0]),
            "y": _r(ego_xy[1]),
            "heading": ego_heading,
            "speed": _r(ego_speed),
            "acceleration": _r(accel if accel is not None else 0.0),
            **({} if curvature is None else {"curvature": _r(curvature, 5)}),
        },
        "vehicle": vehicle,
        "options": {
            "horizon_time": HORIZON_TIME,
            "dt": DT,
            "target_speed": target_speed(ego_speed, goal.speed),
        },
    }
    info = {
        "source": Path(path).name,
        "scenario_id": str(scenario.scenario_id),
        "dt": dt,
        "initial_time_step": t0_step,
        "planning_problem_id": int(problem.planning_problem_id),
        "route_lanelet_ids": [int(i) for i in route],
        "length_m": _r(ref.length, 2),
        "map_edge_extension_m": extension,
        "kappa_max": _r(float(np.max(np.abs(ref.kappa))), 5),
        "s_ego": _r(ego_s, 2),
        "static": n_static,
        "dynamic": n_dynamic,
        "width_left_min_max": [_r(left.min(), 2), _r(left.max(), 2)],
        "width_right_min_max": [_r(right.min(), 2), _r(right.max(), 2)],
        "road_beyond_left_max": _r(float(np.max(road_left - left)), 2),
        "road_beyond_right_max": _r(float(np.max(road_right - right)), 2),
    }
    goal_out = {
        "s_min": None if s_goal is None else _r(s_goal, 2),
        "time": None if goal.time is None else [_r(goal.time[0], 2), _r(goal.time[1], 2)],
        "region": region,
    }
    return Conversion(Path(path).stem, request, goal_out, info)


#: below this speed [m/s] a yaw rate says little of the path's curvature (``κ = ψ̇ / v``)
YAW_RATE_MIN_SPEED = 0.5
#: the share of the vehicle's lateral acceleration limit a converted start's curvature is held to (the
#: planner's own margin, ``PlannerConfig.limit_margin``)
START_LATERAL_SHARE = 0.9


def initial_curvature(yaw_rate: float | None, speed: float, vehicle: dict[str, Any]) -> float | None:
    """The ego's path curvature [1/m] from CommonRoad's initial yaw rate ``ψ̇`` [rad/s] and speed [m/s]:
    ``ψ̇ / v`` (the kinematic single-track model turns its body at ``ψ̇ = v tan δ / ℓ``, ``v`` the rear
    axle's speed, whose path's curvature ``tan δ / ℓ`` a car's request gives), within what the request's
    ``vehicle`` can drive at that speed: its curvature limit and :data:`START_LATERAL_SHARE` of its
    lateral acceleration limit (a recorded driver may turn harder than that, and every answer is held
    to the limit from its first instant). None (the planner then takes the vehicle to follow the road)
    without a yaw rate or below :data:`YAW_RATE_MIN_SPEED`. A vehicle recorded in a turn starts
    steering into it: taken as driving straight, it would have to steer faster than it can to stay in
    its lane."""
    if yaw_rate is None or not math.isfinite(float(yaw_rate)) or speed < YAW_RATE_MIN_SPEED:
        return None
    limit = start_curvature_limit(speed, vehicle)
    return float(np.clip(float(yaw_rate) / speed, -limit, limit))


def start_curvature_limit(speed: float, vehicle: dict[str, Any]) -> float:
    """The largest |curvature| [1/m] a converted start is given at ``speed`` [m/s]
    (:func:`initial_curvature`): the request's ``vehicle``'s curvature limit, and
    :data:`START_LATERAL_SHARE` of its lateral acceleration limit."""
    car = Vehicle(**vehicle)
    if speed <= 0.0:
        return car.curvature_limit
    lateral = START_LATERAL_SHARE * car.max_lateral_acceleration / speed**2
    return min(car.curvature_limit, float(lateral_curvature(lateral, car)))


def vehicle_type_car(vehicle_type: int = VEHICLE_TYPE) -> dict[str, float]:
    """The car of a CommonRoad vehicle type as a request's vehicle fields (commonroad-vehicle-models'
    parameters, which the feasibility checker uses): footprint ``l × w``, wheelbase ``a + b``, the rear
    axle ``b`` behind the centre (CommonRoad's position; ``a``, ``b``: centre to the front and rear
    axles), the steering angle and rate limits, and the curvature limit they give
    (``tan δ_max / wheelbase``: the car's own, not a point model's). Type 2, the BMW 320i:
    4.508 × 1.61 m, wheelbase 2.579 m, rear axle 1.423 m behind the centre, ±1.066 rad (0.70 1/m),
    ±0.4 rad/s."""
    _require_commonroad()
    from vehiclemodels.vehicle_parameters import setup_vehicle_parameters

    p = setup_vehicle_parameters(vehicle_type)
    wheelbase = float(p.a + p.b)
    return {
        "length": float(p.l),
        "width": float(p.w),
        "wheelbase": wheelbase,
        "rear_axle_offset": float(p.b),
        "max_steering_angle": float(p.steering.max),
        "max_steering_rate": float(p.steering.v_max),
        "max_curvature": float(np.tan(p.steering.max)) / wheelbase,
    }


def point_vehicle(vehicle: dict[str, Any]) -> dict[str, Any]:
    """A request's vehicle without its car's fields: the same footprint and limits, the point model (a
    car's curvature limit, its steering's, made the shared requests' point model's again)."""
    point = {k: v for k, v in vehicle.items() if k not in CAR_FIELDS}
    if vehicle.get("wheelbase") is not None:
        point["max_curvature"] = VEHICLE["max_curvature"]
    return point


def car_vehicle(vehicle: dict[str, Any], vehicle_type: int = VEHICLE_TYPE) -> dict[str, Any]:
    """A request's vehicle made CommonRoad's car of ``vehicle_type`` (:func:`vehicle_type_car`), its other
    limits kept."""
    return {**point_vehicle(vehicle), **vehicle_type_car(vehicle_type)}


# --------------------------------------------------------------------------------------------------
# Solutions: the driven motion in CommonRoad's kinematic single-track model
# --------------------------------------------------------------------------------------------------


def driven_states(motion: Any, dt: float, initial_time_step: int = 0) -> list[Any]:
    """The driven motion (:class:`planner_tools.sim.Motion`) every ``dt`` [s] as commonroad-io's
    kinematic single-track states: the footprint's centre, the steering angle, the velocity (a car's
    rear axle's, as the simulator drives it) and the orientation (the body's yaw), their time steps
    from ``initial_time_step``.

    Raises:
        CommonRoadError: when the motion has no sample at some multiple of ``dt`` (its sub-step does
            not divide ``dt``).
    """
    _require_commonroad()
    from commonroad.scenario.state import KSState

    t = np.asarray(motion.t, dtype=float)
    wanted = np.arange(0.0, t[-1] + 1e-9, dt)
    at = np.clip(np.searchsorted(t, wanted), 0, t.size - 1)
    before = np.clip(at - 1, 0, t.size - 1)
    at = np.where(np.abs(t[before] - wanted) < np.abs(t[at] - wanted), before, at)
    if np.any(np.abs(t[at] - wanted) > 1e-6):
        raise CommonRoadError(f"the driven motion has no sample every {dt} s (its sub-step does not fit)")
    return [
        KSState(
            position=np.array([motion.x[i], motion.y[i]]),
            steering_angle=float(motion.steering[i]),
            velocity=float(motion.v[i]),
            orientation=float(motion.yaw[i]),
            time_step=initial_time_step + k,
        )
        for k, i in enumerate(at.tolist())
    ]


def write_solution(
    out: str | Path, conv: Conversion, motion: Any, vehicle_type: int = VEHICLE_TYPE
) -> Path:
    """Write the driven ``motion`` of the scenario ``conv`` (converted from XML: its ``info`` holds the
    scenario id, time step and planning problem) as a CommonRoad solution file ``out`` (commonroad-io's
    :class:`~commonroad.common.solution.CommonRoadSolutionWriter`): the kinematic single-track model of
    ``vehicle_type``, cost function SM1, the states of :func:`driven_states`.

    Raises:
        CommonRoadError: for a conversion that did not come from a CommonRoad XML scenario.
    """
    _require_commonroad()
    from commonroad.common.solution import (
        CommonRoadSolutionWriter,
        CostFunction,
        PlanningProblemSolution,
        Solution,
        VehicleModel,
        VehicleType,
    )
    from commonroad.scenario.scenario import ScenarioID
    from commonroad.scenario.trajectory import Trajectory

    info = conv.info
    if "scenario_id" not in info:
        raise CommonRoadError(f"{conv.name}: a solution needs the CommonRoad XML of the scenario")
    states = driven_states(motion, float(info["dt"]), int(info["initial_time_step"]))
    trajectory = Trajectory(initial_time_step=states[0].time_step, state_list=states)
    solution = Solution(
        ScenarioID.from_benchmark_id(str(info["scenario_id"]), "2020a"),
        [
            PlanningProblemSolution(
                planning_problem_id=int(info["planning_problem_id"]),
                vehicle_model=VehicleModel.KS,
                vehicle_type=VehicleType(vehicle_type),
                cost_function=CostFunction.SM1,
                trajectory=trajectory,
            )
        ],
    )
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    with _quiet():
        CommonRoadSolutionWriter(solution).write_to_file(
            output_path=str(path.parent), filename=path.name, overwrite=True
        )
    return path


#: obstacle types a recorded vehicle of which may become the ego (:func:`recorded_cars`)
EGO_TYPES = frozenset({"car", "truck", "bus", "priorityVehicle"})


def recorded_cars(scenario: Any, min_steps: int, min_distance: float) -> list[Any]:
    """The dynamic obstacles of ``scenario`` that could drive as the ego (:func:`recorded_as_ego`): road
    vehicles (:data:`EGO_TYPES`) recorded for at least ``min_steps`` time steps, at exact positions, whose
    last position lies at least ``min_distance`` [m] from their first; the longest recorded first."""
    out = []
    for ob in scenario.dynamic_obstacles:
        states = getattr(getattr(ob.prediction, "trajectory", None), "state_list", [])
        if ob.obstacle_type.value not in EGO_TYPES or len(states) < min_steps:
            continue
        first, last = _exact(ob.initial_state.position), _exact(states[-1].position)
        if first is None or last is None or float(np.hypot(*(last - first))) < min_distance:
            continue
        out.append(ob)
    return sorted(out, key=lambda ob: -len(ob.prediction.trajectory.state_list))


def _exact(position: Any) -> FloatArray | None:
    """A recorded position as ``[x, y]`` [m]; None for an uncertain one (a shape)."""
    try:
        xy = np.asarray(position, dtype=float)
    except (TypeError, ValueError):
        return None
    return xy if xy.shape == (2,) else None


def recorded_as_ego(
    scenario: Any, obstacle_id: int, slack: tuple[float, float] = (2.0, 4.0)
) -> tuple[Any, Any]:
    """``(scenario, planning problem set)``: a copy of ``scenario`` without its recorded vehicle
    ``obstacle_id``, which becomes the ego: its first recorded state is the initial state (planning
    problem id = ``obstacle_id``), the goal a 10 m × 4 m rectangle along its last heading centred where
    its recording ends, from ``slack[0]`` [s] before to ``slack[1]`` [s] after that end; its yaw rate that
    of its first recorded step. Scenes no test was tuned on, whose traffic reacted to the recorded
    vehicle, not to the planner.

    Raises:
        CommonRoadError: for an id that is no recorded vehicle at exact positions.
    """
    _require_commonroad()
    from commonroad.common.util import Interval
    from commonroad.geometry.occupancy.rect_occupancy import RectOccupancy
    from commonroad.planning.goal import GoalRegion
    from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
    from commonroad.scenario.state import CustomState, InitialState

    if obstacle_id not in {car.obstacle_id for car in recorded_cars(scenario, 2, 0.0)}:
        raise CommonRoadError(f"obstacle {obstacle_id} is no recorded vehicle at exact positions")
    obstacle = scenario.obstacle_by_id(obstacle_id)
    new = copy.deepcopy(scenario)
    new.remove_obstacle(new.obstacle_by_id(obstacle_id))
    dt = float(new.dt)
    init = obstacle.initial_state
    states = obstacle.prediction.trajectory.state_list
    last = states[-1]
    # its yaw rate over its first recorded step (a car recorded in a turn starts steering into it)
    turned = _wrap(float(states[0].orientation) - float(init.orientation))
    steps = max(int(states[0].time_step) - int(init.time_step), 1)
    start = InitialState(
        time_step=int(init.time_step),
        position=np.asarray(init.position, dtype=float),
        orientation=float(init.orientation),
        velocity=float(getattr(init, "velocity", 0.0) or 0.0),
        acceleration=0.0,
        yaw_rate=turned / (steps * dt),
        slip_angle=0.0,
    )
    target = CustomState(
        position=RectOccupancy(
            rect_center=shapely.Point(*np.asarray(last.position, dtype=float)),
            width=4.0,
            length=10.0,
            orientation=float(last.orientation),
        ),
        time_step=Interval(
            max(int(init.time_step) + 1, int(last.time_step) - round(slack[0] / dt)),
            int(last.time_step) + round(slack[1] / dt),
        ),
    )
    problem = PlanningProblem(int(obstacle_id), start, GoalRegion([target]))
    return new, PlanningProblemSet([problem])


def write_scenario(out: str | Path, scenario: Any, problems: Any, source: str = "kappa-planner") -> Path:
    """Write ``scenario`` and its planning problem set as CommonRoad XML to ``out`` (overwritten)."""
    _require_commonroad()
    from commonroad.common.file_writer import CommonRoadFileWriter, OverwriteExistingFile
    from commonroad.common.util import FileFormat

    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = CommonRoadFileWriter(scenario, problems, source, "", source, set(), file_format=FileFormat.XML)
    with _quiet():
        writer.write_to_file(str(path), OverwriteExistingFile.ALWAYS)
    return path


def _shape_module_of_old() -> None:
    """Register ``commonroad.geometry.shape`` where commonroad-io has none.

    commonroad-drivability-checker 2025.4 (its newest release) imports ``Rectangle`` from
    ``commonroad.geometry.shape``, which commonroad-io 2026.1 replaced by
    ``commonroad.geometry.obstacle_shapes`` (``RectObstacleShape``, the same ``length × width``
    rectangle). Its feasibility checker only sizes the ego's shape with it, which the check of
    transitions does not use; the old name is registered as that class so that the checker imports.
    """
    import importlib.util
    import sys
    import types

    if "commonroad.geometry.shape" in sys.modules or importlib.util.find_spec("commonroad.geometry.shape"):
        return
    from commonroad.geometry.obstacle_shapes.rect_obstacle_shape import RectObstacleShape

    module = types.ModuleType("commonroad.geometry.shape", "commonroad-io < 2026's shapes (Rectangle only)")
    module.Rectangle = RectObstacleShape  # type: ignore[attr-defined]
    sys.modules[module.__name__] = module


def feasible_transitions(states: Sequence[Any], dt: float, vehicle_type: int = VEHICLE_TYPE) -> list[bool]:
    """Per transition between consecutive kinematic single-track ``states``: whether
    commonroad-drivability-checker's feasibility checker finds inputs within the vehicle type's limits
    (steering rate and angle, acceleration) that reach the next state within its position and
    orientation tolerances in ``dt`` [s] (its ``state_transition_feasibility``)."""
    _require_commonroad()
    _shape_module_of_old()
    from commonroad.common.solution import VehicleType
    from commonroad_dc.feasibility.feasibility_checker import state_transition_feasibility
    from commonroad_dc.feasibility.vehicle_dynamics import VehicleDynamics

    dynamics = VehicleDynamics.KS(VehicleType(vehicle_type))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return [
            bool(state_transition_feasibility(a, b, dynamics, dt)[0]) for a, b in itertools.pairwise(states)
        ]


def load(path: str | Path, *, planning_problem_id: int | None = None) -> Conversion:
    """A scenario from a CommonRoad XML file (plain or ``*.xml.gz``), a request JSON or a reduced
    scenario JSON."""
    p = Path(path)
    if not p.exists():
        raise CommonRoadError(f"{p}: no such file")
    if p.suffix.lower() == ".json":
        return load_json(p)
    conv = convert_scenario(p, planning_problem_id=planning_problem_id)
    return replace(conv, name=scenario_name(p))
