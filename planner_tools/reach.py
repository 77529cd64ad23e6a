"""The earliest time a vehicle can be inside a goal region at all, along the reference within its limits
and the speed limit (:func:`reach`): what tells a goal out of reach by construction from one the planner
misses. ``bench/goal_reach.py`` prints it for the CommonRoad scenes.

The bound follows the reference (the lane's centre) from the ego's speed with the fastest profile the
limits allow — full acceleration ``a_max``, full braking ``a_min`` with no jerk limit, the speed limit
``options.speed_limit`` (else the target) and the vehicle's max speed, the curvature's speed
``√(a_lat,max / (|κ| √(1 + (l_r κ)²)))`` (the lateral acceleration of the body's centre,
:func:`planner.kinematics.lateral_acceleration`, with no margin) and, for a car, the steering rate's
(:func:`planner.kinematics.steering_rate_speed` with its whole ``max_steering_rate``) — a forward–backward
pass of ``v²`` along ``s`` (:func:`fastest_speeds`). It is a lower bound on the arrival of a vehicle that
follows the reference: the planner's own margins (``limit_margin``, ``steering_rate_share``, the jerk) only
make it later. A path that cuts the bends within the lane has less curvature and may be earlier;
:attr:`Reach.lateral_only` drops the steering rate's limit (the bound for a path whose curvature never
changes faster than the vehicle can steer).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from planner.frenet import to_frenet
from planner.goal import GoalCircle
from planner.kinematics import steering_rate_speed
from planner.problem import PlanningProblem
from planner.reference import FloatArray, ReferenceLine, build_reference

__all__ = ["Reach", "arrival", "fastest_speeds", "reach", "region_entry"]


@dataclass(frozen=True)
class Reach:
    """One scene's bound: the region's entry ``ahead`` [m] of the ego's centre along the reference, the
    window ``[t_min, t_max]`` [s], the earliest arrival with every limit (``earliest``) and without the
    steering rate's (``lateral_only``) [s] (``inf``: never, the region lies beyond the reference)."""

    ahead: float
    t_min: float
    t_max: float
    earliest: float
    lateral_only: float


def fastest_speeds(s: FloatArray, limit: FloatArray, v0: float, a_max: float, a_brake: float) -> FloatArray:
    """The fastest speed [m/s] at the arc lengths ``s`` [m] (increasing, from the start) under ``limit``
    [m/s], from ``v0`` [m/s] accelerating at ``a_max`` and braking at ``a_brake`` [m/s²] at most: the
    running minima of ``v² ± 2as`` (a forward–backward pass with no jerk limit; ``v0`` is kept even
    above the limit at ``s[0]``)."""
    v2 = np.minimum.accumulate((limit**2 + 2.0 * a_brake * s)[::-1])[::-1] - 2.0 * a_brake * s
    v2[0] = v0**2
    v2 = np.minimum.accumulate(v2 - 2.0 * a_max * s) + 2.0 * a_max * s
    return np.sqrt(np.maximum(v2, 0.0))


def arrival(s: FloatArray, v: FloatArray, at: float) -> float:
    """The time [s] the profile ``v`` [m/s] at ``s`` [m] reaches ``at`` [m] (``inf`` beyond ``s[-1]`` or
    where it stands before)."""
    if at > s[-1]:
        return math.inf
    mean = 0.5 * (v[1:] + v[:-1])
    with np.errstate(divide="ignore"):
        dt = np.where(mean > 0.0, np.diff(s) / np.maximum(mean, 1e-300), np.inf)
    t = np.concatenate(([0.0], np.cumsum(dt)))
    return float(np.interp(at, s, t))


def region_entry(ref: ReferenceLine, problem: PlanningProblem) -> float | None:
    """The goal region's nearest arc length [m] on the reference (its boundary's, by TransF-κ)."""
    goal = problem.goal
    if goal is None or goal.position is None:
        return None
    position = goal.position
    if isinstance(position, GoalCircle):
        centre = to_frenet(ref, position.center[None, :]).s[0]
        return float(centre) - position.radius
    return float(to_frenet(ref, position.polygon).s.min())


def reach(problem: PlanningProblem) -> Reach | None:
    """The bound of ``problem`` (see the module docstring); None without a region and a window."""
    goal = problem.goal
    ref = build_reference(problem.reference_line)
    entry = region_entry(ref, problem)
    if goal is None or goal.time is None or entry is None:
        return None
    vehicle, options = problem.vehicle, problem.options
    s0 = float(to_frenet(ref, [[problem.ego.x, problem.ego.y]]).s[0])
    ahead = ref.s >= s0
    s, kappa = ref.s[ahead] - s0, ref.kappa[ahead]
    cap = options.speed_limit if options.speed_limit is not None else options.target_speed
    cap = min(vehicle.max_speed, math.inf if cap is None else cap)
    turn = np.maximum(np.abs(kappa) * np.sqrt(1.0 + (vehicle.rear_offset * kappa) ** 2), 1e-12)
    lateral = np.minimum(cap, np.sqrt(vehicle.max_lateral_acceleration / turn))
    steering = steering_rate_speed(s, kappa, vehicle, 1.0)
    limited = lateral if steering is None else np.minimum(lateral, steering)
    a_max, a_brake, v0 = vehicle.max_acceleration, vehicle.max_deceleration, problem.ego.speed
    at = entry - s0
    return Reach(
        ahead=at,
        t_min=goal.time[0],
        t_max=goal.time[1],
        earliest=arrival(s, fastest_speeds(s, limited, v0, a_max, a_brake), at),
        lateral_only=arrival(s, fastest_speeds(s, lateral, v0, a_max, a_brake), at),
    )
