"""Scenes with cars on a straight road, for the tests of the moving obstacles' bounds and the fallback."""

from __future__ import annotations

import numpy as np

from planner.problem import DynamicObstacle, Lane, PlanningProblem
from planner.reference import build_reference
from planner.roads import straight
from planner.st_bounds import static_shapes
from planner.trajectory import Trajectory
from planner.validation import Violation, trajectory_violations

ROAD = straight(300.0, step=5.0)
LANE = Lane(3.5, 3.5)
#: the times of the cars' predictions [s]
T = np.arange(0.0, 8.01, 0.5)


def car(name: str, x0: float, speed: float, y: float | np.ndarray = 0.0) -> DynamicObstacle:
    """A 4.5 m × 1.8 m car along x from ``x0`` [m] at ``speed`` [m/s], at ``y`` [m] (one per time of T)."""
    return DynamicObstacle(name, 4.5, 1.8, np.column_stack((T, x0 + speed * T, y + 0 * T, 0 * T)))


def violations(problem: PlanningProblem, traj: Trajectory) -> list[Violation]:
    """Every check ``traj`` breaks in ``problem``."""
    ref = build_reference(problem.reference_line)
    return trajectory_violations(ref, problem, traj, static_shapes(problem))
