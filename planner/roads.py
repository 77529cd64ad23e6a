"""Analytic roads: centre lines with exactly known geometry, for the demo, figures, tests and benches.

Each function returns a polyline (n, 2) [m] in driving order, sampled every ``step`` [m] of arc length.
"""

from __future__ import annotations

import numpy as np
from scipy.special import fresnel

from planner.problem import (
    CircleObstacle,
    DynamicObstacle,
    Ego,
    Lane,
    Obstacle,
    Options,
    PlanningProblem,
    PolygonObstacle,
    Road,
    Vehicle,
)
from planner.reference import FloatArray


def straight(length: float = 100.0, *, heading: float = 0.0, step: float = 0.5) -> FloatArray:
    """A straight line from the origin with the given heading [rad]."""
    s = np.linspace(0.0, length, int(np.ceil(length / step)) + 1)
    return np.column_stack((s * np.cos(heading), s * np.sin(heading)))


def arc(radius: float, angle: float, *, step: float = 0.5) -> FloatArray:
    """A circular arc from the origin heading +x, turning left (angle > 0) by ``angle`` [rad]."""
    s = np.linspace(0.0, radius * abs(angle), int(np.ceil(radius * abs(angle) / step)) + 1)
    phi = s / radius
    sign = np.sign(angle) or 1.0
    return np.column_stack((radius * np.sin(phi), sign * radius * (1.0 - np.cos(phi))))


def clothoid(length: float, curvature_rate: float, *, step: float = 0.5) -> FloatArray:
    """A clothoid from the origin heading +x with ``κ(s) = curvature_rate·s`` [1/m²]."""
    s = np.linspace(0.0, length, int(np.ceil(length / step)) + 1)
    scale = np.sqrt(np.pi / abs(curvature_rate))
    fs, fc = fresnel(s / scale)
    return np.column_stack((scale * fc, np.sign(curvature_rate) * scale * fs))


def u_turn(radius: float = 6.0, leg: float = 30.0, *, step: float = 0.5) -> FloatArray:
    """A U-turn: a straight leg along +x, a left half-circle of ``radius``, a leg back along −x.

    The arc's centre is at ``(0, radius)``; the arc starts at the origin and ends at ``(0, 2·radius)``.
    """
    a = np.arange(-leg, 0.0, step)
    first = np.column_stack((a, np.zeros_like(a)))
    half = arc(radius, np.pi, step=step)
    b = np.arange(step, leg + 1e-9, step)
    last = np.column_stack((-b, np.full_like(b, 2.0 * radius)))
    return np.vstack((first, half, last))


def demo_problem() -> PlanningProblem:
    """The built-in demo road: the paper's U-turn with a wide inner side and an obstacle at the corner.

    The lane's inner (left) side is wider than the turn's radius, so naive offset candidates fold
    back on themselves in the turn (κ·d ≥ 1) while TransF-κ candidates do not.
    """
    radius = 8.0
    return PlanningProblem(
        reference_line=u_turn(radius=radius, leg=40.0, step=2.0),
        lane=Lane(left_width=radius + 3.0, right_width=3.5),
        ego=Ego(x=-15.0, y=0.0, heading=0.0, speed=5.0, acceleration=0.0),
        obstacles=(CircleObstacle(id="cone", center=np.array([radius + 1.0, radius]), radius=1.0),),
        vehicle=Vehicle(),
        options=Options(horizon_time=8.0, dt=0.1, target_speed=7.0, num_candidates=32),
    )


#: a two-lane road's lane: half of a 3.5 m lane either side of its centre line [m]
HALF_LANE = 1.75


def two_lane_problem(
    reference: FloatArray,
    *,
    speed: float = 10.0,
    obstacles: tuple[Obstacle, ...] = (),
    road: bool = True,
    opposite_left: bool = True,
    vehicle: Vehicle | None = None,
) -> PlanningProblem:
    """A lane of a two-lane road (right-hand traffic: the opposite lane on the left), the ego at the
    reference's start at ``speed`` [m/s] (also the target), with the whole road (``road``) or without."""
    heading = float(np.arctan2(*(reference[1] - reference[0])[::-1]))
    opposite = 3.0 * HALF_LANE if opposite_left else HALF_LANE
    return PlanningProblem(
        reference_line=reference,
        lane=Lane(HALF_LANE, HALF_LANE),
        ego=Ego(x=float(reference[0, 0]), y=float(reference[0, 1]), heading=heading, speed=speed),
        obstacles=obstacles,
        vehicle=Vehicle() if vehicle is None else vehicle,
        options=Options(target_speed=speed),
        road=Road(opposite, HALF_LANE) if road else None,
    )


def box(obstacle_id: str, x: float, y: float, length: float, width: float) -> PolygonObstacle:
    """An axis-aligned ``length × width`` [m] box centred at ``(x, y)`` [m]."""
    hx, hy = 0.5 * length, 0.5 * width
    corners = np.array([[x - hx, y - hy], [x + hx, y - hy], [x + hx, y + hy], [x - hx, y + hy]])
    return PolygonObstacle(obstacle_id, corners)


def driving(
    obstacle_id: str, x: float, y: float, speed: float, *, length: float = 4.5, width: float = 1.8
) -> DynamicObstacle:
    """A vehicle driving along x at ``speed`` [m/s] (negative: towards −x) from ``(x, y)`` [m], predicted
    over 60 s."""
    t = np.linspace(0.0, 60.0, 121)
    heading = 0.0 if speed >= 0.0 else np.pi
    states = np.column_stack((t, x + speed * t, np.full_like(t, y), np.full_like(t, heading)))
    return DynamicObstacle(obstacle_id, length, width, states)


def hairpin(radius: float, *, leg: float = 40.0, step: float = 0.5, right: bool = True) -> FloatArray:
    """A U-turn of ``radius`` [m] between two legs of ``leg`` [m], turning right (or left)."""
    points = u_turn(radius=radius, leg=leg, step=step)
    return points * np.array([1.0, -1.0]) if right else points


def wide_u_turn_problem() -> PlanningProblem:
    """A left U-turn of radius 7 m whose lane a parked car blocks at the turn's start, on a road whose
    inside (the opposite lanes and a shoulder, 8.75 m from the centre line) is wider than the radius,
    for a vehicle that turns at a radius of 3.3 m (CommonRoad's cars' 0.3 1/m): the corridor a borrow
    opens there reaches beyond the centre of curvature."""
    reference = u_turn(radius=7.0, leg=40.0, step=1.0)
    vehicle = Vehicle(max_curvature=0.3)
    parked = (box("parked", 3.0, 0.0, 4.5, 2.0),)
    problem = two_lane_problem(reference, speed=5.0, obstacles=parked, vehicle=vehicle)
    ego = Ego(x=-25.0, y=0.0, heading=0.0, speed=5.0)
    return PlanningProblem(
        problem.reference_line,
        problem.lane,
        ego,
        parked,
        vehicle,
        problem.options,
        road=Road(5.0 * HALF_LANE, HALF_LANE),
    )
