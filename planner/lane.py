"""The lane as bounds on the vehicle centre's offset, and the corridor around the reference that matters."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.problem import Lane, PlanningProblem
from planner.reference import FloatArray, ReferenceLine, widths_at


@dataclass(frozen=True)
class LaneBounds:
    """Usable lateral bounds of the vehicle's centre at arc lengths ``s`` [m]: ``lower ≤ d ≤ upper``."""

    s: FloatArray
    lower: FloatArray
    upper: FloatArray


def lane_bounds(
    ref: ReferenceLine, lane: Lane, s: FloatArray, *, half_width: float, margin: float
) -> LaneBounds:
    """Bounds of the vehicle centre: lane widths shrunk by ``half_width + margin`` [m] on each side.

    Where the lane is narrower than that, both bounds meet in the middle of the lane.
    """
    left = widths_at(lane.left_width, ref, s, field_name="lane.left_width")
    right = widths_at(lane.right_width, ref, s, field_name="lane.right_width")
    upper = left - half_width - margin
    lower = -(right - half_width - margin)
    squeezed = lower > upper
    mid = 0.5 * (left - right)
    upper = np.where(squeezed, mid, upper)
    lower = np.where(squeezed, mid, lower)
    return LaneBounds(s=s, lower=lower, upper=upper)


def corridor_width(problem: PlanningProblem, config: PlannerConfig = DEFAULT_CONFIG) -> float:
    """How far from the reference line [m] an obstacle can matter: the widest lane side and the
    vehicle's length, with ``corridor_spare`` to spare."""
    widest = max(float(np.max(problem.lane.left_width)), float(np.max(problem.lane.right_width)))
    return widest + problem.vehicle.length + config.corridor_spare
