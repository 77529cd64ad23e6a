"""Goal scenes and an independent judge of a trajectory against a goal, shared by the goal tests.

:func:`meets` does not call the planner: a convex polygon's inside is tested by the signs of cross
products, a disc's by the distance to its centre; times and speeds by comparison. It needs convex goal
regions (the tests' are boxes and discs).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from planner.goal import SPEED_TOLERANCE, Goal, GoalCircle, GoalPolygon
from planner.problem import Ego, Lane, Options, PlanningProblem, Vehicle
from planner.roads import straight
from planner.trajectory import Trajectory

#: a straight road along +x from 0 to 400 m, the ego at x = 10 m at 10 m/s with a target of 10 m/s
ROAD = straight(400.0, step=5.0)
EGO_X = 10.0
CAR = {"wheelbase": 2.7, "rear_axle_offset": 1.35, "max_steering_rate": 0.5}


def straight_problem(
    goal: Goal | None = None, *, model: str = "point", **options: float | None
) -> PlanningProblem:
    """The ego on :data:`ROAD` with ``goal`` and ``options`` (the target 10 m/s unless given)."""
    vehicle = Vehicle(**CAR) if model == "car" else Vehicle()  # type: ignore[arg-type]
    opts = replace(Options(target_speed=10.0), **options)
    return PlanningProblem(ROAD, Lane(3.5, 3.5), Ego(EGO_X, 0.0, 0.0, 10.0), (), vehicle, opts, goal=goal)


def box(x0: float, x1: float, y0: float, y1: float) -> GoalPolygon:
    """The axis-aligned box ``[x0, x1] × [y0, y1]`` [m] as a goal region (counter-clockwise)."""
    return GoalPolygon(np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]))


def inside_convex(
    polygon: NDArray[np.float64], x: NDArray[np.float64], y: NDArray[np.float64], slack: float = 1e-9
) -> NDArray[np.bool_]:
    """Whether each point is in the convex ``polygon`` (k, 2) grown by ``slack`` [m] (shrunk where
    negative), its boundary included."""
    p = np.asarray(polygon, dtype=float)
    q = np.roll(p, -1, axis=0)
    cross = (q[:, 0] - p[:, 0])[:, None] * (y[None, :] - p[:, 1, None]) - (q[:, 1] - p[:, 1])[:, None] * (
        x[None, :] - p[:, 0, None]
    )
    edge = np.hypot(q[:, 0] - p[:, 0], q[:, 1] - p[:, 1])[:, None]
    distance = cross / edge  # signed distance to each edge's line, > 0 on its left
    return np.asarray(np.all(distance >= -slack, axis=0) | np.all(distance <= slack, axis=0))


def meets(goal: Goal, traj: Trajectory, slack: float = 1e-9) -> NDArray[np.bool_]:
    """Per sample, whether ``traj`` meets every part of ``goal`` given (the centre inside the region grown
    by ``slack`` [m], ``t`` in the window, ``v`` in the range within :data:`planner.goal.SPEED_TOLERANCE`)."""
    ok = np.ones(traj.t.shape, dtype=bool)
    if isinstance(goal.position, GoalCircle):
        cx, cy = goal.position.center
        ok &= np.hypot(traj.x - cx, traj.y - cy) <= goal.position.radius + slack
    elif isinstance(goal.position, GoalPolygon):
        ok &= inside_convex(goal.position.polygon, traj.x, traj.y, slack)
    if goal.time is not None:
        ok &= (traj.t >= goal.time[0] - 1e-9) & (traj.t <= goal.time[1] + 1e-9)
    if goal.speed is not None:
        ok &= (traj.v >= goal.speed[0] - SPEED_TOLERANCE) & (traj.v <= goal.speed[1] + SPEED_TOLERANCE)
    return ok
