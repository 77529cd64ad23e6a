"""The vehicle's kinematics: where its planned point is, how its body lies and moves, what it steers.

The planner plans one point of the vehicle along a path in the Frenet frame (:class:`planner.problem.
Vehicle`): the footprint's centre for the point model, the rear axle for a car. For a car (a kinematic
single-track vehicle, wheelbase ``W`` [m], rear axle ``l_r`` [m] behind the footprint's centre) with
the rear axle at ``r`` [m] on a path of heading ``ψ`` [rad] (the body's yaw: the rear axle does not
slip) and curvature ``κ`` [1/m]:

* the steering angle is ``δ = atan(W κ)`` [rad] (``κ = tan δ / W``);
* the footprint's centre is ``c = r + l_r (cos ψ, sin ψ)``: it runs on a circle of radius
  ``√(1/κ² + l_r²)`` about the same centre of rotation, at the speed ``v_c = v √(1 + (l_r κ)²)`` for the
  rear axle's speed ``v`` [m/s], its direction of travel ``ψ + atan(l_r κ)`` (its slip angle);
* its lateral (centripetal) acceleration is ``v_c² / R_c = v² |κ| √(1 + (l_r κ)²)`` [m/s²]: that is the
  point whose lateral acceleration the planner bounds, the body's centre standing for its centre of
  mass (the grip of the tyres carries the mass, and every point of the body turns at the same yaw rate
  ``v κ``; a point farther ahead turns on a wider circle);
* the steering rate is ``dδ/dt = W/(1 + W²κ²) · dκ/dt = v · W/(1 + W²κ²) · dκ/dσ`` along the rear axle's
  arc length ``σ`` [m], so ``|dδ/dt| ≤ δ̇_max`` is the speed limit
  ``v ≤ δ̇_max (1 + W²κ²) / (W |dκ/dσ|)``.

For the point model ``l_r = 0`` and every formula here reduces exactly (in floating point) to the
centre's: the answers of a request without a wheelbase do not move.
"""

from __future__ import annotations

import numpy as np

from planner.problem import Ego, Vehicle
from planner.reference import FloatArray


def lateral_acceleration(v: FloatArray, curvature: FloatArray, vehicle: Vehicle) -> FloatArray:
    """``|a_lat|`` [m/s²] of the footprint's centre at the planned point's speed ``v`` [m/s] and path
    curvature ``κ`` [1/m]: ``v² |κ| √(1 + (l_r κ)²)`` (``v² |κ|`` for the point model)."""
    lateral = v**2 * np.abs(curvature)
    offset = vehicle.rear_offset
    if offset == 0.0:
        return np.asarray(lateral)
    return np.asarray(lateral * np.sqrt(1.0 + (offset * curvature) ** 2))


def lateral_curvature(limit: FloatArray | float, vehicle: Vehicle) -> FloatArray:
    """The largest curvature [1/m] of the planned point's path with ``|κ| √(1 + (l_r κ)²) ≤ limit``
    [1/m] (a lateral-acceleration limit divided by the speed squared): the positive root of
    ``l_r² κ⁴ + κ² = limit²``, ``κ = limit · √(2 / (1 + √(1 + 4 l_r² limit²)))``; ``limit`` itself for the
    point model."""
    q = np.asarray(limit, dtype=float)
    offset = vehicle.rear_offset
    if offset == 0.0:
        return q
    with np.errstate(over="ignore"):  # a limit near the largest float: the root is then ~√(limit/l_r)
        root = np.sqrt(1.0 + 4.0 * (offset * q) ** 2)
    return np.asarray(q * np.sqrt(2.0 / (1.0 + root)))


def steering_angle(curvature: FloatArray, vehicle: Vehicle) -> FloatArray:
    """A car's steering angle ``δ = atan(W κ)`` [rad] for its rear axle's path curvature ``κ`` [1/m]."""
    if vehicle.wheelbase is None:
        raise ValueError("the point model has no steering angle")
    return np.asarray(np.arctan(vehicle.wheelbase * np.asarray(curvature, dtype=float)))


def steering_rate_speed(
    sigma: FloatArray, curvature: FloatArray, vehicle: Vehicle, share: float
) -> FloatArray | None:
    """The speed limit [m/s] at a path's knots (arc length ``σ`` [m], curvature ``κ`` [1/m]) that keeps a
    car's steering rate within ``share · max_steering_rate``; None when nothing bounds the rate (the
    point model, or a car without ``max_steering_rate``).

    Per step between knots, ``dκ/dσ = Δκ/Δσ`` and the factor ``1 + W²κ²`` at the smaller ``|κ|`` of its
    ends: ``v ≤ share · δ̇_max (1 + W²κ²) / (W |dκ/dσ|)``; each knot takes the lower limit of its two
    steps (``inf`` where the curvature does not change).
    """
    if vehicle.wheelbase is None or vehicle.max_steering_rate is None:
        return None
    wheelbase = vehicle.wheelbase
    step = np.diff(sigma)
    change = np.abs(np.diff(curvature))
    kappa_sq = np.minimum(curvature[:-1] ** 2, curvature[1:] ** 2)
    rate = share * vehicle.max_steering_rate * (1.0 + wheelbase**2 * kappa_sq)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        per_step = np.where(change > 0.0, rate * np.maximum(step, 0.0) / (wheelbase * change), np.inf)
    per_step = np.where(np.isnan(per_step), 0.0, per_step)
    if per_step.size == 0:
        return np.full(np.shape(sigma), np.inf)
    return np.minimum(np.concatenate(([np.inf], per_step)), np.concatenate((per_step, [np.inf])))


def curve_speed(
    sigma: FloatArray, curvature: FloatArray, vehicle: Vehicle, lateral_share: float, steering_share: float
) -> FloatArray:
    """The speed [m/s] a path (arc length ``σ`` [m], curvature ``κ`` [1/m] at its knots) can be driven at
    without a speed cap: the body's lateral acceleration within ``lateral_share · a_lat,max``
    (``v² |κ| √(1 + (l_r κ)²)``, :func:`lateral_acceleration`; ``v² |κ|`` for the point model) and, for a
    car with a steering-rate limit, the rate within ``steering_share`` of it (:func:`steering_rate_speed`)."""
    bent = np.maximum(np.abs(curvature), 1e-9)
    if vehicle.rear_offset:
        bent = bent * np.sqrt(1.0 + (vehicle.rear_offset * curvature) ** 2)
    with np.errstate(divide="ignore"):
        speed = np.sqrt(lateral_share * vehicle.max_lateral_acceleration / bent)
    steering = steering_rate_speed(sigma, curvature, vehicle, steering_share)
    return np.asarray(speed if steering is None else np.minimum(speed, steering))


def planned_ego(ego: Ego, vehicle: Vehicle) -> Ego:
    """The ego's planned point: the ego itself for the point model; a car's rear axle,
    ``l_r`` behind the centre along the yaw, with the ego's yaw, speed, acceleration and curvature
    (all the rear axle's already)."""
    offset = vehicle.rear_offset
    if offset == 0.0:
        return ego
    return Ego(
        x=ego.x - offset * float(np.cos(ego.heading)),
        y=ego.y - offset * float(np.sin(ego.heading)),
        heading=ego.heading,
        speed=ego.speed,
        acceleration=ego.acceleration,
        curvature=ego.curvature,
    )


def body_centre(
    x: FloatArray, y: FloatArray, heading: FloatArray, vehicle: Vehicle
) -> tuple[FloatArray, FloatArray]:
    """The footprint's centre [m] of the planned points ``(x, y)`` [m] with heading ``ψ`` [rad]:
    ``l_r`` ahead along ``ψ`` (the points themselves for the point model)."""
    offset = vehicle.rear_offset
    if offset == 0.0:
        return x, y
    return x + offset * np.cos(heading), y + offset * np.sin(heading)


def planned_point(
    x: FloatArray, y: FloatArray, heading: FloatArray, vehicle: Vehicle
) -> tuple[FloatArray, FloatArray]:
    """The planned points [m] of footprint centres ``(x, y)`` [m] with heading ``ψ`` [rad]: a car's
    rear axle ``l_r`` behind along ``ψ`` (the centres themselves for the point model)."""
    offset = vehicle.rear_offset
    if offset == 0.0:
        return x, y
    return x - offset * np.cos(heading), y - offset * np.sin(heading)
