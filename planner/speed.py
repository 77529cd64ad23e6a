"""The speed stage: a jerk-limited speed profile along the lateral stage's path.

On ``steps`` knots ``t_k = k·Δt`` over the horizon (``Δt = horizon / steps``, ``steps`` at most the
configured number and about ``horizon / options.dt``) the SQP (:mod:`solvers.speed`) finds the arc
length ``σ(t)`` [m] along the path within:

* the speed limit ``v ≤ v_lim(σ)`` [m/s]: the target speed (a cap), the vehicle's, the curvature's
  ``√(limit_margin · a_lat,max / |κ|)`` (a car's body: :func:`speed_limit`) and a car's steering rate's,
  each the lowest within ``limit_reach`` either side;
* a stop ``σ ≤ σ_stop``: ``stop_gap`` before the last free knot of a blocked road, or the front
  ``stop_gap`` before the reference's end, or the path's end;
* the space-time bounds of the moving obstacles (:mod:`planner.st_bounds`);
* acceleration within the vehicle's limits and ``|jerk| ≤ jerk`` [m/s³] (``emergency_jerk`` before a
  block, or when the comfortable jerk needs more than ``slack`` to keep the limits).

A profile that still ends past a stop or a space-time bound by more than ``position_slack`` [m] is
replaced by full braking (:func:`braking`): it keeps every ``σ(t)`` as small as the limits allow. The
profile the trajectory samples says what it is (:class:`ProfileKind`); the SQP's own answer is kept
for the diagnostics.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from scipy.ndimage import minimum_filter1d

from planner.config import DEFAULT_CONFIG, PlannerConfig, SpeedConfig
from planner.ego import EgoFrenet
from planner.kinematics import steering_rate_speed
from planner.lateral import LateralPlan
from planner.problem import Options, PlanningProblem, Vehicle
from planner.reference import FloatArray, ReferenceLine
from planner.st_bounds import SpaceTimeBounds, space_time_bounds
from planner.trajectory import Path, Trajectory, body_trajectory, sample
from solvers.speed_problem import SpeedProblem, SpeedResult, integrate_jerk
from solvers.speed_profiles import braking_profile, cruise_profile
from solvers.speed_sqp import SpeedSolver


class ProfileKind(StrEnum):
    """Where the speed profile of a trajectory comes from."""

    #: the speed SQP's solution
    OPTIMISED = "optimised"
    #: full braking within the emergency jerk (analytic: no solve)
    BRAKING = "braking"
    #: the acceleration released as fast as the emergency jerk allows, then the speed kept (analytic;
    #: a brake that cannot be released before standstill stops instead)
    KEEP_SPEED = "keep_speed"


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
class SpeedPlan:
    """The speed stage's outcome: the SQP's answer and the profile the trajectory samples (the SQP's,
    or full braking where it ended past a stop or a space-time bound)."""

    solved: SpeedResult
    profile: Profile


def profile_grid(options: Options, config: SpeedConfig = DEFAULT_CONFIG.speed) -> tuple[int, float]:
    """Steps of the speed profile and their length [s]."""
    steps = int(min(config.steps, max(1, round(options.horizon_time / options.dt))))
    return steps, options.horizon_time / steps


def target_speed(problem: PlanningProblem) -> float:
    """The speed the profile aims at [m/s]: the options' target within the vehicle's limit."""
    v_max = problem.vehicle.max_speed
    target = problem.options.target_speed
    return v_max if target is None else min(target, v_max)


def speed_limit(path: Path, problem: PlanningProblem, config: PlannerConfig = DEFAULT_CONFIG) -> FloatArray:
    """The speed profile's limit along ``path`` [m/s] at its knots: the target speed, within the vehicle's,
    the curvature's and, for a car with a steering-rate limit, the steering rate's (the target is a
    cap: a faster vehicle behind does not raise it).

    The curvature's: ``v² |κ| √(1 + (l_r κ)²) ≤ limit_margin · a_lat,max``, the lateral acceleration of the
    body's centre (:func:`planner.kinematics.lateral_acceleration`; ``v² |κ|`` for the point model). The
    steering rate's: ``|dδ/dt| ≤ steering_rate_share · max_steering_rate``
    (:func:`planner.kinematics.steering_rate_speed`).
    """
    vehicle = problem.vehicle
    a_lat = vehicle.max_lateral_acceleration
    curvature = np.maximum(np.abs(path.curvature), 1e-9)
    if vehicle.rear_offset:
        curvature = curvature * np.sqrt(1.0 + (vehicle.rear_offset * path.curvature) ** 2)
    with np.errstate(divide="ignore"):
        lateral = np.sqrt(config.limit_margin * a_lat / curvature)
    limit = np.minimum(target_speed(problem), lateral)
    steering = steering_rate_speed(path.sigma, path.curvature, vehicle, config.speed.steering_rate_share)
    if steering is not None:
        limit = np.minimum(limit, steering)
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
) -> SpeedProblem:
    """The speed problem along ``path`` from the ego's speed and acceleration (that within the vehicle's
    limits), with the speed limit ``limit_v`` [m/s] at the path's knots, the target ``v_target`` [m/s]
    and the bounds on ``σ`` [m] (see :class:`solvers.speed.SpeedProblem`)."""
    v = problem.vehicle
    return SpeedProblem(
        dt=dt,
        steps=steps,
        v0=max(problem.ego.speed, 0.0),
        a0=float(np.clip(problem.ego.acceleration, -v.max_deceleration, v.max_acceleration)),
        limit_s=path.sigma,
        limit_v=limit_v,
        v_target=v_target,
        a_min=-v.max_deceleration,
        a_max=v.max_acceleration,
        jerk_max=jerk_max,
        s_stop=s_stop,
        s_upper=s_upper,
        s_lower=s_lower,
    )


def stop_position(
    ref: ReferenceLine, path: Path, lateral: LateralPlan, stop_gap: float, front_extent: float
) -> float:
    """``σ_stop`` [m] along ``path``: ``stop_gap`` before the last free knot when the road is blocked,
    else the front (``front_extent`` [m] ahead of the planned point) ``stop_gap`` before the
    reference's end, and never past the path's end (it reaches a braking distance beyond the horizon)."""
    if lateral.blocked is not None:  # the path may run on past the block: ≥ 3 knots
        last_free = lateral.bounds.s[max(lateral.blocked - 1, 0)] - stop_gap
        return max(float(np.interp(last_free, path.s, path.sigma, left=0.0)), 0.0)
    front = front_extent + stop_gap
    if ref.length - front < path.s[-1]:
        return max(float(np.interp(ref.length - front, path.s, path.sigma)), 0.0)
    return path.length


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
) -> SpeedResult:
    limit = speed_limit(path, problem, config)
    sp = _speed_problem(
        path,
        problem,
        steps,
        dt,
        jerk_max,
        limit,
        target_speed(problem),
        s_stop=s_stop,
        s_upper=bounds.upper,
        s_lower=bounds.lower,
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
    passing: Collection[str] = (),
) -> SpeedPlan:
    """The speed profile along the lateral stage's ``path`` (see the module docstring); the moving
    obstacles ``passing`` overtakes are not followed (:func:`planner.st_bounds.space_time_bounds`)."""
    cfg = config.speed
    steps, dt = profile_grid(problem.options, cfg)
    s_stop = stop_position(ref, path, lateral, config.stop_gap, problem.vehicle.front_extent)
    t = np.arange(steps + 1, dtype=np.float64) * dt
    bounds = space_time_bounds(ref, path, problem, t, start.s, config, passing)
    jerk = cfg.emergency_jerk if lateral.stops else cfg.jerk
    speed = _solve(solver, path, problem, s_stop, bounds, steps, dt, jerk, config)
    if max(speed.speed_violation, speed.position_violation) > cfg.slack and jerk < cfg.emergency_jerk:
        # The comfortable jerk cannot slow down in time (a curve or an obstacle close ahead): safety
        # before comfort, brake as hard as the emergency jerk allows. (Not for a follower bound alone:
        # more jerk hardly speeds up sooner.)
        speed = _solve(solver, path, problem, s_stop, bounds, steps, dt, cfg.emergency_jerk, config)
    profile = Profile.optimised(speed)
    if speed.info.usable and speed.position_violation > cfg.position_slack:
        # Past a stop or a space-time bound (the solver's limits are soft): full braking keeps every
        # s(t) as small as the limits allow, so it is the answer here (no creeping up to a block).
        profile = braking(path, problem, steps, dt, cfg)
    return SpeedPlan(speed, profile)


def braking(
    path: Path,
    problem: PlanningProblem,
    steps: int,
    dt: float,
    config: SpeedConfig = DEFAULT_CONFIG.speed,
    keep_speed: bool = False,
) -> Profile:
    """Full braking within the emergency jerk along ``path`` (the fallback's speed profile); with
    ``keep_speed``, the acceleration released as fast and the speed kept instead (the fallback's
    alternative when braking is hit from behind). Analytic: nothing is solved."""
    sp = _speed_problem(path, problem, steps, dt, config.emergency_jerk, np.zeros_like(path.sigma), 0.0)
    jerk = cruise_profile(sp) if keep_speed else braking_profile(sp)
    s, vel, a = integrate_jerk(dt, 0.0, sp.v0, sp.a0, jerk)
    t = np.arange(steps + 1, dtype=np.float64) * dt
    kind = ProfileKind.KEEP_SPEED if keep_speed else ProfileKind.BRAKING
    return Profile(kind, t, s, vel, a, jerk)
