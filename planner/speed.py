"""The speed stage: a jerk-limited speed profile along the lateral stage's path.

On ``steps`` knots ``t_k = k·Δt`` over the horizon (``Δt = horizon / steps``, ``steps`` at most the
configured number and about ``horizon / options.dt``) the SQP (:mod:`solvers.speed`) finds the arc
length ``σ(t)`` [m] along the path within:

* the speed limit ``v ≤ v_lim(σ)`` [m/s]: the cap (:func:`speed_cap`: ``options.speed_limit``, else the
  target speed), the vehicle's, the curvature's ``√(limit_margin · a_lat,max / |κ|)`` (a car's body:
  :func:`speed_limit`) and a car's steering rate's, each the lowest within ``limit_reach`` either side;
* a stop ``σ ≤ σ_stop``: ``stop_gap`` before the last free knot of a blocked road, or the front
  ``stop_gap`` before the reference's end, or the path's end;
* the space-time bounds of the moving obstacles (:mod:`planner.st_bounds`); crossing traffic the fastest
  profile within the limits can pass in front of with the follower headway to spare is passed so, a
  headway ahead of it (:func:`pass_first`), where the profile found keeps that and every other bound
  (else, or where the trajectory breaks a check, it is yielded to as every obstacle ahead);
* acceleration within the vehicle's limits and ``|jerk| ≤ jerk`` [m/s³] (``emergency_jerk`` before a
  block, when the comfortable jerk needs more than ``slack`` to keep the limits, or when braking later
  and harder keeps ahead of a follower bound by more than ``slack`` within the same limits).

The cost pulls the speed towards the target (:func:`target_speed`), which may lie below the cap: then only
what the cost weighs against the target — the follower bound, or a caller's bound such as a goal's —
raises the profile above it, never above the cap (the SQP's ``v_target`` and ``limit_v``).

A profile that still ends past a stop or a space-time bound by more than ``position_slack`` [m] is
replaced by full braking (:func:`braking`): it keeps every ``σ(t)`` as small as the limits allow. The
profile the trajectory samples says what it is (:class:`ProfileKind`); the SQP's own answer is kept
for the diagnostics.

A request's goal adds its terms (:class:`SpeedAim`, decided by :func:`planner.goal_plan.speed_aim`): a
higher cap than the target for the limit, another cruise target, a stop inside its region, the soft
bounds of its time window and the top of its speed range over its region. Without one, nothing changes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from scipy.ndimage import minimum_filter1d

from planner.config import DEFAULT_CONFIG, PlannerConfig, SpeedConfig
from planner.ego import EgoFrenet
from planner.kinematics import curve_speed
from planner.lateral import LateralPlan
from planner.problem import Options, PlanningProblem, Vehicle, speed_cap, target_speed
from planner.reference import FloatArray, ReferenceLine
from planner.st_bounds import (
    Crossing,
    SpaceTimeBounds,
    crossings,
    followers,
    moving_obstacles,
    space_time_bounds,
)
from planner.thread_solvers import Spare
from planner.timing import time_for
from planner.trajectory import Path, Trajectory, body_trajectory, sample
from solvers.speed_problem import SpeedProblem, SpeedResult, integrate_jerk
from solvers.speed_profiles import braking_profile, cruise_profile, limited_profile
from solvers.speed_sqp import SpeedSolver

#: a speed this far above the path's limit [m/s] counts as within it (rounding)
_LIMIT_TOL = 1e-6


class ProfileKind(StrEnum):
    """Where the speed profile of a trajectory comes from."""

    #: the speed SQP's solution
    OPTIMISED = "optimised"
    #: full braking within the emergency jerk (analytic: no solve)
    BRAKING = "braking"
    #: the acceleration released as fast as the emergency jerk allows, then the speed kept, slowing
    #: only where the path's curvature (or a car's steering rate) demands it (analytic; a brake that
    #: cannot be released before standstill stops instead)
    KEEP_SPEED = "keep_speed"
    #: the fastest within the limits: towards the speed cap as fast as the vehicle's acceleration and
    #: the emergency jerk allow, slowing only where the path's limit demands it (analytic)
    ESCAPE = "escape"


@dataclass(frozen=True)
class Profile:
    """A speed profile: knots ``t`` [s], arc length ``s`` [m], ``v`` [m/s], ``a`` [m/s²] (shape (N + 1,)),
    the jerk of each step ``jerk`` [m/s³] (shape (N,)), and what it is."""

    kind: ProfileKind
    t: FloatArray
    s: FloatArray
    v: FloatArray
    a: FloatArray
    jerk: FloatArray

    @classmethod
    def optimised(cls, result: SpeedResult) -> Profile:
        """The SQP's profile."""
        return cls(ProfileKind.OPTIMISED, result.t, result.s, result.v, result.a, result.jerk)

    def sample(self, path: Path, dt: float, ref: ReferenceLine, vehicle: Vehicle) -> Trajectory:
        """The trajectory along ``path`` (the planned point's) every ``dt`` [s], as the answer gives it
        (:func:`planner.trajectory.body_trajectory`)."""
        point = sample(path, self.t, self.s - self.s[0], self.v, self.a, self.jerk, dt, ref)
        return body_trajectory(ref, vehicle, point)


@dataclass(frozen=True)
class SpeedAim:
    """What a goal asks of the speed profile (:func:`planner.goal_plan.speed_aim`), along the path's arc
    length ``σ`` [m] from its start.

    Attributes:
        cap: the speed the limit allows at most [m/s], in place of the target (at least the target).
        v_target: the speed the profile aims at [m/s].
        stop: a stop ``σ ≤ stop`` (the lower of it and the path's own; ``+inf``: none).
        lower, upper: the soft bounds ``goal_lower``, ``goal_upper`` on ``σ`` at the profile's knots [m]
            (:class:`solvers.speed_problem.SpeedProblem`), or None.
        ceiling: a limit [m/s] at the path's knots the speed limit is lowered to, or None.
    """

    cap: float
    v_target: float
    stop: float = math.inf
    lower: FloatArray | None = None
    upper: FloatArray | None = None
    ceiling: FloatArray | None = None

    def limited(self, limit: FloatArray) -> FloatArray:
        """The speed limit ``limit`` [m/s] at the path's knots, lowered to ``ceiling``."""
        return limit if self.ceiling is None else np.minimum(limit, self.ceiling)


@dataclass(frozen=True)
class SpeedPlan:
    """The speed stage's outcome: the SQP's answer and the profile the trajectory samples (the SQP's,
    or full braking where it ended past a stop or a space-time bound)."""

    solved: SpeedResult
    profile: Profile
    #: the crossing vehicles the profile passes in front of (:func:`pass_first`), by id
    first: tuple[str, ...] = ()


def profile_grid(options: Options, config: SpeedConfig = DEFAULT_CONFIG.speed) -> tuple[int, float]:
    """Steps of the speed profile and their length [s]."""
    steps = int(min(config.steps, max(1, round(options.horizon_time / options.dt))))
    return steps, options.horizon_time / steps


def reach_speed(ref: ReferenceLine, problem: PlanningProblem, start_s: float) -> float | None:
    """How fast the candidates' paths must let the plan drive [m/s]: the speed cap when it lies above
    the target and a vehicle comes from behind (:func:`planner.st_bounds.followers` of the ego at
    ``start_s`` [m]: the follower bound may pull the profile up to the cap); None otherwise (the target
    speed: longer paths only spread the candidates' points and the lateral knots thinner)."""
    cap = speed_cap(problem)
    if cap <= target_speed(problem) or not followers(ref, moving_obstacles(problem), start_s):
        return None
    return cap


def speed_limit(
    path: Path, problem: PlanningProblem, config: PlannerConfig = DEFAULT_CONFIG, cap: float | None = None
) -> FloatArray:
    """The speed profile's limit along ``path`` [m/s] at its knots: ``cap`` (default :func:`speed_cap`),
    within the curvature's and, for a car with a steering-rate limit, the steering rate's.

    The curvature's: ``v² |κ| √(1 + (l_r κ)²) ≤ limit_margin · a_lat,max``, the lateral acceleration of the
    body's centre (:func:`planner.kinematics.lateral_acceleration`; ``v² |κ|`` for the point model). The
    steering rate's: ``|dδ/dt| ≤ steering_rate_share · max_steering_rate``
    (:func:`planner.kinematics.steering_rate_speed`).
    """
    curve = curve_speed(
        path.sigma, path.curvature, problem.vehicle, config.limit_margin, config.speed.steering_rate_share
    )
    limit = np.minimum(speed_cap(problem) if cap is None else cap, curve)
    # The lowest limit within limit_reach either side: the profile is checked only at its knots.
    step = float(path.sigma[-1] / max(path.sigma.shape[0] - 1, 1))
    size = 2 * max(1, int(np.ceil(config.speed.limit_reach / max(step, 1e-6)))) + 1
    return np.asarray(minimum_filter1d(limit, size=size, mode="nearest"))


def _speed_problem(
    path: Path,
    problem: PlanningProblem,
    steps: int,
    dt: float,
    jerk_max: float,
    limit_v: FloatArray,
    v_target: float,
    s_stop: float = math.inf,
    s_upper: FloatArray | None = None,
    s_lower: FloatArray | None = None,
    aim: SpeedAim | None = None,
) -> SpeedProblem:
    """The speed problem along ``path`` from the ego's speed and acceleration (that within the vehicle's
    limits, :func:`initial_acceleration`), with the speed limit ``limit_v`` [m/s] at the path's knots,
    the target ``v_target`` [m/s] and the bounds on ``σ`` [m] (see :class:`solvers.speed.SpeedProblem`),
    a goal's from ``aim``."""
    v = problem.vehicle
    return SpeedProblem(
        dt=dt,
        steps=steps,
        v0=max(problem.ego.speed, 0.0),
        a0=initial_acceleration(problem),
        limit_s=path.sigma,
        limit_v=limit_v,
        v_target=v_target,
        a_min=-v.max_deceleration,
        a_max=v.max_acceleration,
        jerk_max=jerk_max,
        s_stop=s_stop,
        s_upper=s_upper,
        s_lower=s_lower,
        goal_lower=None if aim is None else aim.lower,
        goal_upper=None if aim is None else aim.upper,
    )


def initial_acceleration(
    problem: PlanningProblem, jerk: float = DEFAULT_CONFIG.speed.emergency_jerk
) -> float:
    """The acceleration [m/s²] the profiles start from: the ego's, within the vehicle's limits, and no
    harder braking than releasing it at ``jerk`` [m/s³] (the emergency jerk) brings to a stop exactly,
    ``−√(2·jerk·v₀)``. A vehicle braking harder comes to a stop before the release ends and its brakes
    hold it there (a standing one measured braking: its acceleration moves nothing); a profile started
    from the measured value would roll backwards through the release."""
    vehicle, ego = problem.vehicle, problem.ego
    measured = float(np.clip(ego.acceleration, -vehicle.max_deceleration, vehicle.max_acceleration))
    return max(measured, -math.sqrt(2.0 * jerk * max(ego.speed, 0.0)))


def stop_position(
    ref: ReferenceLine, path: Path, lateral: LateralPlan, stop_gap: float, front_extent: float
) -> float:
    """``σ_stop`` [m] along ``path``: ``stop_gap`` before the last free knot when the road is blocked,
    else the front (``front_extent`` [m] ahead of the planned point) ``stop_gap`` before the
    reference's end, and never past the path's end (it reaches a braking distance beyond the horizon)."""
    last_free = lateral.stop_s(stop_gap)
    if last_free is not None:  # the path may run on past the block: ≥ 3 knots
        return max(float(np.interp(last_free, path.s, path.sigma, left=0.0)), 0.0)
    front = front_extent + stop_gap
    if ref.length - front < path.s[-1]:
        return max(float(np.interp(ref.length - front, path.s, path.sigma)), 0.0)
    return path.length


def _limit(path: Path, problem: PlanningProblem, config: PlannerConfig, aim: SpeedAim | None) -> FloatArray:
    """The speed profile's limit along ``path`` [m/s] at its knots (:func:`speed_limit`), a goal's
    ``aim`` within it."""
    if aim is None:
        return speed_limit(path, problem, config)
    # a vehicle from behind may pull the profile up to the speed cap whatever the goal's own cap
    return aim.limited(speed_limit(path, problem, config, max(aim.cap, speed_cap(problem))))


def _solve(
    solver: SpeedSolver,
    path: Path,
    problem: PlanningProblem,
    s_stop: float,
    bounds: SpaceTimeBounds,
    steps: int,
    dt: float,
    jerk_max: float,
    config: PlannerConfig,
    aim: SpeedAim | None,
    limit: FloatArray,
) -> SpeedResult:
    """The profile within ``limit`` [m/s] (:func:`_limit`) and ``bounds``, ``jerk_max`` [m/s³]."""
    v_target = target_speed(problem) if aim is None else aim.v_target
    sp = _speed_problem(
        path,
        problem,
        steps,
        dt,
        jerk_max,
        limit,
        v_target,
        s_stop=s_stop,
        s_upper=bounds.upper,
        s_lower=bounds.lower,
        aim=aim,
    )
    return solver.solve(sp)


def speed_stage(
    solver: SpeedSolver,
    ref: ReferenceLine,
    lateral: LateralPlan,
    path: Path,
    problem: PlanningProblem,
    start: EgoFrenet,
    config: PlannerConfig = DEFAULT_CONFIG,
    aim: SpeedAim | None = None,
    passing: Collection[str] = (),
    go_first: bool = True,
    time_left: Callable[[], float | None] = lambda: None,
    spare: Spare | None = None,
) -> SpeedPlan:
    """The speed profile along the lateral stage's ``path`` (see the module docstring), with a goal's
    ``aim``; the moving obstacles ``passing`` overtakes are not followed
    (:func:`planner.st_bounds.space_time_bounds`). With ``go_first``, crossing traffic the vehicle can
    pass in front of (:func:`pass_first`) is passed so, where the profile manages it within the limits
    (else it yields to it, as to every other obstacle ahead). The second solve with the emergency jerk
    runs only while ``time_left`` [s] (None: no budget) leaves what the first took
    (:func:`planner.timing.time_for`): past the budget the plan falls back to braking anyway. With a
    ``spare`` thread it starts there beside the first where the first is likely to need it
    (:func:`_braking_breaks`, or a vehicle from behind catching up with the ego keeping its speed:
    :mod:`planner.thread_solvers`)."""
    cfg = config.speed
    steps, dt = profile_grid(problem.options, cfg)
    s_stop = stop_position(ref, path, lateral, config.stop_gap, problem.vehicle.front_extent)
    if aim is not None:
        s_stop = min(s_stop, aim.stop)
    t = np.arange(steps + 1, dtype=np.float64) * dt
    jerk = cfg.emergency_jerk if lateral.stops else cfg.jerk
    limit = _limit(path, problem, config, aim)
    if go_first and not lateral.stops:
        first = pass_first(ref, path, problem, t, start, s_stop, config, passing)
        if first:
            ids = tuple(c.id for c in first)
            ahead = space_time_bounds(ref, path, problem, t, start.s, config, {*passing, *ids})
            lower = np.max([c.before for c in first], axis=0)
            if ahead.lower is not None:
                lower = np.maximum(lower, ahead.lower)
            bounds = SpaceTimeBounds(ahead.upper, lower)
            speed = _solve(solver, path, problem, s_stop, bounds, steps, dt, jerk, config, aim, limit)
            if _in_front(speed, np.max([c.least for c in first], axis=0), cfg):
                return SpeedPlan(speed, Profile.optimised(speed), ids)
    bounds = space_time_bounds(ref, path, problem, t, start.s, config, passing)

    def emergency(with_solver: SpeedSolver) -> SpeedResult:
        """The profile with the emergency jerk, solved by ``with_solver``."""
        jerk_max = cfg.emergency_jerk
        return _solve(with_solver, path, problem, s_stop, bounds, steps, dt, jerk_max, config, aim, limit)

    # Started beside the first only where likely needed: the vehicle from behind catches up with the ego
    # keeping its speed (on the closed loops of bench/cycles.py: started 183 times, needed 127 of the 151
    # times the re-solve runs; started with every follower bound, 299 of 450 were not needed, and their
    # work, sharing the interpreter, slowed the plan's thread), or braking with this jerk breaks the limit
    # or a leader's bound (28 of the 30 re-solves for a broken speed or position bound, 7 not needed;
    # both tests: 215 started, 154 used)
    started = None
    if spare is not None and jerk < cfg.emergency_jerk:
        caught = bounds.lower is not None and bool(np.any(problem.ego.speed * t < bounds.lower))
        if caught or _braking_breaks(path, problem, t, jerk, limit, bounds.upper, cfg.slack):
            started = spare.submit(emergency, spare.speed)
    speed = _solve(solver, path, problem, s_stop, bounds, steps, dt, jerk, config, aim, limit)
    # a second solve only while the budget leaves what the first took (past it, the plan falls back)
    again = jerk < cfg.emergency_jerk and time_for(time_left, speed.info.solve_time_ms)
    if again and max(speed.speed_violation, speed.position_violation) > cfg.slack:
        # The comfortable jerk cannot slow down in time (a curve or an obstacle close ahead): safety
        # before comfort, brake as hard as the emergency jerk allows. (Not for a follower bound alone:
        # more jerk hardly speeds up sooner.)
        speed = emergency(solver) if started is None else started.result()
    elif again and speed.follower_violation > cfg.slack:
        # Behind the follower bound with the comfortable jerk: braking later, as hard as the emergency
        # jerk allows, keeps ahead of it longer where a curve or a leader ahead makes the speed drop.
        harder = emergency(solver) if started is None else started.result()
        if (
            harder.info.usable
            and harder.follower_violation < speed.follower_violation - cfg.slack
            and max(harder.speed_violation, harder.position_violation)
            <= max(speed.speed_violation, speed.position_violation, cfg.slack)
        ):
            speed = harder
    elif started is not None:
        started.cancel()  # not needed (where it has begun, its work is spent)
    profile = Profile.optimised(speed)
    if speed.info.usable and speed.position_violation > cfg.position_slack:
        # Past a stop or a space-time bound (the solver's limits are soft): full braking keeps every
        # s(t) as small as the limits allow, so it is the answer here (no creeping up to a block).
        profile = braking(path, problem, steps, dt, cfg)
    return SpeedPlan(speed, profile)


def _braking_breaks(
    path: Path,
    problem: PlanningProblem,
    t: FloatArray,
    jerk: float,
    limit: FloatArray,
    upper: FloatArray | None,
    slack: float,
) -> bool:
    """Whether full braking within ``jerk`` [m/s³] from the ego's state breaks the speed ``limit`` [m/s]
    (at the path's knots) or passes ``upper`` [m] (a bound on ``σ`` at the knot times ``t`` [s]; None:
    none) by more than ``slack`` somewhere. A profile with that jerk then breaks one too: past ``upper``
    always (braking keeps ``σ`` least at every time), above the limit nearly always (another profile comes
    to the bend sooner, and faster). Which solves to start early is all it decides."""
    v0, a0 = max(problem.ego.speed, 0.0), max(initial_acceleration(problem), 0.0)
    # braking never gets faster than v0 + a0²/(2 jerk), nor farther than the acceleration held
    fast = v0 + a0**2 / (2.0 * jerk) > float(np.min(limit)) + slack
    far = upper is not None and bool(np.any(v0 * t + 0.5 * a0 * t**2 > upper + slack))
    if not (fast or far):
        return False
    stop = braking(path, problem, t.size - 1, float(t[1] - t[0]), jerk=jerk)
    over = bool(np.any(stop.v > np.interp(stop.s, path.sigma, limit) + slack))
    return over or (upper is not None and bool(np.any(stop.s > upper + slack)))


def pass_first(
    ref: ReferenceLine,
    path: Path,
    problem: PlanningProblem,
    t: FloatArray,
    start: EgoFrenet,
    s_stop: float,
    config: PlannerConfig = DEFAULT_CONFIG,
    passing: Collection[str] = (),
) -> list[Crossing]:
    """The crossing vehicles (:func:`planner.st_bounds.crossings`) the vehicle may pass in front of along
    ``path`` at the knot times ``t`` [s]: those whose ``least`` (the follower headway ahead of them) the
    fastest profile within the limits (:func:`escape`: towards the speed cap, slowing where the path's
    limit demands it) keeps at every knot, short of the stop ``s_stop`` [m]. Passing in front is then
    never more than the vehicle can do; the speed stage still has to find a profile that keeps it."""
    found = crossings(ref, path, problem, t, start.s, config, passing)
    if not found:
        return []
    fastest = escape(path, problem, t.size - 1, float(t[1] - t[0]), config).s
    out: list[Crossing] = []
    for crossing in found:
        busy = crossing.before > -np.inf
        need = crossing.least[busy]
        if not np.all(np.isfinite(crossing.before[busy])) or float(np.max(crossing.before[busy])) > s_stop:
            continue  # on the path up to its end, or past a stop: no passing in front of it
        if np.all(fastest[busy] >= need):
            out.append(crossing)
    return out


def _in_front(speed: SpeedResult, least: FloatArray, config: SpeedConfig) -> bool:
    """Whether a profile passing in front of crossing traffic does so: usable, keeping ``least`` [m] (the
    follower headway ahead of it) and the limit within ``slack``, the stops and the bounds ahead within
    ``position_slack`` (else it yields; :func:`speed_stage`)."""
    short = float(np.max(least[1:] - speed.s[1:]))
    kept = max(short, speed.speed_violation) <= config.slack
    return speed.info.usable and kept and speed.position_violation <= config.position_slack


def braking(
    path: Path,
    problem: PlanningProblem,
    steps: int,
    dt: float,
    config: SpeedConfig = DEFAULT_CONFIG.speed,
    jerk: float | None = None,
) -> Profile:
    """Full braking within the emergency jerk (or ``jerk`` [m/s³]) along ``path`` (the fallback's speed
    profile). Analytic: nothing is solved."""
    jerk_max = config.emergency_jerk if jerk is None else jerk
    sp = _speed_problem(path, problem, steps, dt, jerk_max, np.zeros_like(path.sigma), 0.0)
    return _analytic(ProfileKind.BRAKING, sp, braking_profile(sp))


def keep_speed(
    path: Path, problem: PlanningProblem, steps: int, dt: float, config: PlannerConfig = DEFAULT_CONFIG
) -> Profile:
    """The acceleration released within the emergency jerk and the speed kept along ``path`` (the
    fallback's alternative when braking is hit from behind), within the path's limit below the vehicle's
    max speed (:func:`speed_limit`): where keeping the speed would break it, the speed after the release
    (at most the max speed: an ego above it drives at it rather than swinging about it) is driven within
    it (:func:`solvers.speed_profiles.limited_profile`). Analytic."""
    limit = speed_limit(path, problem, config, cap=problem.vehicle.max_speed)
    sp = _speed_problem(path, problem, steps, dt, config.speed.emergency_jerk, limit, 0.0)
    jerk = cruise_profile(sp)
    s, v, _ = integrate_jerk(dt, 0.0, sp.v0, sp.a0, jerk)
    if np.any(v > np.interp(s, sp.limit_s, sp.limit_v) + _LIMIT_TOL):
        jerk = limited_profile(sp, min(float(v[-1]), problem.vehicle.max_speed))
    return _analytic(ProfileKind.KEEP_SPEED, sp, jerk)


def escape(
    path: Path, problem: PlanningProblem, steps: int, dt: float, config: PlannerConfig = DEFAULT_CONFIG
) -> Profile:
    """The fastest profile along ``path`` within the limits: towards the speed cap (:func:`speed_cap`; the
    ego's speed where that is faster: it does not slow down for the cap) as fast as the vehicle's
    acceleration and the emergency jerk allow, within the path's limit (:func:`speed_limit`;
    :func:`solvers.speed_profiles.limited_profile`). How far ahead of a vehicle from behind the limits let
    the vehicle get (the fallback's last alternative to braking into it). Analytic."""
    cap = max(speed_cap(problem), min(problem.ego.speed, problem.vehicle.max_speed))
    limit = speed_limit(path, problem, config, cap=cap)
    sp = _speed_problem(path, problem, steps, dt, config.speed.emergency_jerk, limit, cap)
    return _analytic(ProfileKind.ESCAPE, sp, limited_profile(sp, cap))


def _analytic(kind: ProfileKind, sp: SpeedProblem, jerk: FloatArray) -> Profile:
    """The profile of the jerks ``jerk`` from ``sp``'s initial state on its grid."""
    s, vel, a = integrate_jerk(sp.dt, 0.0, sp.v0, sp.a0, jerk)
    return Profile(kind, sp.t, s, vel, a, jerk)
