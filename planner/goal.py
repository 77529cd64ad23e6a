"""A planning goal: where to be, when, and how fast (every part optional).

``position`` is a region of the plane (a polygon, or a disc); ``time`` a window ``[t_min, t_max]`` [s]
from now (``t = 0`` is the ego's state); ``speed`` a range ``[v_min, v_max]`` [m/s] (a range from 0 to
below :attr:`planner.config.GoalConfig.stop_speed` means: stop inside). The goal is met at a time ``t``
of the trajectory when the vehicle is inside the position, ``t`` is inside the window and its speed
inside the range, for each part given.

The dataclasses check their fields when they are built and raise
:class:`~planner.errors.InvalidInputError` naming the field as the JSON request does
(``goal.position.polygon``, ``goal.position.circle.radius``, ``goal.time``, ``goal.speed.1``).

Which point must be inside: the footprint's centre, the trajectory point ``(x, y)`` of the answer (for a
car, ``l_r`` ahead of the rear axle it is planned at), as CommonRoad's goal check tests a state's position;
the region's boundary counts as inside. The speed is the trajectory's ``v`` (a car's rear axle's), within
:data:`SPEED_TOLERANCE`; the time a sample's ``t`` (the trajectory is judged at its samples, every
``options.dt``).

What a plan says of its goal is a :class:`GoalReport`: ``reached`` (at its first ``t``), ``on_the_way`` or
``unreachable`` with a typed :class:`GoalReason` (:mod:`planner.goal_report` judges it).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np

from planner import checks
from planner.errors import InvalidInputError
from planner.reference import FloatArray

#: a goal polygon must enclose more than this area [m²] (as an obstacle's polygon must)
MIN_GOAL_AREA = 1e-6
#: a speed within this of the goal's range [m/s] is in it (a standstill integrates to ±1e-12, not 0)
SPEED_TOLERANCE = 1e-3


@dataclass(frozen=True)
class GoalPolygon:
    """A goal region given by its outline, shape (k, 2) [m], k ≥ 3, enclosing a nonzero area."""

    polygon: FloatArray

    def __post_init__(self) -> None:
        where = "goal.position.polygon"
        polygon = checks.array(self.polygon, where, (None, 2), min_rows=3)
        rel = polygon - polygon[0]  # shoelace relative to a vertex: no cancellation far from the origin
        nxt = np.roll(rel, -1, axis=0)
        area = 0.5 * abs(float(np.sum(rel[:, 0] * nxt[:, 1] - nxt[:, 0] * rel[:, 1])))
        if not area > MIN_GOAL_AREA:
            raise InvalidInputError(
                "the polygon has no area: its points coincide or are collinear", field=where
            )
        if polygon is not self.polygon:
            object.__setattr__(self, "polygon", polygon)


@dataclass(frozen=True)
class GoalCircle:
    """A goal region given as a disc: centre, shape (2,) [m], and radius [m] > 0."""

    center: FloatArray
    radius: float

    def __post_init__(self) -> None:
        center = checks.array(self.center, "goal.position.circle.center", (2,))
        radius = checks.size(self.radius, "goal.position.circle.radius")
        if not radius > 0.0:
            raise InvalidInputError("must be positive", field="goal.position.circle.radius")
        object.__setattr__(self, "center", center)
        object.__setattr__(self, "radius", radius)


GoalPosition = GoalPolygon | GoalCircle


def _interval(value: Any, where: str, minimum: float | None = None) -> tuple[float, float]:
    """``value`` as an interval ``(low, high)`` of finite numbers with ``low ≤ high`` (both at least
    ``minimum`` when given)."""
    if isinstance(value, str | bytes) or not hasattr(value, "__len__") or len(value) != 2:
        raise InvalidInputError("must be a pair [low, high]", field=where)
    low, high = (checks.number(v, f"{where}.{i}") for i, v in enumerate(value))
    if minimum is not None:
        for i, v in enumerate((low, high)):
            if v < minimum:
                raise InvalidInputError(f"must be at least {minimum:g}", field=f"{where}.{i}")
    if low > high:
        raise InvalidInputError(f"the low end {low:g} is above the high end {high:g}", field=where)
    return low, high


@dataclass(frozen=True)
class Goal:
    """Where to be (``position``), when (``time`` [s] from now: ``(t_min, t_max)``) and how fast
    (``speed`` [m/s]: ``(v_min, v_max)``, ``0 ≤ v_min ≤ v_max``); each ``None`` when not asked for.

    A window may have begun already (``t_min < 0``); one that has ended (``t_max < 0``) cannot be met,
    which the plan's diagnostics say.
    """

    position: GoalPosition | None = None
    time: tuple[float, float] | None = None
    speed: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if self.position is not None and not isinstance(self.position, GoalPolygon | GoalCircle):
            raise InvalidInputError("must be a polygon or a circle", field="goal.position")
        if self.time is not None:
            object.__setattr__(self, "time", _interval(self.time, "goal.time"))
        if self.speed is not None:
            object.__setattr__(self, "speed", _interval(self.speed, "goal.speed", minimum=0.0))


class GoalStatus(StrEnum):
    """What the plan's trajectory does with the goal."""

    #: the trajectory meets every part of the goal given at some sample (the first one is reported)
    REACHED = "reached"
    #: it does not meet it within the horizon, which ends before the region or the window, and nothing
    #: found prevents it
    ON_THE_WAY = "on_the_way"
    #: it does not meet it, and something prevents it (:class:`GoalReason`)
    UNREACHABLE = "unreachable"


class GoalReason(StrEnum):
    """Why a goal cannot be met."""

    #: the time window ended before now (``t_max < 0``)
    WINDOW_ENDED = "window_ended"
    #: the region lies behind the vehicle, which drives forwards only
    BEHIND = "behind"
    #: no point of the region is one the vehicle's centre can reach within the lane (or before the
    #: reference's end)
    OFF_ROAD = "off_road"
    #: the region cannot be reached before the window ends, within the speed limit and acceleration
    TOO_FAR = "too_far"
    #: the trajectory passes the region before the window opens
    TOO_EARLY = "too_early"
    #: the speed range cannot be met: above the speed limit, or the vehicle cannot slow into it there
    SPEED_RANGE = "speed_range"
    #: the road or the traffic ahead stops the vehicle before the region
    BLOCKED = "blocked"
    #: the trajectory passes beside the region: the lateral plan cannot get into it
    MISSED = "missed"
    #: the plan fell back (a stage failed): its braking trajectory does not meet the goal
    FALLBACK = "fallback"


@dataclass(frozen=True)
class GoalReport:
    """What a plan says of its goal: ``status``; for ``reached`` the first time ``t`` [s] at which the
    trajectory meets it; for ``unreachable`` the ``reason``; always a ``message`` in words."""

    status: GoalStatus
    message: str
    t: float | None = None
    reason: GoalReason | None = None
