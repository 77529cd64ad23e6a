"""A planning goal: where to be, when, and how fast (every part optional).

``position`` is a region of the plane (a polygon, or a disc); ``time`` a window ``[t_min, t_max]`` [s]
from now (``t = 0`` is the ego's state); ``speed`` a range ``[v_min, v_max]`` [m/s] (a range reaching 0
means: stop inside). The goal is met at a time ``t`` of the trajectory when the vehicle is inside the
position, ``t`` is inside the window and its speed inside the range, for each part given.

The dataclasses check their fields when they are built and raise
:class:`~planner.errors.InvalidInputError` naming the field as the JSON request does
(``goal.position.polygon``, ``goal.position.circle.radius``, ``goal.time``, ``goal.speed.1``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from planner import checks
from planner.errors import InvalidInputError
from planner.reference import FloatArray

#: a goal polygon must enclose more than this area [m²] (as an obstacle's polygon must)
MIN_GOAL_AREA = 1e-6


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
