"""The start state: the ego in the Frenet frame of the reference, refused when it is not on the road.

:func:`start_state` is what both a plan and the candidates of a request start from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.errors import InvalidInputError
from planner.frenet import to_frenet
from planner.kinematics import lateral_curvature, planned_ego
from planner.problem import Ego, Lane, PlanningProblem
from planner.reference import ReferenceLine

#: farthest the ego may be outside the lane, or before the reference's start [m]
MAX_EGO_OFF_ROAD = 10.0
#: largest heading difference between ego and reference accepted [rad]
MAX_EGO_HEADING_ERROR = np.pi / 2 - 1e-3


@dataclass(frozen=True)
class EgoFrenet:
    """The ego in the Frenet frame: ``s`` [m], ``d`` [m], ``d′ = dd/ds`` [-], ``d″`` [1/m], and its
    heading error to the reference [rad]."""

    s: float
    d: float
    dd: float
    ddd: float
    heading_error: float


def start_state(
    ref: ReferenceLine, problem: PlanningProblem, config: PlannerConfig = DEFAULT_CONFIG
) -> EgoFrenet:
    """The Frenet state on ``ref`` of the ego's planned point (:func:`planner.kinematics.planned_ego`:
    the centre, a car's rear axle), checked to be on the road (:func:`check_ego_on_road`).

    An ego without a curvature is taken to follow the road's, within what it can drive at its speed
    ``v``: ``limit_margin · min(κ_max, κ_lat)`` [1/m] with ``κ_lat`` the curvature at the lateral
    acceleration limit (:func:`planner.kinematics.lateral_curvature` of ``a_lat,max / v²``; ``v`` at
    least ``min_curvature_speed``), the margin the speed profile plans the lateral acceleration with.
    """
    vehicle, ego = problem.vehicle, problem.ego
    speed = max(ego.speed, config.min_curvature_speed)
    lateral = float(lateral_curvature(vehicle.max_lateral_acceleration / speed**2, vehicle))
    reachable = min(vehicle.curvature_limit, lateral)
    start = ego_frenet(ref, planned_ego(ego, vehicle), max_curvature=config.limit_margin * reachable)
    check_ego_on_road(ref, problem.lane, start)
    return start


def ego_frenet(ref: ReferenceLine, ego: Ego, *, max_curvature: float = np.inf) -> EgoFrenet:
    """The ego's Frenet state by TransF-κ.

    With heading error ``Δθ = θ − θ_r(s)``: ``d′ = (1 − κd)·tan Δθ`` and, for the ego's path
    curvature ``κ_x``, ``d″ = −(κ′d + κd′)·tan Δθ + (1 − κd)/cos²Δθ · (κ_x(1 − κd)/cos Δθ − κ)``.
    When ``κ_x`` is not given, the ego is taken to follow the road's curvature at its offset,
    ``κ/(1 − κd)``, limited to ``±max_curvature`` [1/m] (what it can be driving at its speed).
    Nothing is refused here: :func:`check_ego_on_road` judges the position and then the heading.
    """
    fr = to_frenet(ref, [[ego.x, ego.y]])
    s, d = float(fr.s[0]), float(fr.d[0])
    err = float(np.angle(np.exp(1j * (ego.heading - ref.heading_at(s)))))
    kappa = float(ref.kappa_at(s))
    one = 1.0 - kappa * d
    dd = one * np.tan(err)
    if ego.curvature is not None:
        curvature = ego.curvature
    else:
        following = kappa / one if one > 1e-6 else 0.0
        curvature = float(np.clip(following, -max_curvature, max_curvature))
    dk = float(ref.kappa_slope[np.clip(int(s / ref.spacing), 0, ref.size - 1)]) if ref.size > 2 else 0.0
    ddd = -(dk * d + kappa * dd) * np.tan(err) + one / np.cos(err) ** 2 * (
        curvature * one / np.cos(err) - kappa
    )
    return EgoFrenet(s=s, d=d, dd=float(dd), ddd=float(ddd), heading_error=err)


def check_ego_on_road(ref: ReferenceLine, lane: Lane, start: EgoFrenet) -> None:
    """Refuse an ego farther than :data:`MAX_EGO_OFF_ROAD` [m] outside the lane or before the start, then
    one heading more than :data:`MAX_EGO_HEADING_ERROR` [rad] away from the reference's direction."""
    left_w, right_w = lane.widths(ref, start.s)
    left, right = float(left_w), float(right_w)
    outside = max(start.d - left, -right - start.d, 0.0)
    if outside > MAX_EGO_OFF_ROAD:
        raise InvalidInputError(
            f"is {outside:.1f} m outside the lane (at most {MAX_EGO_OFF_ROAD:.0f} m is accepted)", field="ego"
        )
    if start.s < -MAX_EGO_OFF_ROAD:
        raise InvalidInputError(
            f"is {-start.s:.1f} m before the start of the reference line "
            f"(at most {MAX_EGO_OFF_ROAD:.0f} m is accepted)",
            field="ego",
        )
    # the heading only once the position is known to be near the road (far off, the nearest point's
    # direction says nothing)
    if abs(start.heading_error) > MAX_EGO_HEADING_ERROR:
        raise InvalidInputError(
            f"points {np.degrees(start.heading_error):.0f}° away from the reference line's driving direction",
            field="ego.heading",
        )
