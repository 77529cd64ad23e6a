"""The planning problem as plain frozen dataclasses over numpy arrays (no pydantic here).

The HTTP layer (`app/`) validates a request and converts it into a :class:`PlanningProblem`; the
planner never sees JSON. Units: metres [m], seconds [s], radians [rad], metres per second [m/s].
A trajectory point is the vehicle's geometric centre; ``heading`` is counter-clockwise from +x.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from planner.reference import FloatArray

Generator = Literal["naive", "transf_kappa"]


@dataclass(frozen=True)
class PolygonObstacle:
    """A static obstacle given by its outline, shape (k, 2) [m], k ≥ 3."""

    id: str
    polygon: FloatArray


@dataclass(frozen=True)
class CircleObstacle:
    """A static disc: centre (2,) [m] and radius [m]."""

    id: str
    center: FloatArray
    radius: float


@dataclass(frozen=True)
class DynamicObstacle:
    """A moving box ``length × width`` [m] centred at each predicted state.

    ``prediction`` has columns ``t [s], x [m], y [m], heading [rad]``, shape (k, 4), ``t`` increasing.
    """

    id: str
    length: float
    width: float
    prediction: FloatArray


Obstacle = PolygonObstacle | CircleObstacle | DynamicObstacle


@dataclass(frozen=True)
class Lane:
    """Lane bounds: width to the left and right of the reference [m]; scalar or one per input point."""

    left_width: float | FloatArray
    right_width: float | FloatArray


@dataclass(frozen=True)
class Ego:
    """The vehicle's current state: centre position [m], heading [rad], speed [m/s], acceleration
    [m/s²] and, if known, path curvature [1/m]."""

    x: float
    y: float
    heading: float
    speed: float = 0.0
    acceleration: float = 0.0
    curvature: float | None = None


@dataclass(frozen=True)
class Vehicle:
    """Vehicle footprint [m] and limits: speed [m/s], accelerations [m/s²], curvature [1/m]."""

    length: float = 4.5
    width: float = 1.8
    max_speed: float = 20.0
    max_acceleration: float = 2.5
    max_deceleration: float = 6.0
    max_lateral_acceleration: float = 3.0
    max_curvature: float = 0.2


@dataclass(frozen=True)
class Options:
    """Planning options.

    Attributes:
        horizon_time: planning horizon [s].
        dt: trajectory sampling step [s].
        target_speed: desired speed [m/s]; ``None`` means the vehicle's max speed.
        num_candidates: candidate lateral profiles to generate.
        num_points: points per candidate.
        generator: ``naive`` (Algorithm 4) or ``transf_kappa`` (Algorithm 5).
        seed: seed of the candidates' random end offsets and lengths.
        return_candidates: include the candidates in the answer.
        lateral_margin: clearance kept from the lane edges and obstacles [m].
        min_path_length: shortest path the candidates cover [m].
        time_budget_ms: wall-clock budget of one plan [ms]; a stage that ends past it makes the answer
            a braking ``fallback`` saying so. ``None``: no budget.
    """

    horizon_time: float = 8.0
    dt: float = 0.1
    target_speed: float | None = None
    num_candidates: int = 32
    num_points: int = 100
    generator: Generator = "transf_kappa"
    seed: int = 0
    return_candidates: bool = False
    lateral_margin: float = 0.2
    min_path_length: float = 20.0
    time_budget_ms: float | None = None


@dataclass(frozen=True)
class PlanningProblem:
    """Everything one plan needs: reference polyline (n, 2) [m] in driving order, lane, obstacles,
    ego state, vehicle and options."""

    reference_line: FloatArray
    lane: Lane
    ego: Ego
    obstacles: tuple[Obstacle, ...] = ()
    vehicle: Vehicle = field(default_factory=Vehicle)
    options: Options = field(default_factory=Options)

    def __post_init__(self) -> None:
        object.__setattr__(self, "reference_line", np.asarray(self.reference_line, dtype=float))
