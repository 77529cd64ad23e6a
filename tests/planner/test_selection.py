"""The choice of a candidate: the cheapest collision-free one (offset, bends, progress), by the
configured weights."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from planner.candidates import CandidateSet
from planner.collision import frenet_boxes
from planner.config import DEFAULT_CONFIG, SelectionConfig
from planner.problem import Ego, Lane, PlanningProblem
from planner.reference import build_reference
from planner.roads import straight
from planner.selection import choose_candidate

ROAD = straight(200.0)
REF = build_reference(ROAD)
PROBLEM = PlanningProblem(ROAD, Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, 5.0))
S = np.linspace(10.0, 60.0, 101)


def _candidates(*offsets: np.ndarray, valid: np.ndarray | None = None) -> CandidateSet:
    d = np.array([np.broadcast_to(o, S.shape) for o in offsets], dtype=float)
    n = d.shape[0]
    s = np.broadcast_to(S, d.shape)
    return CandidateSet(
        s=s,
        d=d,
        xy=np.stack((s, d), axis=-1),
        kappa=np.zeros(d.shape),
        valid=np.ones(d.shape, dtype=bool) if valid is None else valid,
        repaired=np.zeros(n, dtype=bool),
        end_fraction=np.zeros(n),
        transition=np.full(n, 20.0),
        generator="naive",
    )


def _box(x0: float, x1: float, y0: float, y1: float) -> list[tuple[str, BaseGeometry]]:
    return [("box", shapely.box(x0, y0, x1, y1))]


NO_BOXES = frenet_boxes(REF, [])


def test_without_obstacles_the_smallest_offset_wins() -> None:
    choice = choose_candidate(_candidates(1.0, 0.0, -2.0), NO_BOXES, PROBLEM)
    assert choice.best == 1
    assert choice.free.tolist() == [True, True, True] and choice.collision_free == 3


def test_a_free_candidate_wins_over_a_cheaper_one_that_hits() -> None:
    # a box on the centre line 30–35 m: the d = 0 candidate meets it (with obstacle_margin); d = 3 clears it
    boxes = frenet_boxes(REF, _box(30.0, 35.0, -0.5, 0.5))
    choice = choose_candidate(_candidates(0.0, 3.0, -1.0), boxes, PROBLEM)
    assert choice.free.tolist() == [False, True, False]
    assert choice.best == 1 and choice.collision_free == 1


def test_when_every_candidate_hits_the_cheapest_is_chosen() -> None:
    boxes = frenet_boxes(REF, _box(30.0, 35.0, -5.0, 5.0))
    choice = choose_candidate(_candidates(1.0, 0.0, -2.0), boxes, PROBLEM)
    assert not choice.free.any() and choice.best == 1


def test_the_clearance_is_the_configured_obstacle_margin() -> None:
    # the box's edge 1.3 m from the d = 0 candidate's centre: 0.9 m half-width + 0.3 m margin clears it,
    # a 0.5 m margin does not
    boxes = frenet_boxes(REF, _box(30.0, 35.0, 1.3, 2.0))
    assert choose_candidate(_candidates(0.0), boxes, PROBLEM).free.tolist() == [True]
    wider = replace(DEFAULT_CONFIG, obstacle_margin=0.5)
    assert choose_candidate(_candidates(0.0), boxes, PROBLEM, wider).free.tolist() == [False]


def test_the_weights_trade_offset_against_bends_and_progress() -> None:
    wiggle = 0.2 * np.sin(S)  # mean square 0.02, but bends
    offset = np.full(S.shape, 0.5)  # mean square 0.25, straight
    cands = _candidates(wiggle, offset)
    assert choose_candidate(cands, NO_BOXES, PROBLEM).best == 1  # bends cost 10 per unit of slope change
    no_bends = replace(DEFAULT_CONFIG, selection=SelectionConfig(bend_weight=0.0))
    assert choose_candidate(cands, NO_BOXES, PROBLEM, no_bends).best == 0
    # a candidate that ends early (its last points jumped) loses its progress
    short = np.ones(_candidates(0.0, 0.5).d.shape, dtype=bool)
    short[0, 50:] = False
    early = _candidates(0.0, 0.5, valid=short)
    assert choose_candidate(early, NO_BOXES, PROBLEM).best == 1
    no_progress = replace(DEFAULT_CONFIG, selection=SelectionConfig(progress_weight=0.0))
    assert choose_candidate(early, NO_BOXES, PROBLEM, no_progress).best == 0
