"""The choice of a candidate: each is scored and the best collision-free one is followed.

For candidate ``i`` with kept points ``(s_j, d_j)`` [m], ``n`` of them, its cost is::

    J_i = Σ d_j² / n + w_bend · Σ |Δd′_j| + w_progress · (1 − progress_i / longest) + [hits] · collision_cost

(the mean squared offset [m²], the summed change of slope ``d′ = Δd/Δs``, the share of the longest
progress along the reference not reached), with the weights of :class:`planner.config.SelectionConfig`,
plus any term a goal adds (:func:`planner.goal_plan.candidate_cost`).
A candidate hits when its footprint box (placed from the planned point: the centre, a car's rear axle),
turned by its heading error and with ``obstacle_margin`` around it, meets a static obstacle's Frenet
box at one of its points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.candidates import CandidateSet
from planner.collision import FrenetBoxes, box_hits, footprint_extent
from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.problem import PlanningProblem
from planner.reference import FloatArray


@dataclass(frozen=True)
class Choice:
    """The chosen candidate (the best collision-free one, the best overall if none is free) and which
    candidates are collision-free, shape (N,)."""

    best: int
    free: NDArray[np.bool_]

    @property
    def collision_free(self) -> int:
        """How many candidates are collision-free."""
        return int(self.free.sum())


def choose_candidate(
    cands: CandidateSet,
    boxes: FrenetBoxes,
    problem: PlanningProblem,
    config: PlannerConfig = DEFAULT_CONFIG,
    extra: FloatArray | None = None,
) -> Choice:
    """Score every candidate (offset, smoothness, progress, clearance: see the module docstring, and
    ``extra``, shape (N,), when given) and choose the best."""
    weights = config.selection
    ds = np.diff(cands.s, axis=1)
    dd = np.diff(cands.d, axis=1) / np.where(ds > 0, ds, 1.0)
    heading_error = np.arctan(np.concatenate((dd, dd[:, -1:]), axis=1))
    extent = footprint_extent(heading_error, problem.vehicle, config.obstacle_margin)
    hits = box_hits(boxes, cands.s, cands.d, extent) & cands.valid
    free = ~hits.any(axis=1)
    valid = cands.valid
    count = valid.sum(axis=1)
    offset = np.where(valid, cands.d**2, 0.0).sum(axis=1) / count
    bend = np.abs(np.diff(dd, axis=1)).sum(axis=1)
    progress = np.where(valid, cands.s, -np.inf).max(axis=1) - cands.s[:, 0]
    span = max(float(progress.max()), 1e-6)
    cost = (
        offset
        + weights.bend_weight * bend
        + weights.progress_weight * (1.0 - progress / span)
        + weights.collision_cost * (~free)
    )
    if extra is not None:
        cost = cost + extra
    return Choice(int(np.argmin(cost)), np.asarray(free, dtype=bool))
