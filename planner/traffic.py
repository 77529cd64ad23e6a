"""The moving obstacles in the lane decision (:mod:`planner.decision`): when the vehicle can be where,
the slow vehicle ahead it may overtake, and the traffic in the road it would borrow (or beside a
vehicle it would pass within its lane).

Times come from two nominal speed profiles along the reference (:func:`ego_times`): the earliest the
vehicle can be somewhere and a late estimate; the moving obstacles' Frenet boxes over time from
:func:`planner.st_bounds.frenet_extents`, only for those that come near the stretch that matters.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.collision import FrenetBoxes, prediction_at
from planner.config import PlannerConfig
from planner.ego import EgoFrenet
from planner.frenet import to_frenet
from planner.lane import Corridor
from planner.problem import DynamicObstacle, PlanningProblem, target_speed
from planner.reference import FloatArray, ReferenceLine
from planner.st_bounds import frenet_extents, moving_obstacles


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
    target = target_speed(problem)
    ahead = np.maximum(np.asarray(s, dtype=float) - start.s, 0.0)
    fast = max(v0, target)
    reach_fast = max(fast**2 - v0**2, 0.0) / (2.0 * a)  # distance until full speed
    accelerating = np.maximum((np.sqrt(v0**2 + 2.0 * a * np.minimum(ahead, reach_fast)) - v0) / a, 0.0)
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
    between ``s_lo`` and ``s_hi`` [m] (widened by as much) at some time of ``t`` [s], with their states
    then. Along it too their size counts: a long truck beside the vehicle has its centre behind it."""
    states = [prediction_at(ob, t) for ob in movers]
    pts = np.concatenate(states)[:, :2]
    dist, idx = ref.tree.query(pts)
    size = np.repeat([np.hypot(ob.length, ob.width) for ob in movers], t.shape[0])
    s_near = ref.s[idx]
    close = (dist <= reach + size) & (s_near >= s_lo - reach - size) & (s_near <= s_hi + reach + size)
    near = np.flatnonzero(close.reshape(len(movers), -1).any(axis=1))
    return [movers[k] for k in near], [states[k] for k in near]


def oncoming(
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
    v = problem.vehicle
    s_lo = corridor.start - corridor.ramp_in - v.length
    s_hi = corridor.end + corridor.ramp_out + v.length
    span = np.linspace(s_lo, s_hi, 64)
    lane_left, lane_right = problem.lane.widths(ref, span)
    road_left, road_right = corridor.road.widths(ref, span)
    if corridor.side == "left":
        across = (float(np.min(lane_left)), min(float(np.max(road_left)), band))
    else:
        across = (max(-float(np.max(road_right)), band), -float(np.min(lane_right)))
    reach = float(max(np.max(road_left), np.max(road_right)))
    return first_inside(ref, problem, start, (s_lo, s_hi), across, reach, passing, config)


def leaders(
    ref: ReferenceLine, problem: PlanningProblem, start: EgoFrenet, config: PlannerConfig
) -> frozenset[str]:
    """The moving obstacles ahead of the vehicle's front now (their Frenet box) that go the way of the
    reference there (heading closer to it than ``crossing_angle``: not crossing): the vehicles it
    follows."""
    movers = moving_obstacles(problem)
    if not movers:
        return frozenset()
    now = [prediction_at(ob, np.zeros(1)) for ob in movers]
    s_min = frenet_extents(ref, movers, now)[0][:, 0]
    centre = to_frenet(ref, np.array([st[0, :2] for st in now]))
    turned = np.array([st[0, 2] for st in now]) - ref.heading_at(centre.s)
    along = np.cos(turned) > math.cos(config.speed.crossing_angle)
    ahead = s_min > start.s + problem.vehicle.front_extent
    return frozenset(ob.id for ob, keep in zip(movers, ahead & along, strict=True) if keep)


def first_inside(
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    along: tuple[float, float],
    across: tuple[float, float],
    reach: float,
    excluded: frozenset[str],
    config: PlannerConfig,
) -> tuple[str, float] | None:
    """The first moving obstacle (other than ``excluded``) whose Frenet box reaches into the space
    ``along`` × ``across`` (arc length [m] × offset [m], the offsets' bounds excluded) where and while the
    vehicle may be there (its footprint with ``obstacle_margin`` and ``stop_gap`` from its late position
    at ``t − time_margin`` to its earliest at ``t + time_margin``, :func:`ego_times`), and from when [s];
    None when it stays clear. Movers farther than ``reach`` [m] from the reference are not looked at."""
    movers = [ob for ob in moving_obstacles(problem) if ob.id not in excluded]
    if not movers:
        return None
    v, cfg = problem.vehicle, config.decision
    s_lo, s_hi = along
    grid = np.linspace(start.s, max(s_hi, start.s + 1.0), 256)
    early, late = ego_times(ref, problem, start, grid, config)
    # predictions are for the horizon: beyond twice it, a late estimate says nothing
    t_end = min(float(late[-1]) + cfg.time_margin, 2.0 * problem.options.horizon_time)
    t = np.arange(0.0, t_end + cfg.check_step, cfg.check_step)
    gap = config.obstacle_margin + config.stop_gap
    ahead = np.interp(t + cfg.time_margin, early, grid) + v.front_extent + gap
    behind = np.interp(t - cfg.time_margin, late, grid, left=start.s) - v.rear_extent - gap
    occupied_lo, occupied_hi = np.maximum(behind, s_lo), np.minimum(ahead, s_hi)
    near, states = _near_movers(ref, movers, t, s_lo, s_hi, reach)
    if not near:
        return None
    s_min, s_max, d_min, d_max = frenet_extents(ref, near, states)  # (K, T)
    inside = (s_max >= occupied_lo) & (s_min <= occupied_hi) & (occupied_lo <= occupied_hi)
    inside &= (d_max > across[0]) & (d_min < across[1])
    if not inside.any():
        return None
    first = np.where(inside.any(axis=1), np.argmax(inside, axis=1), inside.shape[1])
    k = int(np.argmin(first))
    return near[k].id, float(t[first[k]])


def _ground_speed(movers: list[DynamicObstacle], horizon: float) -> FloatArray:
    """Each mover's average speed over the ground [m/s] from now to the end of its prediction or of the
    horizon [s], whichever comes first (0 for a prediction that ends now)."""
    speeds = []
    for ob in movers:
        end = min(max(float(ob.prediction[-1, 0]), 0.0), horizon)
        (x0, y0, _), (x1, y1, _) = prediction_at(ob, np.array([0.0, end]))
        speeds.append(math.hypot(x1 - x0, y1 - y0) / end if end > 0.0 else 0.0)
    return np.array(speeds)


@dataclass(frozen=True)
class SlowVehicle:
    """A slow vehicle ahead: its id, where its box starts [m] and the box it sweeps until the vehicle is
    past it (None: not within the horizon)."""

    obstacle_id: str
    s: float
    swept: FrenetBoxes | None


def slow_vehicle(
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    at: FloatArray,
    config: PlannerConfig,
    in_lane: tuple[float, float] | None = None,
) -> SlowVehicle | None:
    """The nearest moving obstacle ahead within the path's knots ``at`` [m] that leaves no room to pass
    it in the lane (``in_lane``: that leaves room, and whose box now reaches into this band of offsets
    ``(d_low, d_high)`` [m], the path's, and that goes the same way) and drives much slower than the
    target speed (along the reference, over the horizon or its prediction if that ends sooner), and the
    box it sweeps until the vehicle, at its earliest (:func:`ego_times`; with ``in_lane`` at the late
    estimate, and at most over the horizon), is ``pass_headway`` of its speed (at least ``stop_gap``)
    ahead of it."""
    movers = moving_obstacles(problem)
    if not movers:
        return None
    cfg, v = config.decision, problem.vehicle
    lane_left, lane_right = problem.lane.widths(ref, at)
    now = np.zeros(1)
    near, states = _near_movers(
        ref, movers, now, start.s, float(at[-1]), float(max(np.max(lane_left), np.max(lane_right)))
    )
    if not near:
        return None
    # first where they are now (one mapping): in the way, and not yet passed
    s_min, s_max, d_min, d_max = frenet_extents(ref, near, states)
    left0, right0 = problem.lane.widths(ref, 0.5 * (s_min[:, 0] + s_max[:, 0]))
    need = v.width + 2.0 * problem.options.lateral_margin
    no_room = np.maximum(left0 - d_max[:, 0], d_min[:, 0] + right0) < need
    ahead = (s_max[:, 0] + config.stop_gap >= start.s - v.rear_extent) & (s_min[:, 0] <= float(at[-1]))
    target = target_speed(problem)
    slow_below = min(cfg.slow_share * target, target - cfg.slow_margin)
    if in_lane is None:
        kept = no_room & ahead
    else:
        kept = ~no_room & ahead & (d_max[:, 0] >= in_lane[0]) & (d_min[:, 0] <= in_lane[1])
        # one not slow over the ground is not passed within the lane (along the reference it drives no
        # faster, but for a bend's stretch): a cheap test before its track, for most leaders in a wide lane
        kept &= _ground_speed(near, problem.options.horizon_time) < slow_below
    near = [near[k] for k in np.flatnonzero(kept)]
    if not near:
        return None
    # then their tracks over the horizon
    horizon = problem.options.horizon_time
    t = np.linspace(0.0, horizon, max(2, int(np.ceil(horizon / cfg.track_step)) + 1))
    s_min, s_max, d_min, d_max = frenet_extents(ref, near, [prediction_at(ob, t) for ob in near])
    mid = 0.5 * (s_min + s_max)
    # over the prediction's own span: one that ends within the horizon is held there, not stopping
    span = np.clip([ob.prediction[-1, 0] for ob in near], t[1], horizon)
    at_end = span / t[1]  # where on the grid it ends (t is uniform from 0)
    lo = np.minimum(at_end.astype(int), t.shape[0] - 2)
    rows = np.arange(len(near))
    ends = mid[rows, lo] + (at_end - lo) * (mid[rows, lo + 1] - mid[rows, lo])
    speed = (ends - mid[:, 0]) / span
    slow = speed < slow_below
    if in_lane is not None:  # within the lane, only a vehicle going the same way is overtaken
        slow &= speed >= 0.0
    gap = np.maximum(cfg.pass_headway * np.maximum(speed, 0.0), config.stop_gap)
    not_passed = s_max[:, 0] + gap >= start.s - v.rear_extent
    chosen = np.flatnonzero(slow & not_passed)
    if chosen.size == 0:
        return None
    k = int(chosen[np.argmin(s_min[chosen, 0])])
    grid = np.linspace(start.s, float(at[-1]), 400)
    early, late = ego_times(ref, problem, start, grid, config)
    # within the lane the pass is bounded by this box alone (no corridor's ramps): until surely past
    ego_s = np.interp(t, early if in_lane is None else late, grid, right=np.inf)
    past = np.flatnonzero(ego_s - v.rear_extent >= s_max[k] + gap[k])
    if past.size == 0 and in_lane is None:
        return SlowVehicle(near[k].id, float(s_min[k, 0]), None)
    # (within the lane, a pass not done within the horizon stays beside it: the box to the horizon's end)
    upto = slice(0, int(past[0]) + 1 if past.size else t.shape[0])
    swept = FrenetBoxes(
        (near[k].id,),
        np.array([float(np.min(s_min[k, upto]))]),
        np.array([float(np.max(s_max[k, upto])) + gap[k]]),
        np.array([float(np.min(d_min[k, upto]))]),
        np.array([float(np.max(d_max[k, upto]))]),
    )
    return SlowVehicle(near[k].id, float(s_min[k, 0]), swept)
