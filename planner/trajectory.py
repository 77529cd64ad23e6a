"""Paths and trajectories: the lateral solution as a Cartesian path, and its sampling in time.

A path is given by knots ``s_i`` [m] on the reference with ``d, d′ = dd/ds, d″``. With ``κ, κ′`` of the
reference and ``Δθ = atan2(d′, 1 − κd)``, the path's heading and curvature are the exact Frenet formulas::

    θ = θ_r + Δθ
    κ_x = ((d″ + (κ′d + κd′)·tan Δθ)·cos²Δθ / (1 − κd) + κ)·cos Δθ / (1 − κd)

Its arc length ``σ`` is measured along the Cartesian knots. A trajectory samples the path at times
``t`` [s] from a speed profile ``σ(t)`` (exact constant-jerk integration between the profile's knots).
The path is the planned point's (the vehicle's centre, a car's rear axle); :func:`body_trajectory` turns
the planned point's trajectory into the answer's (the footprint's centre, a car's yaw and steering).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from planner.frenet import to_cartesian, to_frenet
from planner.kinematics import body_centre, steering_angle
from planner.problem import Vehicle
from planner.reference import FloatArray, ReferenceLine


@dataclass(frozen=True)
class Path:
    """A path at knots: ``s, d`` [m] on the reference, ``x, y`` [m], ``heading`` [rad], ``curvature``
    [1/m] and arc length ``sigma`` [m] from the first knot."""

    s: FloatArray
    d: FloatArray
    x: FloatArray
    y: FloatArray
    heading: FloatArray
    curvature: FloatArray
    sigma: FloatArray

    @property
    def length(self) -> float:
        """Arc length of the path [m]."""
        return float(self.sigma[-1])


def frenet_path(ref: ReferenceLine, s: FloatArray, d: FloatArray, dd: FloatArray, ddd: FloatArray) -> Path:
    """The Cartesian path of a lateral profile (see the module docstring)."""
    xy = to_cartesian(ref, s, d)
    kappa = ref.kappa_at(s)
    dkappa = np.interp(s, ref.s, ref.kappa_slope) if ref.size > 2 else np.zeros_like(s)
    one = 1.0 - kappa * d
    dtheta = np.arctan2(dd, one)
    cos, tan = np.cos(dtheta), np.tan(dtheta)
    curvature = ((ddd + (dkappa * d + kappa * dd) * tan) * cos**2 / one + kappa) * cos / one
    heading = ref.heading_at(s) + dtheta
    step = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    sigma = np.concatenate(([0.0], np.cumsum(step)))
    return Path(s=s, d=d, x=xy[:, 0], y=xy[:, 1], heading=heading, curvature=curvature, sigma=sigma)


def polyline_path(ref: ReferenceLine, s: FloatArray, d: FloatArray) -> Path:
    """A path through Frenet points with heading and curvature from finite differences (for fallbacks
    along a candidate)."""
    xy = to_cartesian(ref, s, d)
    step = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    sigma = np.concatenate(([0.0], np.cumsum(step)))
    if s.shape[0] < 2:
        heading = ref.heading_at(s)
        return Path(
            s=s, d=d, x=xy[:, 0], y=xy[:, 1], heading=heading, curvature=np.zeros_like(s), sigma=sigma
        )
    dx = np.gradient(xy[:, 0], sigma, edge_order=1)
    dy = np.gradient(xy[:, 1], sigma, edge_order=1)
    heading = np.unwrap(np.arctan2(dy, dx))
    curvature = np.gradient(heading, sigma, edge_order=1)
    return Path(s=s, d=d, x=xy[:, 0], y=xy[:, 1], heading=heading, curvature=curvature, sigma=sigma)


@dataclass(frozen=True)
class Trajectory:
    """Trajectory points of the vehicle's centre: ``t`` [s], ``x, y`` [m], ``heading`` [rad],
    ``curvature`` [1/m], ``v`` [m/s], ``a`` [m/s²], and ``s, d`` [m] of the centre on the reference.

    For the point model heading, curvature, speed and acceleration are the centre's path's. For a car
    (:attr:`planner.problem.Vehicle.is_car`) heading is the body's yaw ``ψ``, curvature the rear axle's
    path's ``tan δ / W``, speed and acceleration the rear axle's, and ``steering_angle`` is ``δ`` [rad]
    (None for the point model).
    """

    t: FloatArray
    x: FloatArray
    y: FloatArray
    heading: FloatArray
    curvature: FloatArray
    v: FloatArray
    a: FloatArray
    s: FloatArray
    d: FloatArray
    steering_angle: FloatArray | None = None

    @property
    def size(self) -> int:
        return int(self.t.shape[0])


def _along_heading(path: Path, heading: FloatArray, sig: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``(x, y)`` [m] at arc lengths ``sig`` [m] within the path: cubic Hermite through the knots with the
    unit tangents of ``heading`` [rad] (scaled by each interval's chord over its ``σ``, 1 for chords)."""
    if path.sigma.shape[0] < 2 or path.length <= 0.0:
        return np.interp(sig, path.sigma, path.x), np.interp(sig, path.sigma, path.y)
    k = np.clip(np.searchsorted(path.sigma, sig, side="right") - 1, 0, path.sigma.shape[0] - 2)
    h = path.sigma[k + 1] - path.sigma[k]
    u = np.where(h > 0, (sig - path.sigma[k]) / np.where(h > 0, h, 1.0), 0.0)
    h00, h10 = 2 * u**3 - 3 * u**2 + 1, u**3 - 2 * u**2 + u
    h01, h11 = -2 * u**3 + 3 * u**2, u**3 - u**2
    c0, s0, c1, s1 = np.cos(heading[k]), np.sin(heading[k]), np.cos(heading[k + 1]), np.sin(heading[k + 1])
    x = h00 * path.x[k] + h10 * h * c0 + h01 * path.x[k + 1] + h11 * h * c1
    y = h00 * path.y[k] + h10 * h * s0 + h01 * path.y[k + 1] + h11 * h * s1
    return x, y


def body_trajectory(ref: ReferenceLine, vehicle: Vehicle, point: Trajectory) -> Trajectory:
    """The trajectory as the answer gives it from the planned point's ``point``: the point model's as is;
    for a car (``point`` its rear axle's), the footprint's centre ``l_r`` ahead along the yaw, its
    ``s, d`` by TransF-κ (the rear axle's where ``l_r = 0``) and the steering angle ``atan(W κ)``."""
    if not vehicle.is_car:
        return point
    x, y = body_centre(point.x, point.y, point.heading, vehicle)
    s, d = point.s, point.d
    if vehicle.rear_offset:
        fr = to_frenet(ref, np.column_stack((x, y)))
        s, d = fr.s, fr.d
    return replace(point, x=x, y=y, s=s, d=d, steering_angle=steering_angle(point.curvature, vehicle))


def sample(
    path: Path,
    t_knots: FloatArray,
    sigma0: FloatArray,
    v: FloatArray,
    a: FloatArray,
    jerk: FloatArray,
    dt: float,
    ref: ReferenceLine,
) -> Trajectory:
    """Sample ``path`` every ``dt`` [s] over the profile's span; ``σ(t)`` from the profile's knots
    ``(t, σ, v, a)`` and its constant jerks. ``ref`` gives the Frenet coordinates of points past the
    path's end."""
    horizon = float(t_knots[-1])
    t = np.arange(0.0, horizon + 1e-9, dt)
    k = np.clip(np.searchsorted(t_knots, t, side="right") - 1, 0, jerk.shape[0] - 1)
    tau = t - t_knots[k]
    sig = sigma0[k] + v[k] * tau + a[k] * tau**2 / 2 + jerk[k] * tau**3 / 6
    vel = np.maximum(v[k] + a[k] * tau + jerk[k] * tau**2 / 2, 0.0)
    acc = a[k] + jerk[k] * tau
    sig = np.maximum(np.maximum.accumulate(sig), 0.0)
    # A profile that overruns the path (it could not stop in time) carries on straight along the
    # path's last heading, so that positions stay consistent with the speed and the checks see it.
    over = np.maximum(sig - path.length, 0.0)
    unwrapped = np.unwrap(path.heading)
    heading = np.interp(sig, path.sigma, unwrapped)
    # Between knots the positions follow the path's heading (cubic Hermite in σ), not the chord: a
    # point's heading then agrees with its direction of motion however short the step.
    x, y = _along_heading(path, unwrapped, np.minimum(sig, path.length))
    x, y = x + over * np.cos(heading), y + over * np.sin(heading)
    s = np.interp(sig, path.sigma, path.s)
    d = np.interp(sig, path.sigma, path.d)
    past = over > 0
    if np.any(past):  # where those points are on the reference (TransF-κ), not the path's end shifted
        fr = to_frenet(ref, np.column_stack((x[past], y[past])))
        s[past], d[past] = fr.s, fr.d
    return Trajectory(
        t=t,
        x=x,
        y=y,
        heading=heading,
        curvature=np.where(past, 0.0, np.interp(sig, path.sigma, path.curvature)),
        v=vel,
        a=acc,
        s=s,
        d=d,
    )
