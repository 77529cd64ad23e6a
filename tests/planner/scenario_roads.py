"""Road and obstacle builders for the planning-scenario acceptance tests (tests/planner/test_scenarios.py).

Roads are chains of straights and circular arcs with exactly known geometry: :class:`Road` gives the
pose at any arc length analytically, so obstacles, predictions and the ego are placed without going
through the planner's own Frenet transform.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Piece:
    """A straight (``curvature == 0``) or a circular arc of signed curvature [1/m] (left turn > 0)."""

    length: float
    curvature: float = 0.0


def straight_piece(length: float) -> Piece:
    return Piece(length, 0.0)


def arc_piece(radius: float, angle: float) -> Piece:
    """An arc turning by ``angle`` [rad] (> 0 left, < 0 right) on ``radius`` [m]."""
    return Piece(radius * abs(angle), float(np.sign(angle)) / radius)


class Road:
    """A chain of pieces starting at ``origin`` with ``heading``: exact poses by arc length."""

    def __init__(
        self, pieces: list[Piece], *, origin: tuple[float, float] = (0.0, 0.0), heading: float = 0.0
    ) -> None:
        self.pieces = list(pieces)
        starts = [(np.array(origin, dtype=float), float(heading))]
        for p in self.pieces:
            xy, h = starts[-1]
            starts.append(_advance(xy, h, p, p.length))
        self._starts = starts
        self.s_start = np.concatenate(([0.0], np.cumsum([p.length for p in self.pieces])))

    @property
    def length(self) -> float:
        return float(self.s_start[-1])

    def pose(self, s: float) -> tuple[float, float, float]:
        """``(x, y, heading)`` of the centre line at arc length ``s`` (clamped to the road)."""
        s = float(np.clip(s, 0.0, self.length))
        i = int(np.clip(np.searchsorted(self.s_start, s, side="right") - 1, 0, len(self.pieces) - 1))
        xy, h = self._starts[i]
        out, heading = _advance(xy, h, self.pieces[i], s - self.s_start[i])
        return float(out[0]), float(out[1]), heading

    def point(self, s: float, d: float = 0.0) -> FloatArray:
        """The point ``d`` [m] to the left of the centre line at ``s``."""
        x, y, h = self.pose(s)
        return np.array([x - d * np.sin(h), y + d * np.cos(h)])

    def heading(self, s: float) -> float:
        return self.pose(s)[2]

    def polyline(self, step: float) -> FloatArray:
        """Centre-line points every ``step`` [m] of arc length, the end point included."""
        n = int(np.ceil(self.length / step - 1e-9))
        s = np.minimum(np.arange(n + 1) * step, self.length)
        return np.array([self.pose(v)[:2] for v in s])


def _advance(xy: FloatArray, heading: float, piece: Piece, u: float) -> tuple[FloatArray, float]:
    k = piece.curvature
    if k == 0.0:
        return xy + u * np.array([np.cos(heading), np.sin(heading)]), heading
    h = heading + k * u
    return xy + np.array([np.sin(h) - np.sin(heading), np.cos(heading) - np.cos(h)]) / k, h


def rectangle(x: float, y: float, heading: float, length: float, width: float) -> FloatArray:
    """Corners (4, 2) of a ``length × width`` box centred at ``(x, y)`` turned by ``heading``."""
    c, s = np.cos(heading), np.sin(heading)
    along = np.array([-0.5, 0.5, 0.5, -0.5]) * length
    across = np.array([-0.5, -0.5, 0.5, 0.5]) * width
    return np.column_stack((x + along * c - across * s, y + along * s + across * c))


def box_on_road(road: Road, s: float, d: float, length: float, width: float) -> FloatArray:
    """A box aligned with the road, centred ``d`` [m] left of the centre line at ``s``."""
    x, y = road.point(s, d)
    return rectangle(x, y, road.heading(s), length, width)


def follow_prediction(road: Road, s0: float, speed: float, horizon: float, *, d: float = 0.0) -> FloatArray:
    """Prediction rows ``t, x, y, heading`` every 0.1 s of a vehicle at constant ``speed`` along the road."""
    t = np.arange(0.0, horizon + 1e-9, 0.1)
    rows = []
    for ti in t:
        x, y = road.point(s0 + speed * ti, d)
        rows.append((ti, x, y, road.heading(s0 + speed * ti)))
    return np.array(rows)
