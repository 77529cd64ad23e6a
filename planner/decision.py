"""The lane decision: keep the lane, or borrow the road beyond it on one side to get past what blocks it.

Apollo's split: this decider turns what the lane plan met into bounds — a :class:`planner.lane.Corridor`
(the lane widened to the road's edge on one side over an interval of arc length, with ramps in and out),
the boxes of the vehicles it overtakes, a line to wait at — and the optimisers (candidates, lateral
QP, speed profile) consume them. It runs after the plan in the lane (candidates, choice, lateral stage):

* **keep** the lane unless something blocks it: the lane plan stops before a block
  (:attr:`planner.lateral.LateralPlan.stops`: a static obstacle, parked vehicles given as predictions
  included; a bend tighter than the vehicle can take within the lane; a lane narrower than the
  vehicle), or a moving obstacle ahead, too wide to pass within the lane, drives much slower than the
  target speed (``slow_share``, ``slow_margin``), or the ego is already outside its lane where the road
  goes on (it comes back);
* **borrow** the road on the side that gets past: a bend's outside; beside obstacles, the side whose
  corridor the vehicle fits through (the nearer to the reference if both). The interval is the lane's
  blocked knots (its lateral bounds with the obstacles of the whole road, each passed on its roomier side,
  no margin to the lane's edges) merged with blocks that follow closer than a return; a slow vehicle
  blocks where it is swept from now until the vehicle, at its nominal speed, is a ``pass_headway`` ahead
  of it. The ramps are ``ramp_time`` of driving long, at least ``min_ramp_lengths`` vehicle lengths;
* only if the corridor's lateral bounds are free over the interval and its ramps, the manoeuvre ends
  within the path (or the reference's end) and no moving obstacle other than those overtaken is in the
  borrowed space — the road beyond the lane on that side over the interval and its ramps — from the
  earliest the vehicle can get there until the latest it leaves it (:func:`ego_times`, widened by
  ``time_margin``). Otherwise keep, and where a moving obstacle is the reason, stop a swing-out's length
  before the block (:attr:`Decision.wait_at`) to go once it is clear.

An ego already outside its lane keeps borrowing until it is back: it never waits in the road.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from planner.bounds import LateralBounds, lateral_bounds, roomier_left
from planner.collision import FrenetBoxes, box_corners, frenet_boxes, prediction_at
from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.ego import EgoFrenet
from planner.frenet import to_frenet
from planner.lane import Corridor, Side, corridor_width, lane_bounds
from planner.lateral import LateralPlan, knots
from planner.problem import DynamicObstacle, Lane, PlanningProblem, Road
from planner.reference import FloatArray, ReferenceLine
from planner.st_bounds import frenet_extents, moving_obstacles


class LaneChoice(StrEnum):
    """Where the plan drives: its lane, or the road beyond it on one side."""

    KEEP = "keep"
    BORROW_LEFT = "borrow_left"
    BORROW_RIGHT = "borrow_right"


class BlockKind(StrEnum):
    """What blocks the lane."""

    #: a static obstacle (a vehicle that stands over the horizon included)
    OBSTACLE = "obstacle"
    #: a moving obstacle ahead, too wide to pass in the lane, much slower than the target speed
    SLOW_VEHICLE = "slow_vehicle"
    #: a bend tighter than the vehicle can take within the lane
    BEND = "bend"
    #: the lane is narrower than the vehicle
    NARROW = "narrow"


class ReasonKind(StrEnum):
    """Why the decision is what it is."""

    #: keep: nothing blocks the lane
    LANE_FREE = "lane_free"
    #: borrow: to get past what blocks the lane
    PASSING = "passing"
    #: borrow: the vehicle is outside its lane and comes back
    RETURNING = "returning"
    #: keep: a moving obstacle would be in the borrowed space while the vehicle is: wait
    ONCOMING = "oncoming"
    #: keep: the road beyond the lane leaves no room past the block either
    ROAD_BLOCKED = "road_blocked"
    #: keep: the way back into the lane after the block is not within the path
    NO_RETURN = "no_return"
    #: keep: the lateral stage finds no path through the borrowed road from where the vehicle is (too
    #: close to the block to swing out)
    NO_PATH = "no_path"
    #: keep: the lane is blocked and the problem has no road beyond it
    NO_ROAD = "no_road"


@dataclass(frozen=True)
class Reason:
    """Why: its ``kind``; what blocks the lane (``block``: an obstacle ``obstacle_id``, a bend, a narrow
    lane) where (``s`` [m] on the reference); for ``ONCOMING``, the moving obstacle ``oncoming_id`` in the
    borrowed space and the first time ``t`` [s] it is there; the ``side`` borrowed or wanted."""

    kind: ReasonKind
    block: BlockKind | None = None
    obstacle_id: str | None = None
    s: float | None = None
    t: float | None = None
    oncoming_id: str | None = None
    side: Side | None = None

    @property
    def blocked(self) -> str:
        """What blocks the lane, in words (empty when nothing does)."""
        if self.block is None:
            return ""
        at = f"s = {self.s:.1f} m" if self.s is not None else "ahead"
        if self.block is BlockKind.OBSTACLE:
            return f"obstacle {self.obstacle_id} blocks the lane at {at}"
        if self.block is BlockKind.SLOW_VEHICLE:
            return f"obstacle {self.obstacle_id} ahead at {at} is much slower than the target speed"
        if self.block is BlockKind.BEND:
            return f"the bend at {at} is tighter than the vehicle can take in the lane"
        return f"the lane at {at} is narrower than the vehicle"

    @property
    def message(self) -> str:
        """The reason in words, as answers report it."""
        side = f"the {self.side}" if self.side else "either side"
        kind = self.kind
        if kind is ReasonKind.LANE_FREE:
            return "the lane is free"
        if kind is ReasonKind.RETURNING:
            head = f"returning to the lane from the road on {side}"
            return f"{head}; {self.blocked}" if self.block else head
        if kind is ReasonKind.PASSING:
            tail = f"passing through the road on {side}"
        elif kind is ReasonKind.ONCOMING:
            when = "" if self.t is None else f" from t = {self.t:.1f} s"
            tail = f"obstacle {self.oncoming_id} would be in the road beyond the lane on {side}{when}"
            tail += ": waiting"
        elif kind is ReasonKind.ROAD_BLOCKED:
            tail = "the road beyond the lane leaves no room either"
        elif kind is ReasonKind.NO_RETURN:
            tail = "no way back into the lane within the path"
        elif kind is ReasonKind.NO_PATH:
            tail = "no path through the road beyond the lane from here"
        else:
            tail = "no road beyond the lane"
        return f"{self.blocked}: {tail}" if self.block else tail


@dataclass(frozen=True)
class Decision:
    """The lane decision and the bounds it hands the optimisers.

    Attributes:
        lane: keep, or borrow the road on one side.
        reason: why.
        corridor: what a borrow drives in (the lane widened to the road), else None.
        boxes: a borrow's static obstacles over the whole road, with the swept boxes of the vehicles it
            overtakes, else None (the lane plan's stand).
        passing: ids of the moving obstacles a borrow overtakes: the speed profile does not follow them.
        wait_at: where a kept lane stops, before a block [m] (a swing-out's length before it), or None.
        urgent: whether a borrow's block is closer than the vehicle stops braking at half its
            deceleration: the path may then bend as sharply as full braking allows.
    """

    lane: LaneChoice
    reason: Reason
    corridor: Corridor | None = None
    boxes: FrenetBoxes | None = None
    passing: frozenset[str] = field(default_factory=frozenset)
    wait_at: float | None = None
    urgent: bool = False

    @property
    def borrows(self) -> bool:
        """Whether the plan borrows the road beyond its lane."""
        return self.lane is not LaneChoice.KEEP


#: the decision when nothing blocks the lane
KEEP_LANE = Decision(LaneChoice.KEEP, Reason(ReasonKind.LANE_FREE))


def decide(
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    lane_plan: LateralPlan,
    static: list[tuple[str, BaseGeometry]],
    lane_boxes: FrenetBoxes,
    s_end: float,
    config: PlannerConfig = DEFAULT_CONFIG,
) -> Decision:
    """The lane decision (see the module docstring) after the plan in the lane ``lane_plan``, whose
    candidate ends at ``s_end`` [m]; ``static`` are the static obstacles' outlines and ``lane_boxes``
    their boxes as the lane plan saw them."""
    road = problem.road
    if road is None and not lane_plan.stops:
        return KEEP_LANE
    at = knots(ref, start, s_end, config.lateral)
    if road is None:
        if lane_plan.blocked is None:
            return KEEP_LANE
        return _keep(ReasonKind.NO_ROAD, _what_blocks(ref, problem, at, lane_plan.blocked, lane_boxes))
    out_on = _outside_lane(ref, problem, road, config)
    stops = lane_plan.stops and lane_plan.blocked is not None
    slow = None if stops else _slow_vehicle(ref, problem, start, at, config)
    if not stops and out_on is None and slow is None:
        return KEEP_LANE
    boxes = frenet_boxes(ref, static, reach=corridor_width(problem, config, road=True))
    first: int | None = None
    reason = Reason(ReasonKind.RETURNING)
    passing: frozenset[str] = frozenset()
    if stops and lane_plan.blocked is not None:
        first = min(lane_plan.blocked, at.shape[0] - 1)
        reason = _what_blocks(ref, problem, at, first, boxes)
    elif slow is not None:
        if slow.swept is None:
            return _keep(ReasonKind.NO_RETURN, slow.reason)
        boxes = _merged(boxes, slow.swept)
        reason, passing = slow.reason, frozenset(slow.swept.ids)
    blocked = _blocked(ref, problem, _bounds(ref, problem, problem.lane, at, boxes, config), config)
    if slow is not None:
        first = int(np.argmax(blocked))  # the slow vehicle's swept box
    ego_s = start.s if out_on is not None else None
    span = _span(at, blocked, first, ego_s, problem, config)
    side = out_on or _side(ref, problem, road, at, boxes, span, reason, config)
    if side is None:
        return _keep(ReasonKind.ROAD_BLOCKED, reason)
    kind = ReasonKind.RETURNING if first is None else ReasonKind.PASSING
    reason = Reason(kind, reason.block, reason.obstacle_id, reason.s, side=side)
    corridor = _corridor(problem, road, side, span, ego_s, config)
    if out_on is None:
        through = _corridor_blocked(ref, problem, corridor, at, boxes, config)
        if through is None:
            return _keep(ReasonKind.ROAD_BLOCKED, reason)
        if not _room_to_swing(problem, start, through, span.first, side, config):
            return _keep(ReasonKind.NO_PATH, reason)
        if _ends_beyond(ref, problem, corridor, at, config):
            return _keep(ReasonKind.NO_RETURN, reason)
        band = _needed(problem, through, span, side, config)
        conflict = _oncoming(ref, problem, start, corridor, band, passing, config)
        if conflict is not None:
            mover, t = conflict
            wait = Reason(ReasonKind.ONCOMING, reason.block, reason.obstacle_id, reason.s, t, mover, side)
            # before a block it stops a swing-out's length short; behind a slow vehicle it follows
            wait_at = corridor.start - _min_ramp(problem, config) if stops else -np.inf
            return Decision(LaneChoice.KEEP, wait, wait_at=wait_at if wait_at > start.s else None)
    choice = LaneChoice.BORROW_LEFT if side == "left" else LaneChoice.BORROW_RIGHT
    v0, decel = problem.ego.speed, problem.vehicle.max_deceleration
    urgent = span.s_first - start.s < v0 * (v0 / decel)  # within the stop at half deceleration
    return Decision(choice, reason, corridor, boxes, passing, urgent=bool(urgent))


def no_path(decision: Decision) -> Decision:
    """Keep the lane instead of a borrow the lateral stage found no path for (:data:`ReasonKind.NO_PATH`)."""
    return _keep(ReasonKind.NO_PATH, decision.reason)


def _keep(kind: ReasonKind, block: Reason) -> Decision:
    """Keep the lane for ``kind``, what blocks it taken from ``block``."""
    reason = Reason(kind, block.block, block.obstacle_id, block.s, side=block.side)
    return Decision(LaneChoice.KEEP, reason)


def _min_ramp(problem: PlanningProblem, config: PlannerConfig) -> float:
    """The shortest ramp into the road or back [m]: room to swing out from a standstill."""
    return config.decision.min_ramp_lengths * problem.vehicle.length


def _bounds(
    ref: ReferenceLine,
    problem: PlanningProblem,
    lane: Lane,
    at: FloatArray,
    boxes: FrenetBoxes,
    config: PlannerConfig,
    left_of: NDArray[np.bool_] | None = None,
) -> LateralBounds:
    """The lateral bounds in ``lane`` at knots ``at`` [m] with no margin to its edges, every obstacle passed
    on its roomier side unless ``left_of`` says."""
    if left_of is None:
        left_of = _roomier(ref, problem, lane, at, boxes)
    margin = problem.options.lateral_margin
    return lateral_bounds(
        ref, lane, at, problem.vehicle, margin=margin, boxes=boxes, left_of=left_of, lane_margin=0.0
    )


def _roomier(
    ref: ReferenceLine, problem: PlanningProblem, lane: Lane, at: FloatArray, boxes: FrenetBoxes
) -> NDArray[np.bool_]:
    """Per obstacle, whether ``lane`` leaves more room on its left than on its right (for the footprint's
    half width) where it starts (:func:`planner.bounds.roomier_left`)."""
    room = lane_bounds(ref, lane, at, half_width=0.5 * problem.vehicle.width, margin=0.0)
    return roomier_left(boxes, at, room.lower, room.upper)


def _blocked(
    ref: ReferenceLine, problem: PlanningProblem, bounds: LateralBounds, config: PlannerConfig
) -> NDArray[np.bool_]:
    """Blocked knots of ``bounds`` before the reference's end (a lane running out there is its end)."""
    reach = ref.length - problem.vehicle.front_extent - config.stop_gap
    return np.asarray((bounds.lower > bounds.upper) & (bounds.s < reach), dtype=bool)


def _what_blocks(
    ref: ReferenceLine, problem: PlanningProblem, at: FloatArray, knot: int, boxes: FrenetBoxes
) -> Reason:
    """What blocks the lane at knot ``knot`` of ``at``: the nearest obstacle whose box the footprint
    overlaps along the reference there and which reaches into the lane; else a lane narrower than the
    vehicle, or a bend."""
    v, margin = problem.vehicle, problem.options.lateral_margin
    s = float(at[knot])
    left, right = (float(w) for w in problem.lane.widths(ref, s))
    along = (s + v.front_extent + margin >= boxes.s_min) & (s - v.rear_extent - margin <= boxes.s_max)
    across = (boxes.d_max >= -right - margin) & (boxes.d_min <= left + margin)
    hits = np.flatnonzero(along & across)
    if hits.size:
        k = int(hits[np.argmin(boxes.s_min[hits])])
        return Reason(ReasonKind.NO_ROAD, BlockKind.OBSTACLE, boxes.ids[k], s)
    kind = BlockKind.NARROW if left + right <= v.width else BlockKind.BEND
    return Reason(ReasonKind.NO_ROAD, kind, None, s)


def _outside_lane(
    ref: ReferenceLine, problem: PlanningProblem, road: Road, config: PlannerConfig
) -> Side | None:
    """The side on which the ego's footprint reaches more than ``outside_tolerance`` beyond its lane into
    a road that goes on beyond it there, or None."""
    ego, v = problem.ego, problem.vehicle
    corners = box_corners(np.array(ego.x), np.array(ego.y), np.array(ego.heading), v.length, v.width)
    fr = to_frenet(ref, corners.reshape(-1, 2))
    left, right = problem.lane.widths(ref, fr.s)
    road_left, road_right = road.widths(ref, fr.s)
    tol = config.decision.outside_tolerance
    beyond_left = float(np.max(np.where(road_left > left + tol, fr.d - left, 0.0)))
    beyond_right = float(np.max(np.where(road_right > right + tol, -right - fr.d, 0.0)))
    if max(beyond_left, beyond_right) <= tol:
        return None
    return "left" if beyond_left >= beyond_right else "right"


@dataclass(frozen=True)
class _Span:
    """The knots ``first..last`` of ``at`` a borrow covers (the blocked run and those merged with it)."""

    first: int
    last: int
    s_first: float
    s_last: float


def _ramps(problem: PlanningProblem, config: PlannerConfig) -> tuple[float, float]:
    """The ramp into the road at the ego's speed and back at the target's [m], each at least the shortest."""
    shortest = _min_ramp(problem, config)
    target = _target_speed(problem)
    ramp_time = config.decision.ramp_time
    return max(shortest, problem.ego.speed * ramp_time), max(shortest, target * ramp_time)


def _span(
    at: FloatArray,
    blocked: NDArray[np.bool_],
    first: int | None,
    ego_s: float | None,
    problem: PlanningProblem,
    config: PlannerConfig,
) -> _Span:
    """The blocked run of knots from ``first`` (or the ego's ``ego_s`` [m] when it is outside its lane),
    merged with the runs that follow closer than both ramps and a vehicle length."""
    ramp_in, ramp_out = _ramps(problem, config)
    gap = ramp_in + ramp_out + problem.vehicle.length
    idx = np.flatnonzero(blocked)
    i0 = i1 = 0 if first is None else first  # none: outside the lane, from where the ego is
    for k in idx[idx > i1]:
        if at[k] - at[i1] > gap:
            break
        i1 = int(k)
    s_first = float(at[i0]) if ego_s is None else min(float(at[i0]), ego_s)
    return _Span(i0, i1, s_first, float(at[i1]))


def _corridor(
    problem: PlanningProblem,
    road: Road,
    side: Side,
    span: _Span,
    ego_s: float | None,
    config: PlannerConfig,
) -> Corridor:
    """The lane opened to the road on ``side`` over the span, with its ramps (none behind an ego
    already outside the lane, at ``ego_s`` [m])."""
    ramp_in, ramp_out = _ramps(problem, config)
    lane = problem.lane
    start = span.s_first - problem.vehicle.length if ego_s is not None else span.s_first
    return Corridor(lane.left_width, lane.right_width, road, side, start, span.s_last, ramp_in, ramp_out)


def _corridor_blocked(
    ref: ReferenceLine,
    problem: PlanningProblem,
    corridor: Corridor,
    at: FloatArray,
    boxes: FrenetBoxes,
    config: PlannerConfig,
) -> LateralBounds | None:
    """The corridor's lateral bounds at knots ``at`` [m] when they are free from its ramp in to its ramp
    out, else None: the obstacles reaching into the lane along its open stretch and ramps passed on the
    borrowed side, the others on their roomier side."""
    left_of = _roomier(ref, problem, corridor, at, boxes)
    lo, hi = corridor.start - corridor.ramp_in, corridor.end + corridor.ramp_out
    lane_left, lane_right = problem.lane.widths(ref, 0.5 * (boxes.s_min + boxes.s_max))
    in_lane = (boxes.d_min <= lane_left) & (boxes.d_max >= -lane_right)
    passed = (boxes.s_max >= lo) & (boxes.s_min <= hi) & in_lane
    left_of = np.where(passed, corridor.side == "left", left_of)
    bounds = _bounds(ref, problem, corridor, at, boxes, config, left_of)
    within = (at >= lo) & (at <= hi)
    return None if np.any(_blocked(ref, problem, bounds, config) & within) else bounds


def _room_to_swing(
    problem: PlanningProblem,
    start: EgoFrenet,
    bounds: LateralBounds,
    first: int,
    side: Side,
    config: PlannerConfig,
) -> bool:
    """Whether the planned point can get from its offset into the corridor's ``bounds`` at the first
    blocked knot ``first`` at all: an arc at ``curvature_share · κ_max`` from the reference's heading
    moves ``κ·x²/2`` sideways over ``x`` [m] (a cheap bound before the lateral QP tries)."""
    s = bounds.s[first]
    need = bounds.lower[first] - start.d if side == "left" else start.d - bounds.upper[first]
    if need <= 0.0:
        return True
    kappa = config.lateral.curvature_share * problem.vehicle.curvature_limit
    return bool(s - start.s >= np.sqrt(2.0 * need / kappa))


def _needed(
    problem: PlanningProblem, bounds: LateralBounds, span: _Span, side: Side, config: PlannerConfig
) -> float:
    """How far into the road the vehicle needs to go [m] (an offset, signed): the farthest the corridor's
    ``bounds`` push its planned point over the span, its half width and ``band_spare`` beyond."""
    part = slice(span.first, span.last + 1)
    reach = 0.5 * problem.vehicle.width + config.decision.band_spare
    if side == "left":
        return float(np.max(bounds.lower[part])) + reach
    return float(np.min(bounds.upper[part])) - reach


def _ends_beyond(
    ref: ReferenceLine, problem: PlanningProblem, corridor: Corridor, at: FloatArray, config: PlannerConfig
) -> bool:
    """Whether the way back into the lane ends beyond the path's knots (and before the reference's end,
    where a return needs no room)."""
    back_in = corridor.end + corridor.ramp_out
    reach = ref.length - problem.vehicle.front_extent - config.stop_gap
    return bool(back_in > float(at[-1]) and float(at[-1]) < reach)


def _side(
    ref: ReferenceLine,
    problem: PlanningProblem,
    road: Road,
    at: FloatArray,
    boxes: FrenetBoxes,
    span: _Span,
    reason: Reason,
    config: PlannerConfig,
) -> Side | None:
    """The side to borrow: a bend's outside; else the side whose corridor fits with the least offset from
    the reference over the span (left on a tie); None when neither fits."""
    if reason.block is BlockKind.BEND:
        kappa = float(np.mean(ref.kappa_at(at[span.first : span.last + 1])))
        return "right" if kappa > 0.0 else "left"
    best: tuple[float, Side] | None = None
    sides: tuple[Side, Side] = ("left", "right")
    part = slice(span.first, span.last + 1)
    for side in sides:
        bounds = _corridor_blocked(
            ref, problem, _corridor(problem, road, side, span, None, config), at, boxes, config
        )
        if bounds is None:
            continue
        offset = float(np.mean(np.maximum(np.maximum(bounds.lower[part], -bounds.upper[part]), 0.0)))
        if best is None or offset < best[0]:
            best = (offset, side)
    return None if best is None else best[1]


def _merged(a: FrenetBoxes, b: FrenetBoxes) -> FrenetBoxes:
    """Both sets of boxes."""
    return FrenetBoxes(
        a.ids + b.ids,
        np.concatenate((a.s_min, b.s_min)),
        np.concatenate((a.s_max, b.s_max)),
        np.concatenate((a.d_min, b.d_min)),
        np.concatenate((a.d_max, b.d_max)),
    )


def _target_speed(problem: PlanningProblem) -> float:
    """The speed the plan aims at [m/s] (:func:`planner.speed.target_speed`)."""
    target = problem.options.target_speed
    return problem.vehicle.max_speed if target is None else min(target, problem.vehicle.max_speed)


def ego_times(
    ref: ReferenceLine, problem: PlanningProblem, start: EgoFrenet, s: FloatArray, config: PlannerConfig
) -> tuple[FloatArray, FloatArray]:
    """The earliest and a late time [s] the planned point can be at arc lengths ``s`` [m] ahead of it.

    Earliest: full acceleration from the ego's speed up to the faster of it and the target speed. Late:
    ``nominal_acceleration_share`` of it up to the target speed, never faster than the reference's
    curvature allows (``√(limit_margin · a_lat,max / |κ|)``) nor slower than ``nominal_floor_speed``,
    the time stretched by ``late_factor``.
    """
    v0, a = max(problem.ego.speed, 0.0), problem.vehicle.max_acceleration
    target = _target_speed(problem)
    ahead = np.maximum(np.asarray(s, dtype=float) - start.s, 0.0)
    fast = max(v0, target)
    reach_fast = max(fast**2 - v0**2, 0.0) / (2.0 * a)  # distance until full speed
    accelerating = (np.sqrt(v0**2 + 2.0 * a * np.minimum(ahead, reach_fast)) - v0) / a
    early = accelerating + np.maximum(ahead - reach_fast, 0.0) / max(fast, 1e-9)
    cfg = config.decision
    grid = np.linspace(0.0, float(np.max(ahead, initial=0.0)) + 1e-9, 200)
    kappa = np.abs(ref.kappa_at(start.s + grid))
    with np.errstate(divide="ignore"):
        curve = np.sqrt(config.limit_margin * problem.vehicle.max_lateral_acceleration / kappa)
    gentle = np.sqrt(v0**2 + 2.0 * cfg.nominal_acceleration_share * a * grid)
    speed = np.maximum(np.minimum(np.minimum(gentle, curve), target), cfg.nominal_floor_speed)
    pace = 1.0 / speed
    t_grid = np.concatenate(([0.0], np.cumsum(0.5 * (pace[1:] + pace[:-1]) * np.diff(grid))))
    late = cfg.late_factor * np.interp(ahead, grid, t_grid)
    return np.asarray(early), np.asarray(late)


def _near_movers(
    ref: ReferenceLine, movers: list[DynamicObstacle], t: FloatArray, s_lo: float, s_hi: float, reach: float
) -> tuple[list[DynamicObstacle], list[FloatArray]]:
    """The movers whose predicted centres come within ``reach`` [m] plus their own size of the reference
    between ``s_lo`` and ``s_hi`` [m] at some time of ``t`` [s], with their states then."""
    states = [prediction_at(ob, t) for ob in movers]
    pts = np.concatenate(states)[:, :2]
    dist, idx = ref.tree.query(pts)
    size = np.repeat([np.hypot(ob.length, ob.width) for ob in movers], t.shape[0])
    s_near = ref.s[idx]
    close = (dist <= reach + size) & (s_near >= s_lo - reach) & (s_near <= s_hi + reach)
    near = np.flatnonzero(close.reshape(len(movers), -1).any(axis=1))
    return [movers[k] for k in near], [states[k] for k in near]


def _oncoming(
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    corridor: Corridor,
    band: float,
    passing: frozenset[str],
    config: PlannerConfig,
) -> tuple[str, float] | None:
    """The first moving obstacle (other than ``passing``) in the borrowed space where and while the
    vehicle may be there, and from when [s]; None when it stays clear.

    The borrowed space: beyond the lane's edge on the corridor's side (its narrowest over the stretch)
    into the road as far as the vehicle needs (to the offset ``band`` [m], :func:`_needed`; traffic
    farther out, as in a junction's other lanes, is not in its way), along the corridor's open stretch
    and ramps, a vehicle length more either way. Where
    the vehicle may be at time ``t``: its footprint (with ``obstacle_margin`` and ``stop_gap``) from its
    late position at ``t − time_margin`` to its earliest at ``t + time_margin`` (:func:`ego_times`), until
    the latest it leaves the space. So an oncoming vehicle conflicts where the two would meet in it, one
    ahead and faster does not.
    """
    movers = [ob for ob in moving_obstacles(problem) if ob.id not in passing]
    if not movers:
        return None
    v, cfg = problem.vehicle, config.decision
    s_lo = corridor.start - corridor.ramp_in - v.length
    s_hi = corridor.end + corridor.ramp_out + v.length
    grid = np.linspace(start.s, max(s_hi, start.s + 1.0), 256)
    early, late = ego_times(ref, problem, start, grid, config)
    t = np.arange(0.0, float(late[-1]) + cfg.time_margin + cfg.check_step, cfg.check_step)
    gap = config.obstacle_margin + config.stop_gap
    ahead = np.interp(t + cfg.time_margin, early, grid) + v.front_extent + gap
    behind = np.interp(t - cfg.time_margin, late, grid, left=start.s) - v.rear_extent - gap
    occupied_lo, occupied_hi = np.maximum(behind, s_lo), np.minimum(ahead, s_hi)
    span = np.linspace(s_lo, s_hi, 64)
    lane_left, lane_right = problem.lane.widths(ref, span)
    road_left, road_right = corridor.road.widths(ref, span)
    reach = float(max(np.max(road_left), np.max(road_right)))
    near, states = _near_movers(ref, movers, t, s_lo, s_hi, reach)
    if not near:
        return None
    s_min, s_max, d_min, d_max = frenet_extents(ref, near, states)  # (K, T)
    along = (s_max >= occupied_lo) & (s_min <= occupied_hi) & (occupied_lo <= occupied_hi)
    if corridor.side == "left":
        across = (d_max > float(np.min(lane_left))) & (d_min < min(float(np.max(road_left)), band))
    else:
        across = (d_min < -float(np.min(lane_right))) & (d_max > max(-float(np.max(road_right)), band))
    inside = along & across
    if not inside.any():
        return None
    first = np.where(inside.any(axis=1), np.argmax(inside, axis=1), inside.shape[1])
    k = int(np.argmin(first))
    return near[k].id, float(t[first[k]])


@dataclass(frozen=True)
class _SlowVehicle:
    """A slow vehicle ahead: why it blocks (``reason``) and the box it sweeps until the vehicle is past
    it (None: not within the horizon)."""

    reason: Reason
    swept: FrenetBoxes | None


def _slow_vehicle(
    ref: ReferenceLine, problem: PlanningProblem, start: EgoFrenet, at: FloatArray, config: PlannerConfig
) -> _SlowVehicle | None:
    """The nearest moving obstacle ahead within the path's knots ``at`` [m] that leaves no room to pass
    it in the lane and drives much slower than the target speed (along the reference, over the horizon),
    and the box it sweeps until the vehicle, at its earliest (:func:`ego_times`), is ``pass_headway`` of
    its speed (at least ``stop_gap``) ahead of it."""
    movers = moving_obstacles(problem)
    if not movers:
        return None
    cfg, v = config.decision, problem.vehicle
    horizon = problem.options.horizon_time
    t = np.linspace(0.0, horizon, max(2, int(np.ceil(horizon / cfg.check_step)) + 1))
    lane_left, lane_right = problem.lane.widths(ref, at)
    near, _ = _near_movers(
        ref, movers, t[:1], start.s, float(at[-1]), float(max(np.max(lane_left), np.max(lane_right)))
    )
    if not near:
        return None
    s_min, s_max, d_min, d_max = frenet_extents(ref, near, [prediction_at(ob, t) for ob in near])
    mid = 0.5 * (s_min + s_max)
    speed = (mid[:, -1] - mid[:, 0]) / horizon
    target = _target_speed(problem)
    slow = (speed < cfg.slow_share * target) & (speed < target - cfg.slow_margin)
    left0, right0 = problem.lane.widths(ref, mid[:, 0])
    need = v.width + 2.0 * problem.options.lateral_margin
    no_room = np.maximum(left0 - d_max[:, 0], d_min[:, 0] + right0) < need
    gap = np.maximum(cfg.pass_headway * np.maximum(speed, 0.0), config.stop_gap)
    ahead = (s_max[:, 0] + gap >= start.s - v.rear_extent) & (s_min[:, 0] <= float(at[-1]))  # not passed
    chosen = np.flatnonzero(slow & no_room & ahead)
    if chosen.size == 0:
        return None
    k = int(chosen[np.argmin(s_min[chosen, 0])])
    reason = Reason(ReasonKind.PASSING, BlockKind.SLOW_VEHICLE, near[k].id, float(s_min[k, 0]))
    early, _ = ego_times(ref, problem, start, np.linspace(start.s, float(at[-1]), 400), config)
    ego_s = np.interp(t, early, np.linspace(start.s, float(at[-1]), 400), right=np.inf)
    past = np.flatnonzero(ego_s - v.rear_extent >= s_max[k] + gap[k])
    if past.size == 0:
        return _SlowVehicle(reason, None)
    upto = slice(0, int(past[0]) + 1)
    swept = FrenetBoxes(
        (near[k].id,),
        np.array([float(np.min(s_min[k, upto]))]),
        np.array([float(np.max(s_max[k, upto])) + gap[k]]),
        np.array([float(np.min(d_min[k, upto]))]),
        np.array([float(np.max(d_max[k, upto]))]),
    )
    return _SlowVehicle(reason, swept)
