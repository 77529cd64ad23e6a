"""The lateral corridor where the road ends or turns tightly: regressions from two CommonRoad runs.

* ITA_CarpiCentro-9_6_T-1: the lane's right width falls to 0 at the reference's last point (the converter
  gives the end point that width). The bounds of the last knots jumped there, beyond where the vehicle
  ever stops, and the lateral QP bent the whole tail of the path into an S to meet them: the front
  corner left the lane before the stop (90 fallbacks, timeout short of the goal).
* DEU_Lohmar-26_1_T-1: a right turn tighter than the vehicle's smallest radius in a lane that flares
  out at the corner. The bounds measured the corners' bulge against the lane's width at the centre, not
  where the corners are, and the margin to the lane's edges left no corridor: the QP was infeasible
  from the first cycle, and its unfinished iterates broke the curvature limit in the turn (49
  fallbacks, then a collision from behind while stopped in the turn).
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scenario_roads import Road, arc_piece, straight_piece

from planner.io import problem_from_json
from planner.pipeline import plan
from planner.problem import Ego, Lane, Options, PlanningProblem, Vehicle
from planner.sim import shift_obstacle
from solvers.result import SolverStatus

DATA = Path(__file__).resolve().parents[1] / "data" / "commonroad"
CONVERGED = (SolverStatus.SOLVED, SolverStatus.SOLVED_INACCURATE)
#: the vehicle of the CommonRoad requests
CAR = Vehicle(
    length=4.508,
    width=1.61,
    max_speed=40.0,
    max_acceleration=3.0,
    max_deceleration=8.0,
    max_lateral_acceleration=4.0,
    max_curvature=0.3,
)


def _recorded(name: str, t: float, ego: Ego) -> PlanningProblem:
    """The request of a recorded scene at time ``t`` [s] with ``ego`` (as the closed loop sends it)."""
    problem = problem_from_json(json.loads((DATA / f"{name}.json").read_text()))
    return replace(problem, ego=ego, obstacles=tuple(shift_obstacle(ob, t) for ob in problem.obstacles))


@pytest.mark.parametrize("curved", [False, True], ids=["straight", "left-curve"])
@pytest.mark.parametrize("d0", [0.0, 0.3])
def test_a_lane_closing_at_the_references_end_does_not_bend_the_path_before_it(
    curved: bool, d0: float
) -> None:
    road = Road([arc_piece(18.0, 0.9), straight_piece(25.0)] if curved else [straight_piece(60.0)])
    points = road.polyline(1.0)
    right = np.full(points.shape[0], 1.75)
    right[-1] = 0.0  # the lane's right edge closes in over the last metre
    length = float(np.sum(np.hypot(*np.diff(points, axis=0).T)))
    x, y, heading = road.pose(length - 35.0)
    problem = PlanningProblem(
        reference_line=points,
        lane=Lane(left_width=np.full(points.shape[0], 1.75), right_width=right),
        ego=Ego(x=x - d0 * np.sin(heading), y=y + d0 * np.cos(heading), heading=heading, speed=4.65),
        vehicle=CAR,
        options=Options(horizon_time=8.0, dt=0.1, target_speed=5.0),
    )
    result = plan(problem)
    assert result.status == "ok", result.message
    assert result.diagnostics.lateral_qp.status in CONVERGED


def test_carpi_near_the_references_end_plans_a_path_in_the_lane() -> None:
    # the closed loop's state at 16.0 s, its first fallback ("footprint leaves the lane")
    ego = Ego(
        x=-406.1666984876076,
        y=-98.84071853924524,
        heading=-1.6749305775443724,
        speed=4.6518732858494465,
        acceleration=-0.1301502005580535,
        curvature=0.045125949637990916,
    )
    result = plan(_recorded("ITA_CarpiCentro-9_6_T-1", 16.0, ego))
    assert result.status == "ok", result.message
    assert result.diagnostics.lateral_qp.status in CONVERGED


def test_lohmar_tight_right_turn_has_a_feasible_corridor() -> None:
    # the first cycle: the lateral QP was infeasible (4000 iterations, an unfinished iterate returned)
    problem = problem_from_json(json.loads((DATA / "DEU_Lohmar-26_1_T-1.json").read_text()))
    result = plan(problem)
    assert result.status == "ok", result.message
    assert result.diagnostics.lateral_qp.status in CONVERGED, result.diagnostics.lateral_qp


def test_lohmar_entering_the_turn_keeps_the_curvature_limit() -> None:
    # the closed loop's state at 3.9 s: "curvature 0.309 1/m above max_curvature"
    ego = Ego(
        x=-454.2472923719862,
        y=-426.4789411565085,
        heading=1.639105612310302,
        speed=3.985992304213016,
        acceleration=-4.9818012875256334,
        curvature=0.07391958262517646,
    )
    problem = _recorded("DEU_Lohmar-26_1_T-1", 3.9, ego)
    result = plan(problem)
    assert result.status == "ok", result.message
    moving = result.trajectory.v > 0.05
    assert np.abs(result.trajectory.curvature[moving]).max() <= problem.vehicle.max_curvature * (1 + 1e-3)
