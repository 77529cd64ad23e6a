"""The lane decision: keep the lane, or borrow the road beyond it on one side to get past what blocks it.

Apollo's split: this decider turns what the lane plan met into bounds — a :class:`planner.lane.Corridor`
(the lane widened to the road's edge on one side over an interval of arc length, with ramps in and out),
the swept boxes of the vehicles it overtakes, a line to wait at — and the optimisers (candidates, lateral
QP, speed profile) consume them. It runs after the plan in the lane (candidates, choice, lateral stage):

* **keep** the lane unless something blocks it: the lane plan stops before a block
  (:attr:`planner.lateral.LateralPlan.stops`: a static obstacle, parked vehicles given as predictions
  included; a bend tighter than the vehicle can take within the lane; a lane narrower than the
  vehicle), or a moving obstacle ahead, too wide to pass within the lane, drives much slower than the
  target speed (``slow_share``, ``slow_margin``), or the ego is already outside its lane where the road
  goes on (it comes back: ``returning``). A goal region that lies in the lane where the plan in it can
  take the vehicle, before an obstacle or a slow vehicle, keeps the lane (``goal_first``: passing would
  not bring it nearer, and would drive past it beside the lane; a bend's swing-out is still taken);
* **borrow** the road on the side that gets past: a bend's outside; beside obstacles, the side whose
  corridor the vehicle fits through (the nearer to the reference if both). The interval is the lane's
  blocked knots (its lateral bounds with the obstacles of the whole road, each passed on its roomier side,
  no margin to the lane's edges) merged with blocks that follow closer than a return; a slow vehicle
  blocks where it is swept from now until the vehicle, at its earliest, is a ``pass_headway`` ahead of it
  (:func:`planner.traffic.slow_vehicle`). Where the lane plan stops because its path leaves the lane
  (:attr:`planner.lateral.LateralPlan.leaves`; its bounds let it through) the block is what it swerves
  round: an obstacle up to a swing-out's ramp beyond, else a slow vehicle ahead (on its way out round it,
  a borrow begun), whose borrow then starts where the path leaves; else the bend. The ramps are
  ``ramp_time`` of driving long, at least ``min_ramp_lengths`` vehicle lengths;
* only if the corridor's lateral bounds are free over the interval and its ramps, an arc can take the
  planned point out far enough before the block, the way back into the lane is within the path (or past
  the reference's end) and no moving obstacle other than those overtaken (round a bend, those ahead going
  the same way, followed: :func:`planner.traffic.leaders`) is in the borrowed space — beyond the lane on
  that side as far as the vehicle needs, over the interval and its ramps — where and while the vehicle
  may be there (:func:`planner.traffic.oncoming`). Otherwise keep; where a moving obstacle
  is the reason and the lane is blocked, stop a swing-out's length before the block
  (:attr:`Decision.wait_at`) to go once it is clear; behind a slow vehicle, follow it.

An ego already outside its lane keeps borrowing until it is back: it never waits in the road. A borrow
the lateral stage finds no path for is dropped for the lane plan (:func:`no_path`).

A much slower vehicle going the same way (slow along the reference and over the ground) that leaves room
beside it *in* the lane (a wide lane; several lanes of one direction a converter merged) is passed within
it (``passing_in_lane``, :func:`_pass_within`) when the lane plan's path runs into the box it sweeps
until the vehicle, at a late estimate, is past it (:func:`planner.traffic.slow_vehicle`), the lane stays
open beside that box on one side and no other moving obstacle is in the lane beside it, from where the
vehicle is, where and while the vehicle may be there (:func:`planner.traffic.first_inside`, the borrow's
check of the road it would take); its roomier side first. The lane stays kept, the corridor is the lane
itself, the swept box is bounded as a static obstacle's on that side, and the speed profile does not
follow it. Without this the lateral stage, which bounds static obstacles only, followed it, to a
standstill behind one that crawls. A pass whose path must stop before the sweep (the lateral stage keeps
a margin to the lane's edges that this check does not) is dropped for the lane plan, which follows it
(:attr:`Decision.passes_within`, :mod:`planner.pipeline`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from functools import partial

import numpy as np
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from planner.bounds import KnotGeometry, LateralBounds, knot_geometry, lateral_bounds, roomier_left
from planner.collision import FrenetBoxes, box_hits, footprint_extent, frenet_boxes, outline_points
from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.ego import EgoFrenet
from planner.frenet import to_frenet
from planner.goal_plan import GoalSetup
from planner.lane import Corridor, Side, corridor_width, lane_bounds
from planner.lateral import LateralPlan, knots
from planner.problem import Lane, PlanningProblem, Road, target_speed
from planner.reference import FloatArray, ReferenceLine
from planner.traffic import first_inside, leaders, oncoming, slow_vehicle


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
    #: keep: a much slower vehicle that leaves room beside it in the lane is passed within the lane
    PASSING_IN_LANE = "passing_in_lane"
    #: borrow: the vehicle is outside its lane and comes back
    RETURNING = "returning"
    #: keep: a moving obstacle would be in the borrowed space while the vehicle is: wait
    ONCOMING = "oncoming"
    #: keep: the road beyond the lane leaves no room past the block either
    ROAD_BLOCKED = "road_blocked"
    #: keep: the way back into the lane after the block is not within the path
    NO_RETURN = "no_return"
    #: keep: no path through the borrowed road from where the vehicle is (too close to the block to swing
    #: out, or the lateral stage finds none, or the plan through it breaks a check)
    NO_PATH = "no_path"
    #: keep: the lane is blocked and the problem has no road beyond it
    NO_ROAD = "no_road"
    #: keep: the goal's region lies in the lane before what blocks it (reached in the lane)
    GOAL_FIRST = "goal_first"


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
        elif kind is ReasonKind.PASSING_IN_LANE:
            tail = f"passing it within the lane on {side}"
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
        elif kind is ReasonKind.GOAL_FIRST:
            tail = "the goal lies in the lane before it"
        else:
            tail = "no road beyond the lane"
        return f"{self.blocked}: {tail}" if self.block else tail


@dataclass(frozen=True)
class Decision:
    """The lane decision and the bounds it hands the optimisers.

    Attributes:
        lane: keep, or borrow the road on one side.
        reason: why.
        corridor: what a borrow drives in (the lane widened to the road), the lane itself for a pass
            within it, else None.
        boxes: a borrow's static obstacles over the whole road, or a pass's in the lane, with the swept
            boxes of the vehicles it overtakes, else None (the lane plan's stand).
        passing: ids of the moving obstacles a borrow or a pass within the lane overtakes: the speed
            profile does not follow them.
        wait_at: where a kept lane stops, before a block [m] (a swing-out's length before it), or None.
        urgent: whether a borrow's block is closer than the vehicle stops braking at half its
            deceleration: the path may then bend as sharply as full braking allows.
        sides: the obstacles a borrow passes on the borrowed side (id → passed on its left): those
            reaching into the lane along the corridor's open stretch and ramps.
    """

    lane: LaneChoice
    reason: Reason
    corridor: Lane | None = None
    boxes: FrenetBoxes | None = None
    passing: frozenset[str] = field(default_factory=frozenset)
    wait_at: float | None = None
    urgent: bool = False
    sides: Mapping[str, bool] = field(default_factory=dict)

    @property
    def borrows(self) -> bool:
        """Whether the plan borrows the road beyond its lane."""
        return self.lane is not LaneChoice.KEEP

    @property
    def passes_within(self) -> bool:
        """Whether the plan passes a slow vehicle within its lane (:data:`ReasonKind.PASSING_IN_LANE`)."""
        return self.reason.kind is ReasonKind.PASSING_IN_LANE


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
    goal: GoalSetup | None = None,
) -> Decision:
    """The lane decision (see the module docstring) after the plan in the lane ``lane_plan``, whose
    candidate ends at ``s_end`` [m]; ``static`` are the static obstacles' outlines and ``lane_boxes``
    their boxes as the lane plan saw them; ``goal`` the request's goal, if any.

    Where the lane plan's path leaves the lane at a bend with a slow vehicle ahead, the borrow passes that
    vehicle; where that is not possible (oncoming traffic, no way back), the decision is the bend's, as
    without the vehicle: a swing-out through it behind the vehicle where the road is clear (a right angle
    tighter than the car can take in its lane behind a slow car), else what keeps the lane there."""
    once = partial(_decide, ref, problem, start, lane_plan, static, lane_boxes, s_end, config, goal)
    decision = once(pass_slow=True)
    # kept behind the slow vehicle its leaving path was taken to swerve round: decide for the bend
    rounded = (
        problem.road is not None and lane_plan.stops and lane_plan.blocked is not None and lane_plan.leaves
    )
    if rounded and decision.lane is LaneChoice.KEEP and decision.reason.block is BlockKind.SLOW_VEHICLE:
        return once(pass_slow=False)
    return decision


def _decide(
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    lane_plan: LateralPlan,
    static: list[tuple[str, BaseGeometry]],
    lane_boxes: FrenetBoxes,
    s_end: float,
    config: PlannerConfig,
    goal: GoalSetup | None,
    pass_slow: bool,
) -> Decision:
    """:func:`decide`, where a lane plan leaving the lane at a bend with a slow vehicle ahead is taken as
    one swerving round that vehicle (``pass_slow``) or as the bend's."""
    road = problem.road
    at = knots(ref, start, s_end, config.lateral)
    out_on = None if road is None else _outside_lane(ref, problem, road, config)
    if not lane_plan.stops and out_on is None:
        within = _pass_within(ref, problem, start, lane_plan, lane_boxes, at, config)
        if within is not None:
            return within
    if road is None:
        if not lane_plan.stops or lane_plan.blocked is None:
            return KEEP_LANE
        block = _lane_block(ref, problem, at, lane_plan, lane_plan.blocked, lane_boxes, config)
        if lane_plan.leaves and block.block is BlockKind.BEND:
            # its path leaves the lane with nothing in the way there: round a vehicle too slow to follow
            # and too wide to pass, if there is one (candidates weigh movers, the lane's bounds do not)
            slow = slow_vehicle(ref, problem, start, at, config)
            if slow is not None:
                block = Reason(ReasonKind.NO_ROAD, BlockKind.SLOW_VEHICLE, slow.obstacle_id, slow.s)
        return _keep(ReasonKind.NO_ROAD, block)
    stops = lane_plan.stops and lane_plan.blocked is not None
    looks = not stops or (pass_slow and lane_plan.leaves)  # for a slow vehicle to pass
    slow = slow_vehicle(ref, problem, start, at, config) if looks else None
    if not stops and out_on is None and slow is None:
        return KEEP_LANE
    boxes = frenet_boxes(ref, static, reach=corridor_width(problem, config, road=True))
    first: int | None = None
    reason = Reason(ReasonKind.RETURNING)
    passing: frozenset[str] = frozenset()
    leaves_at: int | None = None
    if stops and lane_plan.blocked is not None:
        first = min(lane_plan.blocked, at.shape[0] - 1)
        reason = _lane_block(ref, problem, at, lane_plan, first, boxes, config)
        if slow is not None and reason.block is BlockKind.BEND:
            # its path leaves the lane with nothing in the way there: on its way out round a slow vehicle
            # (a borrow begun), or into a bend before it; the borrow passes that vehicle and covers both
            stops, leaves_at = False, first
        elif (
            out_on is None
            and reason.block is BlockKind.OBSTACLE
            and _goal_first(problem, goal, float(at[max(first - 1, 0)]), config)
        ):
            return _keep(ReasonKind.GOAL_FIRST, reason)
    if not stops and slow is not None:
        reason = Reason(ReasonKind.PASSING, BlockKind.SLOW_VEHICLE, slow.obstacle_id, slow.s)
        behind = slow.s - problem.vehicle.front_extent  # the planned point following it, at most
        if out_on is None and _goal_first(problem, goal, behind, config):
            return _keep(ReasonKind.GOAL_FIRST, reason)
        if slow.swept is None:
            return _keep(ReasonKind.NO_RETURN, reason)
        boxes = _merged(boxes, slow.swept)
        passing = frozenset(slow.swept.ids)
    blocked = _blocked(ref, problem, _bounds(ref, problem, problem.lane, at, boxes, config), config)
    if slow is not None:
        if leaves_at is not None:
            blocked[leaves_at] = True
        first = int(np.argmax(blocked))  # the slow vehicle's swept box, or where the path leaves before it
    ego_s = start.s if out_on is not None else None
    span = _span(at, blocked, first, ego_s, problem, config)
    side = out_on or _side(ref, problem, road, at, boxes, span, reason, config)
    if side is None:
        return _keep(ReasonKind.ROAD_BLOCKED, reason)
    kind = ReasonKind.RETURNING if first is None else ReasonKind.PASSING
    reason = Reason(kind, reason.block, reason.obstacle_id, reason.s, side=side)
    corridor = _corridor(ref, problem, road, side, span, start if out_on else None, config)
    if out_on is None:
        through = _corridor_blocked(ref, problem, corridor, at, boxes, config)
        if through is None:
            return _keep(ReasonKind.ROAD_BLOCKED, reason)
        # (round a bend, the reference's own curvature takes the vehicle outwards)
        swing = reason.block is BlockKind.BEND or _room_to_swing(
            problem, start, through, span.first, side, config
        )
        if not swing:
            return _keep(ReasonKind.NO_PATH, reason)
        if _ends_beyond(ref, problem, corridor, at, config):
            return _keep(ReasonKind.NO_RETURN, reason)
        band = _needed(problem, through, span, side, config)
        ignored = passing
        if reason.block is BlockKind.BEND and not passing:  # vehicles ahead going its way are followed
            ignored = leaders(ref, problem, start, config)
        conflict = oncoming(ref, problem, start, corridor, band, ignored, config)
        if conflict is not None:
            mover, t = conflict
            wait = Reason(ReasonKind.ONCOMING, reason.block, reason.obstacle_id, reason.s, t, mover, side)
            # before a block it stops a swing-out's length short; behind a slow vehicle it follows
            wait_at = corridor.start - _min_ramp(problem, config) if stops else -np.inf
            return Decision(LaneChoice.KEEP, wait, wait_at=wait_at if wait_at > start.s else None)
    elif first is not None:  # outside the lane before a block: pass it only if the road stays clear
        conflict = oncoming(ref, problem, start, corridor, _needed_out(problem, side), passing, config)
        if conflict is not None:  # back into the lane where it is, and wait there
            mover, t = conflict
            reason = Reason(ReasonKind.ONCOMING, reason.block, reason.obstacle_id, reason.s, t, mover, side)
            back = _Span(0, 0, start.s, start.s)
            corridor = _corridor(ref, problem, road, side, back, start, config)
    choice = LaneChoice.BORROW_LEFT if side == "left" else LaneChoice.BORROW_RIGHT
    v0, decel = problem.ego.speed, problem.vehicle.max_deceleration
    urgent = span.s_first - start.s < v0 * (v0 / decel)  # within the stop at half deceleration
    passed = _passed(ref, problem, corridor, boxes)
    sides = {ob_id: side == "left" for ob_id, on in zip(boxes.ids, passed, strict=True) if on}
    return Decision(choice, reason, corridor, boxes, passing, urgent=bool(urgent), sides=sides)


def _pass_within(
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    lane_plan: LateralPlan,
    lane_boxes: FrenetBoxes,
    at: FloatArray,
    config: PlannerConfig,
) -> Decision | None:
    """Pass a much slower vehicle going the same way that leaves room beside it within the lane (a wide
    lane, a lane of several the converter merged): its swept box until the vehicle is past it bounded as a
    static obstacle's, where the lane plan's path meets it, on a side (the roomier first) where the lane
    stays open beside it over the whole sweep and no other moving obstacle is in the lane beside the box
    (at least the vehicle's width with ``lateral_margin`` either side), from where the vehicle is to a
    vehicle length past the box, where and while the vehicle may be there; None otherwise (the speed
    profile follows it)."""
    path = lane_plan.path
    if path is None:
        return None
    margin = problem.options.lateral_margin
    reach = 0.5 * problem.vehicle.width + margin
    band = (float(np.min(path.d)) - reach, float(np.max(path.d)) + reach)
    slow = slow_vehicle(ref, problem, start, at, config, in_lane=band)
    if slow is None or slow.swept is None:
        return None
    turned = path.heading - ref.heading_at(path.s)  # the path's heading error, wrapped to (−π, π]
    heading = np.arctan2(np.sin(turned), np.cos(turned))
    if not box_hits(slow.swept, path.s, path.d, footprint_extent(heading, problem.vehicle, margin)).any():
        return None  # the lane plan passes it already
    boxes = _merged(lane_boxes, slow.swept)
    left_of = _roomier(ref, problem, problem.lane, at, boxes)
    swept, v, passing = slow.swept, problem.vehicle, frozenset(slow.swept.ids)
    need = v.width + 2.0 * margin
    # from where the vehicle is: its path swings out from here
    along = (min(start.s, float(swept.s_min[0]) - v.length), float(swept.s_max[0]) + v.length)
    lane_left, lane_right = problem.lane.widths(ref, at)
    lane_reach = float(max(np.max(lane_left), np.max(lane_right)))
    # the lane is open beside the box where the footprint overlaps it along the reference (elsewhere the
    # bounds are the lane plan's, which does not stop); the geometry the same for both sides
    beside = at[
        (at + v.front_extent + margin >= swept.s_min[0]) & (at - v.rear_extent - margin <= swept.s_max[0])
    ]
    if not beside.size:
        return None
    geometry: KnotGeometry | None = None
    for left in (bool(left_of[-1]), not left_of[-1]):  # its roomier side first
        # no other traffic in the lane beside it (the path may use all of it) where and while the vehicle
        # may be there
        if left:
            across = (float(swept.d_max[0]), max(float(swept.d_max[0]) + need, float(np.max(lane_left))))
        else:
            across = (min(float(swept.d_min[0]) - need, -float(np.max(lane_right))), float(swept.d_min[0]))
        traffic = first_inside(ref, problem, start, along, across, lane_reach, passing, config)
        if traffic is not None:
            continue
        left_of[-1] = left
        if geometry is None:
            geometry = knot_geometry(ref, problem.lane, beside, v)
        bounds = _bounds(ref, problem, problem.lane, beside, boxes, config, left_of, geometry)
        if _blocked(ref, problem, bounds, config).any():
            continue
        side: Side = "left" if left else "right"
        reason = Reason(
            ReasonKind.PASSING_IN_LANE, BlockKind.SLOW_VEHICLE, slow.obstacle_id, slow.s, side=side
        )
        return Decision(LaneChoice.KEEP, reason, problem.lane, boxes, passing, sides={slow.obstacle_id: left})
    return None


def no_path(decision: Decision) -> Decision:
    """Keep the lane instead of a borrow the lateral stage found no path for (:data:`ReasonKind.NO_PATH`);
    instead of a pass within the lane, the lane plan as if nothing blocked it (it follows the vehicle)."""
    if decision.reason.kind is ReasonKind.PASSING_IN_LANE:
        return KEEP_LANE
    return _keep(ReasonKind.NO_PATH, decision.reason)


def _goal_first(
    problem: PlanningProblem, goal: GoalSetup | None, free_to: float, config: PlannerConfig
) -> bool:
    """Whether the goal's region lies in the lane where the plan in it can take the vehicle: its centre
    inside at the first knot with an offset in the region (:attr:`planner.goal_region.RegionOnReference.
    s_in`) no farther than where the planned point stops, ``stop_gap`` before ``free_to`` [m] (the last
    free knot, or behind a slow vehicle), and the region not all behind the centre now. Passing the block
    would not bring the goal nearer."""
    region = None if goal is None else goal.region
    if goal is None or region is None or not region.reachable or region.s_out < goal.ego_s:
        return False
    centre = free_to - config.stop_gap + problem.vehicle.rear_offset  # (a car plans its rear axle)
    return region.s_in <= centre


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
    geometry: KnotGeometry | None = None,
) -> LateralBounds:
    """The lateral bounds in ``lane`` at knots ``at`` [m] with no margin to its edges, every obstacle passed
    on its roomier side unless ``left_of`` says (``geometry``: :func:`planner.bounds.knot_geometry` of
    these knots and lane, where the caller has it)."""
    if left_of is None:
        left_of = _roomier(ref, problem, lane, at, boxes)
    margin = problem.options.lateral_margin
    return lateral_bounds(
        ref,
        lane,
        at,
        problem.vehicle,
        margin=margin,
        boxes=boxes,
        left_of=left_of,
        lane_margin=0.0,
        geometry=geometry,
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


def _lane_block(
    ref: ReferenceLine,
    problem: PlanningProblem,
    at: FloatArray,
    lane_plan: LateralPlan,
    knot: int,
    boxes: FrenetBoxes,
    config: PlannerConfig,
) -> Reason:
    """What stops ``lane_plan`` at knot ``knot`` of ``at`` (:func:`_what_blocks`). Where its path leaves
    the lane there (:attr:`planner.lateral.LateralPlan.leaves`), also what it swerves round: an obstacle
    up to a swing-out's ramp beyond."""
    ahead = _ramps(problem, config)[0] if lane_plan.leaves else 0.0
    return _what_blocks(ref, problem, at, min(knot, at.shape[0] - 1), boxes, ahead)


def _what_blocks(
    ref: ReferenceLine,
    problem: PlanningProblem,
    at: FloatArray,
    knot: int,
    boxes: FrenetBoxes,
    ahead: float = 0.0,
) -> Reason:
    """What blocks the lane at knot ``knot`` of ``at``: the nearest obstacle whose box the footprint
    overlaps along the reference there, or up to ``ahead`` [m] beyond it, and which reaches into the
    lane; else a lane narrower than the vehicle, or a bend."""
    v, margin = problem.vehicle, problem.options.lateral_margin
    s = float(at[knot])
    left, right = (float(w) for w in problem.lane.widths(ref, s))
    along = (s + v.front_extent + margin + ahead >= boxes.s_min) & (s - v.rear_extent - margin <= boxes.s_max)
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
    """The side on which the ego's footprint (its outline: :func:`planner.collision.outline_points`) reaches
    more than ``outside_tolerance`` beyond its lane into a road that goes on beyond it there, or None."""
    ego, v = problem.ego, problem.vehicle
    outline = outline_points(np.array(ego.x), np.array(ego.y), np.array(ego.heading), v.length, v.width)
    fr = to_frenet(ref, outline.reshape(-1, 2))
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


def _ramps(problem: PlanningProblem, config: PlannerConfig, shift: float = 0.0) -> tuple[float, float]:
    """The ramp into the road at the ego's speed and back at the target's [m]: ``ramp_time`` of driving,
    and at least the shortest and the length of a move ``shift`` [m] sideways at ``ramp_lateral_share``
    of the lateral-acceleration limit (``2·v·√(shift/a)``: accelerating sideways, then braking)."""
    cfg = config.decision
    a = cfg.ramp_lateral_share * problem.vehicle.max_lateral_acceleration
    sideways = 2.0 * np.sqrt(max(shift, 0.0) / a)  # [s]
    shortest = _min_ramp(problem, config)
    ramps = [
        max(shortest, v * max(cfg.ramp_time, sideways)) for v in (problem.ego.speed, target_speed(problem))
    ]
    return ramps[0], ramps[1]


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
    ref: ReferenceLine,
    problem: PlanningProblem,
    road: Road,
    side: Side,
    span: _Span,
    out: EgoFrenet | None,
    config: PlannerConfig,
) -> Corridor:
    """The lane opened to the road on ``side`` over the span, with ramps long enough to move over by
    a vehicle width and the margins (within the road beyond the lane there) or, for an ego already
    outside the lane (``out``, its Frenet state), back into it (the corridor then starts a vehicle
    length behind it)."""
    lane, vehicle = problem.lane, problem.vehicle
    s = np.linspace(span.s_first, span.s_last, 16)
    k = 0 if side == "left" else 1
    beyond = float(np.max(np.asarray(road.widths(ref, s))[k] - np.asarray(lane.widths(ref, s))[k]))
    shift = min(beyond, vehicle.width + 2.0 * problem.options.lateral_margin)
    if out is not None:  # how far its centre is from where it fits in the lane
        edge = float(lane.widths(ref, out.s)[k]) - 0.5 * vehicle.width
        shift = max(shift, abs(out.d) - edge)
    ramp_in, ramp_out = _ramps(problem, config, shift)
    start = span.s_first - problem.vehicle.length if out is not None else span.s_first
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
    left_of = np.where(_passed(ref, problem, corridor, boxes), corridor.side == "left", left_of)
    bounds = _bounds(ref, problem, corridor, at, boxes, config, left_of)
    within = (at >= corridor.start - corridor.ramp_in) & (at <= corridor.end + corridor.ramp_out)
    return None if np.any(_blocked(ref, problem, bounds, config) & within) else bounds


def _passed(
    ref: ReferenceLine, problem: PlanningProblem, corridor: Corridor, boxes: FrenetBoxes
) -> NDArray[np.bool_]:
    """Which obstacles a borrow passes on its side: those reaching into the lane along the corridor's
    open stretch and ramps."""
    lane_left, lane_right = problem.lane.widths(ref, 0.5 * (boxes.s_min + boxes.s_max))
    in_lane = (boxes.d_min <= lane_left) & (boxes.d_max >= -lane_right)
    along = (boxes.s_max >= corridor.start - corridor.ramp_in) & (
        boxes.s_min <= corridor.end + corridor.ramp_out
    )
    return np.asarray(along & in_lane, dtype=bool)


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


def _needed_out(problem: PlanningProblem, side: Side) -> float:
    """How far into the road a vehicle already in it needs to stay (an offset, signed): the whole road
    it may be in (the borrowed space's outer bound left open)."""
    return np.inf if side == "left" else -np.inf


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
    lane_widths = problem.lane.widths(ref, at[part])
    road_widths = road.widths(ref, at[part])
    for side, lane_w, road_w in zip(sides, lane_widths, road_widths, strict=True):
        if not np.any(road_w > lane_w):  # no road beyond the lane on this side there
            continue
        bounds = _corridor_blocked(
            ref, problem, _corridor(ref, problem, road, side, span, None, config), at, boxes, config
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
