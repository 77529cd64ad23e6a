"""Checks of paths against the reference: the properties Algorithm 5 guarantees and Algorithm 4 breaks.

Used by the tests, the figures and (later) the planner's own output checks.
"""

from __future__ import annotations

import numpy as np
import shapely
from numpy.typing import ArrayLike
from shapely import LineString
from shapely.geometry.base import BaseGeometry

from planner.collision import box_corners, footprints, prediction_at
from planner.frenet import to_frenet
from planner.problem import DynamicObstacle, PlanningProblem
from planner.reference import ReferenceLine, widths_at
from planner.trajectory import Trajectory


def backward_steps(ref: ReferenceLine, xy: ArrayLike) -> int:
    """Number of consecutive points of a path whose TransF-κ ``s`` does not increase."""
    pts = np.asarray(xy, dtype=float)
    if pts.shape[0] < 2:
        return 0
    s = to_frenet(ref, pts).s
    return int(np.count_nonzero(np.diff(s) <= 0.0))


def self_intersects(xy: ArrayLike) -> bool:
    """Whether the polyline through the points crosses or overlaps itself."""
    pts = np.asarray(xy, dtype=float)
    if pts.shape[0] < 3:
        return False
    return not LineString(pts).is_simple


def folds_back(ref: ReferenceLine, xy: ArrayLike) -> bool:
    """Whether a path runs backwards along the reference or crosses itself."""
    return backward_steps(ref, xy) > 0 or self_intersects(xy)


#: tolerances of the trajectory checks
_GEOMETRY_TOL = 1e-3  # [m]
_RATE_TOL = 1e-3  # relative, on limits


def trajectory_violations(
    ref: ReferenceLine,
    problem: PlanningProblem,
    traj: Trajectory,
    static: list[tuple[str, BaseGeometry]],
) -> list[str]:
    """Every check a returned trajectory must pass; an empty list when it passes them all.

    Starts at the ego; footprint inside the lane (all four corners by TransF-κ; no further out than
    the measured start where that is already partly outside) and clear of every
    static obstacle and of every moving one at its predicted pose at the same time; ``1 − κ·d > 0``;
    ``|curvature| ≤ max_curvature`` and ``v²·|curvature| ≤ max_lateral_acceleration`` while moving;
    acceleration within the limits; consecutive positions consistent with ``v·dt``; ``s`` never
    decreasing and strictly increasing while moving; no self-intersection.
    """
    vehicle, ego = problem.vehicle, problem.ego
    out: list[str] = []
    if np.hypot(traj.x[0] - ego.x, traj.y[0] - ego.y) > 0.05:
        out.append("does not start at the ego")
    moving = traj.v > 0.05
    kappa = ref.kappa_at(traj.s)
    if np.any(1.0 - kappa * traj.d <= 0.0):
        out.append("1 − κ·d ≤ 0 at some point")
    curv = np.abs(traj.curvature)
    if np.any(moving & (curv > vehicle.max_curvature * (1 + _RATE_TOL) + 1e-4)):
        out.append(f"curvature {float(curv[moving].max()):.3f} 1/m above max_curvature")
    lat = traj.v**2 * curv
    if np.any(lat > vehicle.max_lateral_acceleration * (1 + _RATE_TOL) + 1e-3):
        out.append(f"lateral acceleration {float(lat.max()):.2f} m/s² above the limit")
    if np.any(traj.a > vehicle.max_acceleration + 1e-3) or np.any(traj.a < -vehicle.max_deceleration - 1e-3):
        out.append("acceleration outside the limits")
    dt = np.diff(traj.t)
    step = np.hypot(np.diff(traj.x), np.diff(traj.y))
    expected = 0.5 * (traj.v[:-1] + traj.v[1:]) * dt
    if np.any(np.abs(step - expected) > 0.05 + 0.05 * expected):
        out.append("positions inconsistent with v·dt")
    ds = np.diff(traj.s)
    if np.any(ds < -1e-6) or np.any((ds <= 0) & moving[:-1] & moving[1:]):
        out.append("s does not increase while moving")
    travelled = np.concatenate(([True], step > 1e-3))
    if self_intersects(np.column_stack((traj.x, traj.y))[travelled]):
        out.append("self-intersects")
    prints = footprints(traj.x, traj.y, traj.heading, vehicle)
    corners = box_corners(traj.x, traj.y, traj.heading, vehicle.length, vehicle.width).reshape(-1, 2)
    fr = to_frenet(ref, corners)
    left = widths_at(problem.lane.left_width, ref, fr.s, field_name="lane.left_width")
    right = widths_at(problem.lane.right_width, ref, fr.s, field_name="lane.right_width")
    outside = np.maximum(fr.d - left, -right - fr.d).reshape(-1, 4)
    # The start is a measurement: a vehicle already partly outside the lane may not get further out
    # until it has moved one length away.
    near_start = np.hypot(traj.x - traj.x[0], traj.y - traj.y[0]) < vehicle.length
    allowance = np.where(near_start, max(float(outside[0].max()), 0.0), 0.0)[:, None]
    if np.any(outside - allowance > _GEOMETRY_TOL):
        out.append("footprint leaves the lane")
    for ob_id, shape in static:
        if np.any(shapely.intersects(prints, shape)):
            out.append(f"footprint hits obstacle {ob_id}")
    for ob in problem.obstacles:
        if isinstance(ob, DynamicObstacle) and not any(ob.id == i for i, _ in static):
            states = prediction_at(ob, traj.t)
            boxes = shapely.polygons(
                box_corners(states[:, 0], states[:, 1], states[:, 2], ob.length, ob.width)
            )
            if np.any(shapely.intersects(prints, boxes)):
                out.append(f"footprint hits moving obstacle {ob.id}")
    return out
