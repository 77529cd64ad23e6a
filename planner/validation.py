"""Checks of paths against the reference: the properties Algorithm 5 guarantees and Algorithm 4 breaks.

Used by the tests, the figures and (later) the planner's own output checks.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from shapely import LineString

from planner.frenet import to_frenet
from planner.reference import ReferenceLine


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
