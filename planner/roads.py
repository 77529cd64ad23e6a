"""Analytic roads: centre lines with exactly known geometry, for the demo, figures, tests and benches.

Each function returns a polyline (n, 2) [m] in driving order, sampled every ``step`` [m] of arc length.
"""

from __future__ import annotations

import numpy as np
from scipy.special import fresnel

from planner.problem import CircleObstacle, Ego, Lane, Options, PlanningProblem, Vehicle
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
