"""How a plan aims at its goal (:class:`planner.goal.Goal`): what each stage decides for it.

* **Before planning** (:func:`goal_setup`): the region on the reference (:mod:`planner.goal_region`), the
  speed cap the goal may use, the cruise target, and what already makes the goal unreachable.
* **The speed cap.** The vehicle cruises at the target; a goal with a time window and a region (which it
  may have to hurry to), or a speed range above the target, may drive faster, up to
  ``options.speed_limit`` (None: the target is the cap) within the vehicle's ``max_speed``. The
  candidates then reach as far as that speed drives (:func:`candidate_options`).
* **The candidates' choice** (:func:`candidate_cost`): a candidate costs ``candidate_weight`` times the
  mean squared distance [m²] of its offsets to the region's offsets over the region's ``s``-interval: a
  region beside the reference draws the choice to the candidates that run into it.
* **The lateral QP** (:func:`toward_region`): over that interval the chosen candidate's offsets are moved
  into the region where they lie beside it (``margin`` inside its edge, no more than needed), blended in
  over ``max(2 L, 1.5 s · v)`` before it, back to the candidate's at its end (the QP smooths the step,
  leaving the region late rather than early, and keeps to its obstacle bounds beyond), and scaled
  against the QP's pull towards the reference (``(w_ref + w_offset)/w_ref``,
  :class:`solvers.lateral_qp.LateralWeights`); not where the moved footprint would meet a static obstacle
  up to the region's end (the candidate's own offsets then stay).
* **The speed profile** (:func:`speed_aim`), where the path's centre is inside the region over
  ``[σ_in, σ_out]`` (:func:`planner.goal_region.along_path`), entered and left ``m = min(margin,
  (σ_out − σ_in)/4)`` inside:

  - a speed range from 0 to below ``stop_speed`` is a stop inside, as soon as it comfortably can:
    ``σ_stop`` at the region's entry (``m`` in), else its middle, else its exit (``m`` before it) —
    points fixed on the reference, so that the stop does not creep on from cycle to cycle —, the first
    one the vehicle can stop at braking
    at ``a_c``, ``deceleration_share`` of its deceleration (the exit also where only full braking can; no
    stop where not even that can);
    where ``a_c`` can stop there, the limit keeps to its braking curve to ``m/2`` beyond the stop,
    ``v ≤ √(c² + 2 a_c (σ_stop + m/2 − σ)) − c`` with ``c = a_c²/(2 j)`` (:func:`stop_distance` inverted;
    the stop itself then ends it in finite time), so that the vehicle does not brake late and hard; and
    not to brake early and creep (the cruise target makes standing still cost), it aims to keep up with
    that approach, cruising (reached at half ``max_acceleration``) and then braking on that curve
    (:func:`approach`), :data:`APPROACH_SLACK` behind: at the stop by when it gets there, or where it is
    at the horizon's end (a soft bound as the window's);
  - a time window ``[t_min, t_max]``, with ``m_t = min(window_margin, (t_max − t_min)/4)``: not late,
    ``σ(t_k) ≥ σ_in + m`` at the last knot ``t_k ≤ t_max − m_t`` (beyond the horizon ``T``:
    ``σ(T) ≥ σ_in + m − share · cap · (t_max − m_t − T)``), and — unless it stops inside, where arriving
    early is waiting — not early, ``σ(t_k) ≤ σ_out − m`` at the first knot ``t_k ≥ t_min + m_t``
    (beyond the horizon: at ``T``); soft bounds that every stop, obstacle, limit and follower outranks
    (:class:`solvers.speed_problem.SpeedWeights`);
  - a speed range ``[v_min, v_max]`` otherwise: the limit at most ``v_max`` over the region, from where
    the vehicle can have slowed to it at ``a_c`` (on that braking curve before it), and a cruise target
    of at least ``v_min`` (within the cap).

  Without a region, the cruise target is the target within the speed range (and the cap).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from planner.candidates import CandidateSet
from planner.collision import FrenetBoxes, box_hits, footprint_extent
from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.frenet import to_frenet
from planner.goal import Goal, GoalReason
from planner.goal_region import (
    MAX_PATH_SAMPLES,
    PATH_STEP,
    RegionOnReference,
    along_path,
    distance_to,
    inside,
    on_reference,
)
from planner.lane import lane_bounds
from planner.problem import Options, PlanningProblem, target_speed
from planner.reference import FloatArray, ReferenceLine
from planner.speed import SpeedAim, profile_grid
from planner.trajectory import Path
from solvers.lateral_qp import LateralWeights

#: a stop inside aims to keep up with its comfortable approach this far behind it [s]
APPROACH_SLACK = 0.2
#: a stop point inside this share of the comfortable stopping distance away is taken still [-]
STOP_TOLERANCE = 0.9


@dataclass(frozen=True)
class GoalBlock:
    """Why a goal cannot be met, known before planning: a typed reason and a message."""

    reason: GoalReason
    message: str


@dataclass(frozen=True)
class GoalSetup:
    """What a plan knows of its goal before planning.

    Attributes:
        goal: the request's goal.
        region: its region on the reference (None without a position).
        ego_s: the ego's centre's arc length on the reference [m].
        ego_inside: whether the ego's centre is inside the region now.
        cap: the highest speed the speed profile may drive for the goal [m/s].
        v_target: the cruise target [m/s].
        block: why the goal cannot be met, when that is known already (else None).
        stops_inside: whether the goal asks to stop inside its region: a position and a speed range from
            0 whose top is below :attr:`planner.config.GoalConfig.stop_speed` (a range from 0 reaching
            higher allows standing inside, e.g. waiting for the window, but does not ask for it).
    """

    goal: Goal
    region: RegionOnReference | None
    ego_s: float
    ego_inside: bool
    cap: float
    v_target: float
    block: GoalBlock | None
    stops_inside: bool = False


def reach(v0: float, accel: float, cap: float, t: float) -> float:
    """The farthest [m] a vehicle at ``v0`` [m/s] drives in ``t`` [s] accelerating at ``accel`` [m/s²] up to
    ``cap`` [m/s] (or keeping ``v0`` where that is faster)."""
    if t <= 0.0:
        return 0.0
    top = max(cap, v0)
    rise = (top - v0) / accel if accel > 0.0 else math.inf
    if t <= rise:
        return v0 * t + 0.5 * accel * t * t
    return v0 * rise + 0.5 * accel * rise * rise + top * (t - rise)


def goal_setup(
    ref: ReferenceLine, problem: PlanningProblem, config: PlannerConfig = DEFAULT_CONFIG
) -> GoalSetup | None:
    """The :class:`GoalSetup` of ``problem``'s goal, None without one."""
    goal = problem.goal
    if goal is None:
        return None
    vehicle, options, ego = problem.vehicle, problem.options, problem.ego
    target = target_speed(problem)
    limit = options.speed_limit
    allowed = max(target, min(vehicle.max_speed, target if limit is None else limit))
    hurries = goal.time is not None and goal.position is not None
    fast = goal.speed is not None and goal.speed[0] > target
    cap = allowed if hurries or fast else target
    v_target = target
    if goal.speed is not None:
        v_min, v_max = goal.speed
        if goal.position is None:
            v_target = min(max(target, v_min), v_max, cap)
        elif v_min > target:
            v_target = min(v_min, cap)
    ego_s = float(ref_s(ref, ego.x, ego.y))
    region, ego_in = None, False
    if goal.position is not None:
        s_end = ref.length - config.stop_gap - 0.5 * vehicle.length  # the centre stops there
        region = on_reference(
            ref, goal.position, problem.lane, vehicle, options.lateral_margin, s_end, config.goal
        )
        ego_in = bool(inside(goal.position, ego.x, ego.y))
    block = _block(goal, region, ego_s, ego_in, problem, allowed)
    speeds = goal.speed
    stops = (
        goal.position is not None
        and speeds is not None
        and speeds[0] <= 0.0
        and speeds[1] < config.goal.stop_speed
    )
    return GoalSetup(goal, region, ego_s, ego_in, cap, v_target, block, stops)


def ref_s(ref: ReferenceLine, x: float, y: float) -> float:
    """The arc length [m] of the point ``(x, y)`` on the reference (TransF-κ)."""
    return float(to_frenet(ref, [[x, y]]).s[0])


def _block(
    goal: Goal,
    region: RegionOnReference | None,
    ego_s: float,
    ego_inside: bool,
    problem: PlanningProblem,
    allowed: float,
) -> GoalBlock | None:
    """What makes ``goal`` unreachable before anything is planned (``allowed``: the highest speed it may
    use [m/s]), or None."""
    ego, vehicle = problem.ego, problem.vehicle
    if goal.time is not None and goal.time[1] < 0.0:
        return GoalBlock(GoalReason.WINDOW_ENDED, f"the time window ended {-goal.time[1]:.1f} s ago")
    if goal.speed is not None and goal.speed[0] > allowed:
        return GoalBlock(
            GoalReason.SPEED_RANGE,
            f"the speed range starts at {goal.speed[0]:.1f} m/s, above the speed limit {allowed:.1f} m/s",
        )
    if goal.position is None or region is None or ego_inside:
        return None
    if not region.reachable:
        if region.s_max < ego_s:
            return GoalBlock(GoalReason.BEHIND, f"the region lies {ego_s - region.s_max:.1f} m behind")
        return GoalBlock(
            GoalReason.OFF_ROAD, "no point of the region is within the lane for the vehicle's centre"
        )
    if region.s_out < ego_s:
        return GoalBlock(GoalReason.BEHIND, f"the region lies {ego_s - region.s_out:.1f} m behind")
    if goal.time is not None:
        gap = distance_to(goal.position, ego.x, ego.y)
        far = reach(ego.speed, vehicle.max_acceleration, allowed, goal.time[1])
        if gap > far:
            return GoalBlock(
                GoalReason.TOO_FAR,
                f"the region is {gap:.1f} m away; by t = {goal.time[1]:.1f} s the vehicle drives at most "
                f"{far:.1f} m (up to {max(allowed, ego.speed):.1f} m/s at {vehicle.max_acceleration:g} m/s²)",
            )
    return None


def candidate_options(setup: GoalSetup | None, options: Options) -> Options:
    """The options the candidates are generated with: a goal's cap above the target as the speed their
    length plans for (:func:`planner.candidates.path_length`)."""
    if setup is None or options.target_speed is None or setup.cap <= options.target_speed:
        return options
    return replace(options, target_speed=setup.cap)


def _region_rows(setup: GoalSetup | None) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """The region's knots and offsets ``(s, d_low, d_high)`` [m] where the centre can be inside, or None."""
    if setup is None or setup.region is None or not setup.region.reachable or setup.block is not None:
        return None
    region = setup.region
    on = region.on_lane
    return region.s[on], region.d_low[on], region.d_high[on]


def candidate_cost(
    setup: GoalSetup | None,
    cands: CandidateSet,
    problem: PlanningProblem,
    config: PlannerConfig = DEFAULT_CONFIG,
) -> FloatArray | None:
    """Each candidate's goal term (see the module docstring), shape (N,), or None without a region to aim
    at."""
    rows = _region_rows(setup)
    if rows is None:
        return None
    knots, low, high = rows
    s, d = cands.s, cands.d
    centre = s + problem.vehicle.rear_offset
    within = cands.valid & (centre >= knots[0]) & (centre <= knots[-1])
    miss = np.maximum(np.maximum(np.interp(centre, knots, low) - d, d - np.interp(centre, knots, high)), 0.0)
    total = np.where(within, miss**2, 0.0).sum(axis=1)
    return np.asarray(config.goal.candidate_weight * total / np.maximum(within.sum(axis=1), 1))


def toward_region(
    setup: GoalSetup | None,
    ref: ReferenceLine,
    s: FloatArray,
    d: FloatArray,
    boxes: FrenetBoxes,
    problem: PlanningProblem,
    config: PlannerConfig = DEFAULT_CONFIG,
) -> FloatArray:
    """The chosen candidate's offsets ``d`` [m] at ``s`` [m] moved into the region (see the module
    docstring), within the candidates' lane bounds; ``d`` itself where there is nothing to move or the move
    would meet a static obstacle."""
    rows = _region_rows(setup)
    if rows is None:
        return d
    knots, low, high = rows
    vehicle = problem.vehicle
    centre = s + vehicle.rear_offset
    within = (centre >= knots[0]) & (centre <= knots[-1])
    if not within.any():
        return d
    lo, hi = np.interp(centre, knots, low), np.interp(centre, knots, high)
    margin = np.minimum(config.goal.margin, 0.25 * (hi - lo))
    aim = np.clip(d, lo + margin, hi - margin)
    weights = LateralWeights()
    aim = np.where(aim == d, d, aim * (weights.ref + weights.offset) / weights.ref)
    shift = np.where(within, aim - d, 0.0)
    if not np.any(np.abs(shift) > 1e-9):
        return d
    first, last = np.flatnonzero(within)[[0, -1]]
    band = lane_bounds(
        ref, problem.lane, s, half_width=0.5 * vehicle.width, margin=problem.options.lateral_margin
    )
    extent = footprint_extent(np.zeros_like(s), vehicle, config.obstacle_margin)
    blend = max(2.0 * vehicle.length, 1.5 * problem.ego.speed)
    # A static obstacle on the blend (a parked car just before the region): blend in beyond the last knot
    # where the candidate's own footprint meets its box grown by the move, no earlier.
    close = box_hits(boxes, s, d + np.where(s < s[first], shift[first], 0.0), extent)[:first]
    if close.any():
        blend = min(blend, float(s[first] - s[int(np.flatnonzero(close)[-1])]))
    if blend <= 0.0:
        return d
    before = _smoothstep((s - (s[first] - blend)) / blend) * shift[first]
    shift = np.where(within, shift, np.where(s < s[first], before, 0.0))
    moved = np.clip(d + shift, band.lower, np.maximum(band.upper, band.lower))
    heading = np.arctan(np.gradient(moved, s)) if s.size > 1 else np.zeros_like(s)
    hits = box_hits(boxes, s, moved, footprint_extent(heading, vehicle, config.obstacle_margin))
    if np.any((hits & (np.abs(moved - d) > 1e-9))[: last + 1]):  # (only where moved: not the candidate's)
        return d
    return np.asarray(moved)


def _smoothstep(u: FloatArray) -> FloatArray:
    """``3u² − 2u³`` on ``u`` clipped to [0, 1]."""
    u = np.clip(u, 0.0, 1.0)
    return np.asarray(u * u * (3.0 - 2.0 * u))


def stop_distance(v: float, a: float, decel: float, jerk: float) -> float:
    """Distance [m] to a standstill from ``v`` [m/s] at acceleration ``a`` [m/s²], braking at ``decel``
    [m/s²] reached at ``jerk`` [m/s³] (:func:`slow_distance`)."""
    return slow_distance(v, a, 0.0, decel, jerk)


def slow_distance(v: float, a: float, v_to: float, decel: float, jerk: float) -> float:
    """Distance [m] to slow from ``v`` [m/s] at acceleration ``a`` [m/s²] to ``v_to`` [m/s], braking at
    ``decel`` [m/s²] reached at ``jerk`` [m/s³]; 0 when ``v`` is not above it.

    A positive ``a`` is released first (``v·a/jerk`` metres on, ``v′ = v + a²/(2 jerk)``), then
    ``((v′ + c)² − (v_to + c)²)/(2 decel)`` with ``c = decel²/(2 jerk)`` (the speed profile's own braking
    margin, :mod:`solvers.speed_cost`). Braking already (``a ≤ 0``): the ramp from ``a`` to ``−b``, ``b =
    max(decel, −a)``, then ``−b``, exactly (the ramp alone where it slows enough).
    """
    if a > 0.0:
        release = a / jerk
        v_top = v + 0.5 * a * release
        if v_top <= v_to:
            return 0.0
        c = decel * decel / (2.0 * jerk)
        return v * release + ((v_top + c) ** 2 - (v_to + c) ** 2) / (2.0 * decel)
    if v <= v_to:
        return 0.0
    b = max(decel, -a)
    ramp = (a + b) / jerk
    v_ramp = v + a * ramp - 0.5 * jerk * ramp * ramp
    if v_ramp <= v_to:  # slows enough on the ramp: v + a τ − j τ²/2 = v_to
        tau = (a + math.sqrt(a * a + 2.0 * jerk * (v - v_to))) / jerk
        return v * tau + 0.5 * a * tau * tau - jerk * tau**3 / 6.0
    s_ramp = v * ramp + 0.5 * a * ramp * ramp - jerk * ramp**3 / 6.0
    return s_ramp + (v_ramp * v_ramp - v_to * v_to) / (2.0 * b)


def speed_aim(
    setup: GoalSetup | None, path: Path, problem: PlanningProblem, config: PlannerConfig = DEFAULT_CONFIG
) -> SpeedAim | None:
    """The goal's terms for the speed profile along ``path`` (see the module docstring), or None without
    a goal."""
    if setup is None:
        return None
    plain = SpeedAim(setup.cap, setup.v_target)
    goal, region = setup.goal, setup.region
    if goal.position is None or region is None or setup.block is not None:
        return plain
    stretch = along_path(path, goal.position, problem.vehicle, (region.s_min, region.s_max))
    if stretch is None:
        return plain
    sigma_in, sigma_out = stretch
    margin = min(config.goal.margin, 0.25 * (sigma_out - sigma_in))
    enter = sigma_in + margin if sigma_in > 0.0 else 0.0  # already inside: no margin to enter by
    leave = sigma_out - margin
    ego, vehicle, speed = problem.ego, problem.vehicle, config.speed
    comfort = config.goal.deceleration_share * vehicle.max_deceleration
    steps, dt = profile_grid(problem.options, speed)
    t = np.arange(steps + 1, dtype=np.float64) * dt
    stop, ceiling, lower = math.inf, None, None
    if setup.stops_inside:
        soft = stop_distance(ego.speed, ego.acceleration, comfort, speed.jerk)
        hard = stop_distance(ego.speed, ego.acceleration, vehicle.max_deceleration, speed.emergency_jerk)
        # fixed in space, not a braking distance from the vehicle (which would creep on from cycle to
        # cycle): the region's entry, middle and exit on the reference, the first one it can stop at
        assert region.reachable  # for mypy: a path that runs inside runs over the lane's band
        s_in, s_out = region.s_in, region.s_out
        inset = min(config.goal.margin, 0.25 * (s_out - s_in))
        marks = np.array([s_in + inset, 0.5 * (s_in + s_out), s_out - inset]) - vehicle.rear_offset
        points = np.clip(np.interp(marks, path.s, path.sigma), enter, leave)
        if np.any(points >= STOP_TOLERANCE * soft):  # (a little harder than comfortable is fine)
            stop = float(points[np.argmax(points >= STOP_TOLERANCE * soft)])
        elif hard <= sigma_out:  # the exit (or, already close to it, as soon as it can: inside still)
            stop = min(max(leave, hard), sigma_out)
        if soft <= stop < math.inf:
            curve = (stop + 0.5 * margin, 0.0, comfort, speed.jerk)
            ceiling = braking_curve(path.sigma, *curve)
            sigma, clock = approach(stop, problem, setup.v_target, curve)
            slack = APPROACH_SLACK
            when, near = float(clock[-1]) + slack, stop
            if when > t[-1]:  # beyond the horizon: where the approach is at its end
                near = float(np.interp(t[-1] - slack, clock, sigma))
            if near > 0.0:  # (standing at the stop already: nothing to ask)
                lower = _at_knot(t, min(when, t[-1]), near, -math.inf, late=False)
    upper = None
    if goal.time is not None:
        t_min, t_max = goal.time
        spare = min(config.goal.window_margin, 0.25 * (t_max - t_min))
        t_min, t_max = t_min + spare, t_max - spare
        ahead = enter - config.goal.beyond_horizon_share * setup.cap * max(t_max - t[-1], 0.0)
        by_window = _at_knot(t, t_max, ahead, -math.inf, late=True)
        if by_window is not None:  # (None: the window asks nothing within the horizon; a stop's own stays)
            lower = by_window if lower is None else np.maximum(lower, by_window)
        if not setup.stops_inside and t_min > 0.0:
            upper = _at_knot(t, t_min, leave, math.inf, late=False)
        if lower is not None and upper is not None and np.any(lower > upper):  # a window within one step
            upper = np.maximum(upper, lower)
    if goal.speed is not None and not setup.stops_inside and goal.speed[1] < setup.cap:
        v_max = goal.speed[1]
        start = max(enter, slow_distance(ego.speed, ego.acceleration, v_max, comfort, speed.jerk))
        if start <= leave:
            slowed = braking_curve(path.sigma, start, v_max, comfort, speed.jerk)
            ceiling = np.where(path.sigma <= sigma_out, slowed, np.inf)
    return SpeedAim(setup.cap, setup.v_target, stop, lower, upper, ceiling)


def approach(
    end: float, problem: PlanningProblem, cruise: float, curve: tuple[float, float, float, float]
) -> tuple[FloatArray, FloatArray]:
    """``(σ, t)``: when [s] a vehicle gets to each ``σ`` [m] of a fine grid up to ``end`` [m] from the ego's
    speed, accelerating at half ``max_acceleration`` up to ``cruise`` [m/s], below :func:`braking_curve` of
    ``curve``: ``∫ dσ / v`` (trapezoids, ``v`` at least 0.1 m/s)."""
    sigma = np.linspace(0.0, max(end, 0.0), int(np.clip(end / PATH_STEP, 2, MAX_PATH_SAMPLES)))
    v0, accel = problem.ego.speed, 0.5 * problem.vehicle.max_acceleration
    speed = np.sqrt(v0 * v0 + 2.0 * accel * sigma)
    speed = np.minimum(np.minimum(speed, max(cruise, 0.1)), braking_curve(sigma, *curve))
    pace = 1.0 / np.maximum(speed, 0.1)
    return sigma, np.concatenate(([0.0], np.cumsum(0.5 * (pace[1:] + pace[:-1]) * np.diff(sigma))))


def braking_curve(sigma: FloatArray, at: float, v_at: float, decel: float, jerk: float) -> FloatArray:
    """The highest speed [m/s] at ``sigma`` [m] from which braking at ``decel`` [m/s²], reached at ``jerk``
    [m/s³], gets down to ``v_at`` [m/s] by ``at`` [m]: ``√((v_at + c)² + 2 decel (at − σ)) − c``, ``c =
    decel²/(2 jerk)``; ``v_at`` from ``at`` on (0 for a stop: standstill)."""
    c = decel * decel / (2.0 * jerk)
    ahead = np.maximum(at - sigma, 0.0)
    return np.asarray(np.sqrt((v_at + c) ** 2 + 2.0 * decel * ahead) - c)


def _at_knot(t: FloatArray, when: float, value: float, free: float, *, late: bool) -> FloatArray | None:
    """A bound ``value`` [m] on the knot of ``t`` [s] that ``when`` [s] asks for — the last one at or
    before it (``late``: not late by then), else the first one at or after it, the last knot where
    ``when`` lies beyond the horizon — and ``free`` elsewhere; None when that is the start (not imposed) or
    when a bound not to be late asks for no progress at all."""
    if late and value <= 0.0:
        return None
    if when > t[-1]:
        k = t.size - 1
    elif late:
        k = int(np.searchsorted(t, when + 1e-9, side="right")) - 1
    else:
        k = int(np.searchsorted(t, when - 1e-9, side="left"))
    if k <= 0:
        return None
    bound = np.full(t.shape, free)
    bound[k] = value
    return bound
