"""The lane as bounds on the vehicle centre's offset, the corridor a borrow widens it to, and the corridor
around the reference that matters."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np

from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.problem import Lane, PlanningProblem, Road
from planner.reference import FloatArray, ReferenceLine

Side = Literal["left", "right"]


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
    left, right = lane.widths(ref, s)
    upper = left - half_width - margin
    lower = -(right - half_width - margin)
    squeezed = lower > upper
    mid = 0.5 * (left - right)
    upper = np.where(squeezed, mid, upper)
    lower = np.where(squeezed, mid, lower)
    return LaneBounds(s=s, lower=lower, upper=upper)


@dataclass(frozen=True)
class Corridor(Lane):
    """The lane widened on one ``side`` to the road's edge: fully over ``[start, end]`` [m] of arc
    length, ramping linearly from the lane's edge over ``ramp_in`` [m] before ``start`` and back to it over
    ``ramp_out`` [m] after ``end`` (a ramp of 0 is a step); the lane elsewhere and on the other side.

    It stands in for the lane wherever widths are read (:meth:`widths`): the candidates, the lateral
    bounds and the trajectory checks of a plan that borrows the road (:mod:`planner.decision`).
    """

    KEY: ClassVar[str] = "lane"

    road: Road
    side: Side
    start: float
    end: float
    ramp_in: float
    ramp_out: float

    def share(self, s: Any) -> FloatArray:
        """How much of the road beyond the lane is open at arc lengths ``s`` [m]: 1 over ``[start, end]``,
        0 beyond the ramps, linear on them."""
        s_arr = np.asarray(s, dtype=float)
        rising = _ramp(s_arr - self.start, self.ramp_in)
        falling = _ramp(self.end - s_arr, self.ramp_out)
        return np.asarray(np.minimum(rising, falling))

    def widths(self, ref: ReferenceLine, s: Any) -> tuple[FloatArray, FloatArray]:
        """The lane's widths [m] at ``s`` [m], the borrowed side's opened towards the road's edge."""
        left, right = super().widths(ref, s)
        road_left, road_right = self.road.widths(ref, s)
        open_ = self.share(s)
        if self.side == "left":
            return left + open_ * np.maximum(road_left - left, 0.0), right
        return left, right + open_ * np.maximum(road_right - right, 0.0)


def _ramp(inside: FloatArray, length: float) -> FloatArray:
    """1 where ``inside`` [m] ≥ 0, 0 where it is ``−length`` or less, linear between (a step for 0)."""
    if length <= 0.0:
        return np.where(inside >= 0.0, 1.0, 0.0)
    return np.asarray(np.clip(1.0 + inside / length, 0.0, 1.0))


def corridor_width(
    problem: PlanningProblem, config: PlannerConfig = DEFAULT_CONFIG, *, road: bool = False
) -> float:
    """How far from the reference line [m] an obstacle can matter: the widest lane side (with ``road``,
    the road's) and the vehicle's length, with ``corridor_spare`` to spare."""
    surface: Lane = problem.road if road and problem.road is not None else problem.lane
    widest = max(float(np.max(surface.left_width)), float(np.max(surface.right_width)))
    return widest + problem.vehicle.length + config.corridor_spare
