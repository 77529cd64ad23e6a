"""The fallback: when a stage fails or its trajectory breaks a check, brake safely along the best path known.

Full braking within the emergency jerk is tried along the optimised path, then along the chosen
candidate, then at the ego's offset from the reference; the first braking trajectory that passes every
check is taken. Where the least severe of them still breaks the vehicle's limits (a start faster than
any bend ahead allows) or its numbers disagree (it does not start at the ego's steering angle, say),
braking straight on along the ego's heading (:func:`straight_on`: steering back to straight as fast as
the vehicle may, then no curvature) is tried too. Else the least severe is taken (:func:`severity`).

Braking into moving traffic is never better than driving on: when a braking trajectory is hit from behind
(a :attr:`~planner.validation.ViolationKind.HITS_MOVING_OBSTACLE` of one of
:func:`planner.st_bounds.followers`), or the least severe one by any other moving obstacle (crossing or
oncoming traffic that reaches where the ego stands), three more profiles along the best path are
weighed, in this order: the planned one (which may have slowed for a leader's headway only), keeping the
speed (:func:`planner.speed.keep_speed`: slowing only where the path's curvature demands it) and getting
away as fast as the limits allow (:func:`planner.speed.escape`, up to the speed cap). The first that
passes every check is taken; else the least severe, on a tie the one whose first hit of anything but a
vehicle from behind comes later and then slower (so braking before driving into a leader), then the one
a vehicle from behind hits later, and then the earlier (so these before braking: a harder stop gives the
follower less time). A follower that still hits the answer is named with the reason it is not escaped
(:func:`planner.follower.unescaped`).

Severity (:func:`severity`) ranks what a trajectory breaks, never its messages: first numbers that
disagree (:data:`~planner.validation.CONSISTENCY`: no motion at all), then the vehicle's own limits
(:data:`~planner.validation.LIMITS`: a trajectory outside them cannot be driven as planned, so it is no
option while one within them exists), then hits of anything but a vehicle from behind, then hits from
behind, then the other checks (the lane, the road's end).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from dataclasses import dataclass

import numpy as np
from shapely.geometry.base import BaseGeometry

from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.ego import EgoFrenet
from planner.follower import UnescapedFollower, first_hit_from_behind, from_behind, unescaped
from planner.frenet import to_frenet
from planner.lateral import held_offset, knots
from planner.problem import PlanningProblem
from planner.reference import FloatArray, ReferenceLine
from planner.speed import Profile, ProfileKind, braking, escape, keep_speed, profile_grid
from planner.st_bounds import followers, moving_obstacles
from planner.trajectory import Path, Trajectory
from planner.validation import (
    CONSISTENCY,
    HITS,
    LIMITS,
    Violation,
    ViolationKind,
    trajectory_violations,
)
from solvers.speed_problem import SpeedResult


@dataclass(frozen=True)
class Fallback:
    """The fallback's answer: the trajectory, what it still breaks, why (the message), its profile and
    the vehicle from behind that still hits it, if any (with the reason)."""

    trajectory: Trajectory
    violations: tuple[Violation, ...]
    message: str
    profile: ProfileKind
    follower: UnescapedFollower | None = None


@dataclass(frozen=True)
class _Option:
    """One profile along one path, weighed: what it is called in the message, the profile, the
    trajectory and what it breaks."""

    label: str
    profile: Profile
    trajectory: Trajectory
    violations: list[Violation]


def severity(bad: Collection[Violation], rear: Collection[str]) -> tuple[int, int, int, int, int, int]:
    """How bad a trajectory's violations ``bad`` are, to compare fallbacks (smaller is better): first
    whether it does not start at the ego (:attr:`~planner.validation.ViolationKind.START`: not the ego's
    motion at all, where the others' numbers disagree only along it), then numbers that disagree
    (:data:`~planner.validation.CONSISTENCY`), the vehicle's limits broken
    (:data:`~planner.validation.LIMITS`), hits of obstacles other than the vehicles behind (ids
    ``rear``), hits from behind, then the other checks (the lane, the road's end, which do not hit
    anything by themselves)."""
    rear_ids = set(rear)
    elsewhere = int(any(v.kind is ViolationKind.START for v in bad))
    wrong = sum(v.kind in CONSISTENCY for v in bad)
    limits = sum(v.kind in LIMITS for v in bad)
    hits = [v for v in bad if v.kind in HITS]
    behind = sum(from_behind(v, rear_ids) for v in hits)
    return elsewhere, wrong, limits, len(hits) - behind, behind, len(bad) - len(hits) - limits - wrong


def _rank(option: _Option, rear: set[str]) -> tuple[float, ...]:
    """:func:`severity`, then the later the first hit of anything but a vehicle from behind, the better
    (more time to react), and the slower at that hit, the better; then the later a vehicle from behind
    first hits, the better (it is braked into less)."""
    bad, traj = option.violations, option.trajectory
    ahead = [v.t or 0.0 for v in bad if v.kind in HITS and not from_behind(v, rear)]
    t_ahead = min(ahead) if ahead else None
    hit = first_hit_from_behind(bad, rear)
    return (
        *severity(bad, rear),
        -t_ahead if t_ahead is not None else 0.0,
        float(np.interp(t_ahead, traj.t, traj.v)) if t_ahead is not None else 0.0,
        -(hit.t or 0.0) if hit is not None else 0.0,
    )


def _moving_hit(bad: list[Violation]) -> Violation | None:
    """The first of ``bad`` that is a hit of a moving obstacle, if any."""
    return next((v for v in bad if v.kind is ViolationKind.HITS_MOVING_OBSTACLE), None)


def fallback(
    reason: str,
    path: Path,
    candidate: Path,
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    static: list[tuple[str, BaseGeometry]],
    planned: SpeedResult | None = None,
    config: PlannerConfig = DEFAULT_CONFIG,
    borrowing: bool = False,
) -> Fallback:
    """The fallback for ``reason``, along ``path`` (the best path known), the chosen ``candidate`` and
    the ego's offset; ``planned`` is the SQP's profile along ``path``, weighed when braking is hit from
    behind (if it is a solution). ``static`` are the static obstacles' outlines; ``borrowing``: the lane
    decision borrows the road (the checks then keep the footprint in the road, not the lane)."""
    steps, dt = profile_grid(problem.options, config.speed)

    def weigh(label: str, profile: Profile, along: Path) -> _Option:
        traj = profile.sample(along, problem.options.dt, ref, problem.vehicle)
        bad = trajectory_violations(ref, problem, traj, static, borrowing=borrowing)
        return _Option(label, profile, traj, bad)

    hold = held_offset(ref, knots(ref, start, float(candidate.s[-1]), config.lateral), start.d)
    tried: list[_Option] = []
    for option in _distinct(path, candidate, hold):
        tried.append(weigh("braking", braking(option, problem, steps, dt, config.speed), option))
        if not tried[-1].violations:
            return Fallback(tried[-1].trajectory, (), reason, ProfileKind.BRAKING)
    rear = {ob.id for ob in followers(ref, moving_obstacles(problem), start.s)}
    best = min(tried, key=lambda o: severity(o.violations, rear))
    if any(v.kind in LIMITS or v.kind in CONSISTENCY for v in best.violations):
        line = straight_on(ref, problem, config)
        tried.append(weigh("braking", braking(line, problem, steps, dt, config.speed), line))
        if not tried[-1].violations:
            return Fallback(tried[-1].trajectory, (), reason, ProfileKind.BRAKING)
        best = min(tried, key=lambda o: severity(o.violations, rear))
    message = f"{reason}; the braking trajectory still breaks: {best.violations[0]}"
    hit_from_behind = next((h for o in tried if (h := first_hit_from_behind(o.violations, rear))), None)
    # crossing or oncoming traffic: only where it hits the best braking option (weighing costs a check each)
    moving_hit = hit_from_behind or _moving_hit(best.violations)
    if moving_hit is None:
        return Fallback(best.trajectory, tuple(best.violations), message, ProfileKind.BRAKING)

    others: list[tuple[str, Callable[[], Profile]]] = []
    if planned is not None and planned.info.usable:
        solved = planned
        others.append(("the planned profile", lambda: Profile.optimised(solved)))
    others.append(("keeping the speed", lambda: keep_speed(path, problem, steps, dt, config)))
    others.append(("speeding up within the limits", lambda: escape(path, problem, steps, dt, config)))
    weighed: list[_Option] = []
    for label, make in others:
        weighed.append(weigh(label, make(), path))
        if not weighed[-1].violations:
            break
    chosen = min([*weighed, *tried], key=lambda o: _rank(o, rear))
    if chosen.profile.kind is ProfileKind.BRAKING:
        message = f"{reason}; the braking trajectory still breaks: {chosen.violations[0]}"
    else:
        how = "from behind" if hit_from_behind is not None else "by moving traffic"
        message = f"{reason}; braking is hit {how} ({moving_hit}): {chosen.label} instead"
        if chosen.violations:
            message += f", which still breaks: {chosen.violations[0]}"
    follower = None
    if (hit := first_hit_from_behind(chosen.violations, rear)) is not None:
        runaway = next((o for o in weighed if o.profile.kind is ProfileKind.ESCAPE), None)
        if runaway is None:
            runaway = weigh("", escape(path, problem, steps, dt, config), path)
        follower = unescaped(hit, problem, path, runaway.profile, runaway.violations, config)
        message += f"; {follower.obstacle_id} cannot be escaped: {follower.reason.description}"
    return Fallback(chosen.trajectory, tuple(chosen.violations), message, chosen.profile.kind, follower)


def straight_on(ref: ReferenceLine, problem: PlanningProblem, config: PlannerConfig = DEFAULT_CONFIG) -> Path:
    """The path from the ego's planned point (its centre, a car's rear axle) along its heading [rad],
    steering back to straight as fast as it may (:func:`unwound`) and then straight on, long enough to
    brake to a stop from its speed (``v²/(2·a_dec)`` plus a second at that speed for the jerk's ramp; at
    most the horizon at that speed, 1 m at least), at knots ``config.lateral.knot_spacing`` [m] apart or
    wider (at most ``max_knots``); ``s, d`` by TransF-κ."""
    ego, vehicle = problem.ego, problem.vehicle
    v0 = max(ego.speed, 0.0)
    # no longer than the horizon drives at the start's speed (a profile past the end carries on straight)
    length = max(min(v0 * v0 / (2.0 * vehicle.max_deceleration) + v0, v0 * problem.options.horizon_time), 1.0)
    n = int(np.clip(np.ceil(length / config.lateral.knot_spacing) + 1, 2, config.lateral.max_knots))
    # positions integrated on a grid _FINE times finer than the knots (the heading is exact)
    fine: FloatArray = np.linspace(0.0, length, (n - 1) * _FINE + 1)
    curvature, heading = unwound(problem, fine, config)
    step = np.diff(fine)
    # the planned point: a car's rear axle, ``l_r`` behind the centre along the yaw
    x0 = ego.x - vehicle.rear_offset * np.cos(ego.heading)
    y0 = ego.y - vehicle.rear_offset * np.sin(ego.heading)
    cos, sin = np.cos(heading), np.sin(heading)
    x = x0 + np.concatenate(([0.0], np.cumsum(0.5 * (cos[1:] + cos[:-1]) * step)))
    y = y0 + np.concatenate(([0.0], np.cumsum(0.5 * (sin[1:] + sin[:-1]) * step)))
    at = slice(None, None, _FINE)
    frenet = to_frenet(ref, np.column_stack((x[at], y[at])))
    return Path(
        s=frenet.s, d=frenet.d, x=x[at], y=y[at], heading=heading[at], curvature=curvature[at], sigma=fine[at]
    )


#: :func:`straight_on` integrates its positions on a grid this many times finer than its knots
_FINE = 16


def unwound(
    problem: PlanningProblem, sigma: FloatArray, config: PlannerConfig = DEFAULT_CONFIG
) -> tuple[FloatArray, FloatArray]:
    """The curvature [1/m] and heading [rad] at arc lengths ``sigma`` [m] of a path that starts at the ego's
    heading and measured curvature and steers back to straight: for a car whose steering rate is bounded,
    ``κ(σ) = κ₀ − sign(κ₀)·c·min(σ, |κ₀|/c)`` with ``c = share·δ̇_max / (W·v₀)`` [1/m²] (``share`` the speed
    stage's ``steering_rate_share``), so that ``|δ̇| = W·v·|dκ/dσ| / (1 + W²κ²) ≤ share·δ̇_max`` at any speed
    up to ``v₀``: the start's, plus ``a₀²/(2·j)`` for a positive measured acceleration ``a₀`` that braking
    releases at the emergency jerk ``j`` first; the heading ``θ₀ + κ₀·m − sign(κ₀)·c·m²/2`` with
    ``m = min(σ, |κ₀|/c)``.
    Straight from the start (no curvature) for any other vehicle or without a measured curvature: it may
    steer at once."""
    ego, vehicle = problem.ego, problem.vehicle
    kappa0 = ego.curvature if vehicle.is_car and vehicle.max_steering_rate is not None else None
    if not kappa0:
        return np.zeros_like(sigma), np.full_like(sigma, ego.heading)
    assert vehicle.wheelbase is not None and vehicle.max_steering_rate is not None  # a car's, above
    rate = config.speed.steering_rate_share * vehicle.max_steering_rate
    fastest = ego.speed + max(ego.acceleration, 0.0) ** 2 / (2.0 * config.speed.emergency_jerk)
    slope = rate / (vehicle.wheelbase * max(fastest, _SLOWEST))
    m = np.minimum(sigma, abs(kappa0) / slope)
    sign = math.copysign(1.0, kappa0)
    curvature = sign * np.maximum(abs(kappa0) - slope * sigma, 0.0)  # exactly 0 once unwound
    return curvature, ego.heading + kappa0 * m - sign * slope * m * m / 2.0


#: the speed [m/s] :func:`unwound` unwinds at least for (slower: within a few millimetres)
_SLOWEST = 0.1


def _distinct(*paths: Path) -> list[Path]:
    """``paths`` without repeats of the same object (the best path known may be the candidate)."""
    out: list[Path] = []
    for p in paths:
        if not any(p is q for q in out):
            out.append(p)
    return out
