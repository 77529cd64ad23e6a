"""The lateral stage: its knots and curvature bound, and the corridor where the road ends or turns
tightly (regressions from CommonRoad runs).

* ITA_CarpiCentro-9_6_T-1: the lane's right width falls to 0 at the reference's last point (the converter
  gives the end point that width). The bounds of the last knots jumped there, beyond where the vehicle
  ever stops, and the lateral QP bent the whole tail of the path into an S to meet them: the front
  corner left the lane before the stop (90 fallbacks, timeout short of the goal).
* DEU_Lohmar-26_1_T-1: a right turn tighter than the vehicle's smallest radius in a lane that flares
  out at the corner. The bounds measured the corners' bulge against the lane's width at the centre, not
  where the corners are, and the margin to the lane's edges left no corridor: the QP was infeasible
  from the first cycle, and its unfinished iterates broke the curvature limit in the turn (49
  fallbacks, then a collision from behind while stopped in the turn).
* USA_US101-6_1_T-1: stopped at a heading error with the road blocked ahead and no room to steer, the
  planner keeps the current offset; that offset ran into a parked car long before the block, the stop
  was only before the block, and every cycle ended in a fallback that hit the car (227 fallbacks).
"""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import shapely
from scenario_roads import Road, arc_piece, straight_piece
from spies import counted_calls

from planner.bounds import LateralBounds, knot_geometry, lateral_bounds
from planner.collision import box_corners, frenet_boxes
from planner.config import DEFAULT_CONFIG, LateralConfig
from planner.ego import EgoFrenet
from planner.lateral import (
    curvature_allowance,
    curvature_rate_allowance,
    jerk_bounds,
    knots,
    lateral_problem,
    reference_jerk,
    solve_lateral,
    straight_allowance,
)
from planner.pipeline import plan
from planner.problem import Ego, Lane, Options, PlanningProblem, PolygonObstacle, Vehicle
from planner.problem import Road as WholeRoad
from planner.reference import build_reference
from planner.roads import demo_problem, straight, u_turn
from planner.timing import StageTimer
from planner.trajectory import frenet_path
from planner.validation import ViolationKind, car_violations
from planner_tools.io import problem_from_json
from planner_tools.sim import shift_obstacle
from solvers.lateral_qp import LateralQPSolver
from solvers.result import SolverStatus

DATA = Path(__file__).resolve().parents[1] / "data" / "commonroad"
ROAD_DATA = DATA.parent / "commonroad-road"
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
#: the same vehicle as CommonRoad's car (vehicle type 2): planned at its rear axle, steering limited
CAR_WITH_AXLE = replace(
    CAR,
    max_curvature=0.7017693147614497,
    wheelbase=2.5789128,
    rear_axle_offset=1.4227170936,
    max_steering_angle=1.066,
    max_steering_rate=0.4,
)


def _recorded(name: str, t: float, ego: Ego) -> PlanningProblem:
    """The request of a recorded scene at time ``t`` [s] with ``ego`` (as the closed loop sends it)."""
    problem = problem_from_json(json.loads((DATA / f"{name}.json").read_text()))
    return replace(problem, ego=ego, obstacles=tuple(shift_obstacle(ob, t) for ob in problem.obstacles))


START = EgoFrenet(s=10.0, d=0.0, dd=0.0, ddd=0.0, heading_error=0.0)


def test_knots_are_the_spacing_apart_up_to_their_most_and_at_least_three() -> None:
    config = DEFAULT_CONFIG.lateral
    line = build_reference(straight(10_100.0, step=50.0))
    at = knots(line, START, 60.0, config)
    assert at[0] == 10.0 and at[-1] == 60.0
    np.testing.assert_allclose(np.diff(at), config.knot_spacing)
    assert knots(line, START, 10.2, config).tolist() == [10.0, 10.5, 11.0]  # at least two spacings on
    far = knots(line, START, 10_000.0, config)
    assert far.size == config.max_knots and far[-1] == 10_000.0
    assert knots(line, START, 60.0, LateralConfig(knot_spacing=20.0)).size == 4
    assert knots(line, START, 10.0, LateralConfig(knot_spacing=20.0)).size == 3


def test_knots_never_chord_across_a_curve() -> None:
    """On a road with a 4 m hairpin, knots for a 2 km path would be 8 m apart: they end where
    ``max_knots`` knots that turn the reference by ``max_knot_turn`` each end."""
    config = DEFAULT_CONFIG.lateral
    hairpin = build_reference(u_turn(radius=4.0, leg=1000.0, step=0.5))
    at = knots(hairpin, START, 2000.0, config)
    assert at.size == config.max_knots
    spacing = float(at[1] - at[0])
    assert spacing * 0.25 <= config.max_knot_turn + 1e-9  # κ = 1/4 1/m
    assert at[-1] < 2000.0


def test_the_curvature_bound_is_the_vehicles_within_what_the_speed_allows() -> None:
    problem = PlanningProblem(np.array([[0.0, 0.0], [100.0, 0.0]]), Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, 15.0))
    v = problem.vehicle
    s = np.linspace(10.0, 60.0, 11)
    allowance = curvature_allowance(s, START, problem)
    assert np.all(allowance <= 0.9 * v.max_curvature)
    # braking at half the deceleration from 15 m/s: v² = 225 − 6·travelled
    v_sq = np.maximum(225.0 - v.max_deceleration * (s - 10.0), 1.0)
    np.testing.assert_allclose(
        allowance, np.minimum(0.9 * v.max_curvature, 0.9 * v.max_lateral_acceleration / v_sq)
    )
    assert allowance[0] < allowance[-1]  # slower farther on: tighter curves


#: CommonRoad's vehicle type 2 (BMW 320i) as the closed loops drive it
BMW = replace(
    CAR,
    max_curvature=float(np.tan(1.066)) / 2.5789128,
    wheelbase=2.5789128,
    rear_axle_offset=1.4227170936,
    max_steering_angle=1.066,
    max_steering_rate=0.4,
)


def test_the_curvature_rate_bound_keeps_the_steering_rate_at_the_least_speed_braking_leaves() -> None:
    line = np.array([[0.0, 0.0], [200.0, 0.0]])
    problem = PlanningProblem(line, Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, 20.0), vehicle=BMW)
    s = np.linspace(10.0, 60.0, 11)
    rate = curvature_rate_allowance(s, START, problem, braking_share=0.5)
    assert rate is not None
    # |dδ/dt| ≤ v·W·|dκ/dσ| ≤ 0.9·0.4 rad/s at v² = 400 − 8·travelled (half of 8 m/s²)
    speed = np.sqrt(np.maximum(400.0 - 8.0 * (s - 10.0), 0.0))
    with np.errstate(divide="ignore"):
        expected = np.where(speed > 0.0, 0.36 / (BMW.wheelbase * np.maximum(speed, 1e-300)), np.inf)
    np.testing.assert_allclose(rate, expected)
    assert rate[0] == pytest.approx(0.36 / (2.5789128 * 20.0))
    assert np.isposinf(rate[-1])  # it can stand there: no bound
    assert np.all(np.diff(rate) >= 0.0)  # slower farther on: the wheel may turn faster per metre
    # the point model and a car without a steering-rate limit have none
    assert curvature_rate_allowance(s, START, replace(problem, vehicle=CAR)) is None
    free = replace(BMW, max_steering_rate=None)
    assert curvature_rate_allowance(s, START, replace(problem, vehicle=free)) is None


def test_the_jerk_bounds_even_out_the_references_curvature_and_always_allow_holding() -> None:
    s = np.arange(6) * 0.5
    one = np.ones(6)
    flat = np.zeros(6)
    rate = np.full(6, 0.02)
    lower, upper = jerk_bounds(s, flat, one, rate, 0.5)
    np.testing.assert_allclose(lower, -0.02)
    np.testing.assert_allclose(upper, 0.02)
    # a ripple of the reference's curvature (+0.004 1/m over one interval): the path's d‴ must undo it
    # within the rate: d‴ ∈ −0.008 ± 0.02 there
    ripple = np.array([0.0, 0.0, 0.004, 0.004, 0.004, 0.004])
    lower, upper = jerk_bounds(s, ripple, one, rate, 0.5)
    assert (lower[1], upper[1]) == pytest.approx((-0.028, 0.012))
    # a step steeper than the rate allows (+0.1 1/m): d‴ ∈ −0.2 ± 0.02, widened to keep 0 (following the
    # reference is what the speed profile slows for), and within the comfort jerk
    step = np.array([0.0, 0.0, 0.1, 0.1, 0.1, 0.1])
    lower, upper = jerk_bounds(s, step, one, rate, 0.5)
    assert (lower[1], upper[1]) == pytest.approx((-0.22, 0.0))
    assert np.all(lower <= 0.0) and np.all(upper >= 0.0) and np.all(lower >= -0.5)
    # where the vehicle may stand there is no rate bound, only the comfort jerk
    lower, upper = jerk_bounds(s, flat, one, np.full(6, np.inf), 0.5)
    np.testing.assert_allclose(lower, -0.5)
    np.testing.assert_allclose(upper, 0.5)


def test_a_car_eases_into_a_bend_its_steering_cannot_take_at_once() -> None:
    """A straight into a bend of radius 4 m (curvature steps from 0 to 0.25 1/m), ±1.5 m of room: with
    ``smooth`` the QP's jerk term costs the path's own curvature rate, so the path cuts into the bend
    gradually — its steepest change of curvature along the path well below the reference's — and
    keeps its bounds; without it the path follows the reference's step."""
    road = Road([straight_piece(20.0), arc_piece(4.0, 1.2), straight_piece(20.0)])
    ref = build_reference(road.polyline(0.5))
    s = np.arange(5.0, 35.0, 0.5)
    bounds = LateralBounds(s, np.full(s.shape, -1.5), np.full(s.shape, 1.5), None)
    start = EgoFrenet(s=5.0, d=0.0, dd=0.0, ddd=0.0, heading_error=0.0)
    problem = PlanningProblem(road.polyline(0.5), Lane(1.5, 1.5), Ego(5.0, 0.0, 0.0, 3.0), vehicle=BMW)
    allowance = np.full(s.shape, 0.9 * BMW.curvature_limit)
    rate = curvature_rate_allowance(s, start, problem)
    solver = LateralQPSolver()

    def steepest(smooth: bool) -> tuple[float, np.ndarray]:
        config = DEFAULT_CONFIG.lateral
        problem_qp = lateral_problem(bounds, np.zeros(s.shape), start, ref, allowance, config, rate, smooth)
        qp = solve_lateral(solver, problem_qp, config)
        assert qp.info.converged, qp.info
        assert np.all(qp.d >= -1.5 - 1e-3) and np.all(qp.d <= 1.5 + 1e-3)
        path = frenet_path(ref, s, qp.d, qp.dd, qp.ddd)
        return float(np.max(np.abs(np.diff(path.curvature) / np.diff(path.sigma)))), qp.d

    followed, d_followed = steepest(False)
    eased, d_eased = steepest(True)
    own = float(np.max(np.abs(reference_jerk(s, ref.kappa_at(s), np.ones(s.shape)))))
    assert followed > 0.5 * own  # the step, about as the reference has it
    assert eased < 0.5 * followed
    assert np.abs(d_eased).max() > 0.1 > np.abs(d_followed).max()  # by cutting into the bend


def test_zam_over_swerving_with_road_keeps_the_steering_rate() -> None:
    """ZAM_Over-1_1 with the whole road, CommonRoad's car, the closed loop's state at 0.1 s: swerving
    round the lane-wide obstacle 1402 from 19.9 m/s, the path reversed its curvature at 9 m/s where
    the steering could not follow (0.403 rad/s > 0.4), and the fallback, the vehicle's limits first,
    braked straight into the obstacle."""
    problem = problem_from_json(json.loads((ROAD_DATA / "ZAM_Over-1_1.json").read_text()))
    ego = Ego(
        x=31.988632798155468,
        y=-1.0612730430670965,
        heading=0.04415847561853791,
        speed=19.861896523558578,
        acceleration=-2.7248148265678727,
        curvature=0.008986764279133738,
    )
    problem = replace(problem, ego=ego, vehicle=BMW, options=replace(problem.options, speed_limit=23.0))
    result = plan(problem)
    assert result.status != "error"
    assert result.diagnostics.decision.borrows
    kinds = {v.kind for v in car_violations(problem.vehicle, result.trajectory)}
    assert ViolationKind.STEERING_RATE not in kinds
    assert not result.violations, result.message


def test_aarschot_where_the_path_leaves_the_lane_in_the_hairpin_is_the_block() -> None:
    """BEL_Aarschot-3_1's first cycle, CommonRoad's car (turning to 0.70 1/m): the lateral bounds let
    the footprint through the 2.4 m hairpin, but the QP's path (bounds linearised at the candidate's
    heading) leaves the lane there, and every cycle was a fallback. Where it leaves is the block: the
    plan stops before it (and, with a road, the lane decision may borrow it)."""
    problem = problem_from_json(json.loads((DATA / "BEL_Aarschot-3_1_T-1.json").read_text()))
    problem = replace(problem, vehicle=BMW)
    result = plan(problem)
    assert result.status == "stopped", result.message
    assert not result.violations
    assert result.diagnostics.decision.reason.block is not None  # what blocks: the bend
    assert result.diagnostics.decision.reason.block.value == "bend"


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


@pytest.mark.parametrize("scene", ["DEU_Flensburg-58_1_T-1", "DEU_Lohmar-26_1_T-1"])
def test_an_infeasible_qp_is_relaxed_only_where_its_path_may_be_chosen(
    monkeypatch: pytest.MonkeyPatch, scene: str
) -> None:
    """The first requests of two scenes whose QP at the speed's curvature allowance has no solution. At
    DEU_Lohmar-26 OSQP's iterate keeps to the lane (no retry at the vehicle's own limit follows) and the
    corridor without the lane margin gives a solved path that wins whatever the least-violating one
    does: the elastic problem (the stage's costliest solve) is not solved. At DEU_Flensburg-58 it is: only
    where that path leaves the lane does the retry run (a relaxed path in the lane is taken before a
    retry's, whose sharper turns the speed may not allow). Either way the answer is the one of a stage
    that relaxes every proven-infeasible QP at once."""
    problem = problem_from_json(json.loads((DATA / f"{scene}.json").read_text()))
    relaxed = counted_calls(monkeypatch, LateralQPSolver, "relax")
    lazy = plan(problem)
    assert len(relaxed) == (0 if scene == "DEU_Lohmar-26_1_T-1" else 1)
    assert lazy.diagnostics.lateral_qp.status in CONVERGED
    relaxed.clear()
    solve = LateralQPSolver.solve

    def at_once(self: LateralQPSolver, qp: object, **kwargs: object) -> object:
        return solve(self, qp, **{**kwargs, "relax": True})  # type: ignore[arg-type]

    monkeypatch.setattr(LateralQPSolver, "solve", at_once)
    eager = plan(problem)
    assert len(relaxed) >= 1  # the elastic path was there to choose from, and lost
    assert (eager.status, eager.message) == (lazy.status, lazy.message)
    for field_name in ("x", "y", "v", "a", "curvature", "heading"):
        np.testing.assert_array_equal(
            getattr(eager.trajectory, field_name), getattr(lazy.trajectory, field_name)
        )


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


def _box(s0: float, s1: float, d0: float, d1: float) -> np.ndarray:
    return np.array([[s0, d0], [s1, d0], [s1, d1], [s0, d1]])


def test_keeping_the_offset_stops_before_an_obstacle_on_it() -> None:
    # Stopped at 0.7 rad to the road beside a parked car (no room to steer: the lateral QP is
    # infeasible), a wall across the road at 60 m and a car on the held offset at 30 m.
    points = np.column_stack((np.linspace(0.0, 100.0, 101), np.zeros(101)))
    obstacles = (
        PolygonObstacle("beside", _box(12.0, 20.0, -3.5, -2.3)),
        PolygonObstacle("ahead", _box(30.0, 34.0, -1.5, -0.5)),
        PolygonObstacle("wall", _box(60.0, 62.0, -4.0, 4.0)),
    )
    problem = PlanningProblem(
        reference_line=points,
        lane=Lane(left_width=np.full(101, 3.5), right_width=np.full(101, 3.5)),
        ego=Ego(x=10.0, y=-1.0, heading=-0.7, speed=0.0),
        vehicle=CAR,
        obstacles=obstacles,
        options=Options(horizon_time=8.0, dt=0.1),
    )
    result = plan(problem)
    assert result.diagnostics.lateral_qp.status not in CONVERGED  # the hold path is what is tested
    assert result.status == "stopped", result.message
    # the front stops short of the car on the held offset, not of the wall
    assert result.trajectory.s.max() + 0.5 * CAR.length < 30.0
    # and the message gives the car's distance, not the wall's (ego at s = 10 m)
    ahead = re.search(r"blocked ([0-9.]+) m ahead", result.message)
    assert ahead is not None and float(ahead.group(1)) < 20.0, result.message


def test_us101_keeping_the_offset_stops_before_the_parked_car() -> None:
    # the closed loop's state at 16.0 s: "footprint hits obstacle 418" (a parked car 18.5 m ahead on the
    # held offset; the block is 54 m ahead), a fallback at every cycle from there on
    ego = Ego(x=78.67763460141727, y=-66.71339440778627, heading=-1.3719129302718025, speed=0.0)
    result = plan(_recorded("USA_US101-6_1_T-1", 16.0, ego))
    # (steering around the car or stopping before it on the held offset: either is a safe answer)
    assert result.status == "stopped", result.message
    assert not result.violations


def test_lohmar_the_car_eases_into_the_tight_turn_instead_of_crawling_through_it() -> None:
    """DEU_Lohmar-26_1, CommonRoad's car, the closed loop's state at 1.6 s (4.4 m/s, the recorded car 362
    coming up from behind): the eased path (its jerk term costing the path's own curvature rate) missed
    the lane by millimetres in the right turn 15 m ahead (its bounds linearised at the candidate's
    heading), so the path followed the reference's own change of curvature there, which the steering
    rate (0.4 rad/s) lets the car drive at about 1.1 m/s: the profile braked to that crawl, 362 hit it,
    and the cycle (as the next 45) was a fallback. The bounds moved inside where the eased path left the
    lane, its second solve keeps the footprint in the lane and lets the car through the turn at
    about twice that."""
    ego = Ego(
        x=-455.9462057745639,
        y=-438.59342793682026,
        heading=1.4745587171400905,
        speed=4.416733269450525,
        acceleration=2.922510769401568,
        curvature=-0.000982011149314392,
    )
    problem = replace(_recorded("DEU_Lohmar-26_1_T-1", 1.6, ego), vehicle=BMW)
    result = plan(problem)
    assert result.status == "ok", result.message
    assert not result.violations
    assert not car_violations(problem.vehicle, result.trajectory)
    through = result.trajectory.v[result.trajectory.t > 1.0]
    assert through.min() > 1.8  # the reference's own turn-in: 1.1 m/s


def _jog(shift: float = 1.0, length: float = 12.0, at: float = 150.0) -> np.ndarray:
    """A straight reference along +x with an S-jog of ``shift`` [m] to the left over ``length`` [m] at
    ``at`` [m] (a fitted map's kink: curvature ``±π² shift / (2 length²)``, 0.034 1/m here)."""
    x = np.arange(0.0, 320.0, 1.0)
    u = np.clip((x - at) / length, 0.0, 1.0)
    return np.column_stack((x, 0.5 * shift * (1.0 - np.cos(np.pi * u))))


def test_the_straight_allowance_keeps_a_bend_and_leaves_out_a_jog() -> None:
    """A bend of the road keeps the curvature it needs; a jog of the reference (curvatures of either sign
    close together) averages out: the path is asked to drive it at the cruise speed's curvature."""
    problem = PlanningProblem(
        _jog(), Lane(4.0, 4.0), Ego(100.0, 0.0, 0.0, speed=20.0), (), CAR, Options(target_speed=20.0)
    )
    ref = build_reference(problem.reference_line)
    s = np.linspace(100.0, 200.0, 201)
    loose = np.full(s.shape, 0.2)
    cruise = DEFAULT_CONFIG.limit_margin * CAR.max_lateral_acceleration / 20.0**2
    straight = straight_allowance(s, ref, problem, loose)
    assert np.max(np.abs(ref.kappa_at(s))) > 3.0 * cruise  # the jog itself is far too sharp
    np.testing.assert_allclose(straight[(s > 140.0) & (s < 172.0)], cruise, rtol=0.3)
    assert np.all(straight <= loose)
    ego = Ego(0.0, 0.0, 0.0, speed=20.0)
    bend = PlanningProblem(u_turn(radius=40.0), Lane(4.0, 4.0), ego, (), CAR, Options(target_speed=20.0))
    ref_b = build_reference(bend.reference_line)
    kept = straight_allowance(ref_b.s, ref_b, bend, np.full(ref_b.s.shape, 0.2))
    np.testing.assert_array_equal(kept, 0.2)  # a bend (its entry and exit too) keeps the allowance


@pytest.mark.parametrize("vehicle", [CAR, CAR_WITH_AXLE], ids=["point", "car"])
def test_a_jog_of_the_reference_in_a_wide_lane_is_driven_straight_at_target_speed(vehicle: Vehicle) -> None:
    """Following the jog would need 0.034 1/m, 7.5 m/s² at the 20 m/s target for a 4 m/s² vehicle, so the
    speed profile would slow to ~10 m/s for it; the lane has room to drive it straight at the target."""
    problem = PlanningProblem(
        _jog(), Lane(4.0, 4.0), Ego(100.0, 0.0, 0.0, speed=20.0), (), vehicle, Options(target_speed=20.0)
    )
    result = plan(problem)
    assert result.status == "ok" and not result.violations, result.message
    traj = result.trajectory
    through = (traj.s > 140.0) & (traj.s < 175.0)
    assert through.any() and np.min(traj.v) > 19.5  # no slowing for the jog
    lat = traj.v[through] ** 2 * np.abs(traj.curvature[through])
    assert np.max(lat) <= vehicle.max_lateral_acceleration


def test_a_jog_in_a_lane_without_room_is_followed_as_before() -> None:
    """Where the lane leaves no room to drive the jog straight, the path follows it (the first QP's) and the
    speed profile slows for it, within the limits."""
    narrow = Lane(1.0, 1.0)
    problem = PlanningProblem(
        _jog(shift=2.0), narrow, Ego(100.0, 0.0, 0.0, speed=20.0), (), CAR, Options(target_speed=20.0)
    )
    result = plan(problem)
    assert result.status == "ok" and not result.violations, result.message
    traj = result.trajectory
    assert np.min(traj.v) < 19.0  # slows for the jog it cannot leave out
    assert np.max(traj.v**2 * np.abs(traj.curvature)) <= CAR.max_lateral_acceleration + 1e-6


def test_the_straighter_path_gets_its_own_iterations_and_no_second_backend(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The straighter path is optional: its QP gets ``straight_max_iter`` OSQP iterations (fewer than a
    required QP's ``max_iter``) and no second backend; the jog is still driven straight within them."""
    problem = PlanningProblem(
        _jog(), Lane(4.0, 4.0), Ego(100.0, 0.0, 0.0, speed=20.0), (), CAR, Options(target_speed=20.0)
    )
    asked: list[tuple[int, bool]] = []
    solve = LateralQPSolver.solve

    def spy(self: LateralQPSolver, qp: object, **kwargs: object) -> object:
        asked.append((int(kwargs["max_iter"]), bool(kwargs["second_backend"])))  # type: ignore[call-overload]
        return solve(self, qp, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(LateralQPSolver, "solve", spy)
    result = plan(problem)
    config = DEFAULT_CONFIG.lateral
    assert config.straight_max_iter < config.max_iter
    assert asked == [(config.max_iter, True), (config.straight_max_iter, False)]
    assert result.status == "ok" and np.min(result.trajectory.v) > 19.5


def test_bounds_with_the_knots_geometry_given_are_the_bounds_computed_whole() -> None:
    """The lateral stage computes the turning limits and corners at its knots once for the corridor with
    its lane margin and without (:func:`planner.bounds.knot_geometry`): the bounds are the same numbers as
    computed whole, with either margin, in a bend tight enough that corners bulge and an obstacle in it."""
    road = Road([straight_piece(20.0), arc_piece(6.0, 1.5), straight_piece(20.0)])
    ref = build_reference(road.polyline(0.5))
    lane = Lane(2.0, 2.0)
    s = np.arange(2.0, 40.0, 0.5)
    boxes = frenet_boxes(ref, [("box", shapely.box(14.0, 0.8, 16.0, 2.5))])
    left_of = np.zeros(1, dtype=bool)
    geometry = knot_geometry(ref, lane, s, CAR_WITH_AXLE)
    assert np.any(geometry.corners.reach > 0.0)  # corners bulge out of the bend
    for lane_margin in (None, 0.0):
        whole, shared = (
            lateral_bounds(
                ref,
                lane,
                s,
                CAR_WITH_AXLE,
                margin=0.3,
                boxes=boxes,
                left_of=left_of,
                lane_margin=lane_margin,
                geometry=given,
            )
            for given in (None, geometry)
        )
        assert np.array_equal(whole.lower, shared.lower) and np.array_equal(whole.upper, shared.upper)
        assert whole.blocked == shared.blocked
    # the obstacle narrows the bounds beside it
    assert np.all(whole.upper[(s > 13.0) & (s < 17.0)] < 0.8)


def test_past_its_budget_the_lateral_stage_skips_the_solves_that_only_improve_its_path(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The retries at the vehicle's own curvature limit and without the lane margin, and the straighter
    path, run only while the budget leaves them what the solve before took: past it, the plan reaches its
    fallback instead of solving on. Without a budget (``time_left()`` None) they all run."""
    base = demo_problem()
    problem = replace(base, vehicle=replace(base.vehicle, max_curvature=0.01))  # its U-turn is too tight
    solves = counted_calls(monkeypatch, LateralQPSolver, "solve")
    free = plan(problem)
    unbudgeted = len(solves)
    solves.clear()
    monkeypatch.setattr(StageTimer, "remaining_s", lambda self: 1e-9)  # nothing left, whatever the budget
    spent = plan(problem)
    # the QP has no solution at the allowed curvature: unbudgeted, the vehicle's own limit is tried too
    assert unbudgeted >= 2 and len(solves) < unbudgeted
    assert free.status == spent.status == "stopped"


def _on_a_straight(ego: Ego, **vehicle: float) -> PlanningProblem:
    """The demo's vehicle (with ``vehicle``'s fields changed) on a straight 3.5 m lane, no obstacles."""
    base = demo_problem()
    return replace(
        base,
        reference_line=straight(150.0),
        lane=Lane(left_width=1.75, right_width=1.75),
        obstacles=(),
        ego=ego,
        vehicle=replace(base.vehicle, **vehicle),
    )


def test_a_start_that_cannot_reach_its_bounds_is_proven_infeasible_without_the_second_backend(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """An ego 0.75 m outside its lane on a straight at 10 m/s, too fast to steer back within the bounds'
    ramp: its lateral QP is proven infeasible by the start's reach (``reach_gap``), not by the second
    backend, and the answer is the one the second backend's proof gave."""
    import solvers.lateral_qp as lateral_qp

    problem = _on_a_straight(Ego(x=5.0, y=2.5, heading=0.0, speed=10.0))
    solves: list[str] = []
    solve_conic_qp = lateral_qp.solve_conic_qp

    def counted(*args: object, **kwargs: object) -> object:
        solves.append("conic")
        return solve_conic_qp(*args, **kwargs)

    monkeypatch.setattr(lateral_qp, "solve_conic_qp", counted)
    elastic = counted_calls(monkeypatch, LateralQPSolver, "_solve_elastic")
    proven = plan(problem)
    assert proven.status == "ok" and elastic
    proofs = len(solves) - len(elastic)  # the second backend's solves that are not elastic problems
    solves.clear()
    elastic.clear()
    monkeypatch.setattr(lateral_qp, "reach_gap", lambda qp: 0.0)  # the proof left to the second backend
    by_clarabel = plan(problem)
    assert len(solves) - len(elastic) > proofs
    assert (by_clarabel.status, by_clarabel.message) == (proven.status, proven.message)
    for name in ("t", "x", "y", "heading", "curvature", "v", "a", "s", "d"):
        np.testing.assert_array_equal(getattr(by_clarabel.trajectory, name), getattr(proven.trajectory, name))


@pytest.mark.parametrize("wheelbase", [None, 2.7])
def test_the_lane_check_of_a_path_far_off_the_road_maps_two_poses(
    monkeypatch: pytest.MonkeyPatch, wheelbase: float | None
) -> None:
    """A path whose planned point runs tens of metres off the lane (an unconverged QP's iterate integrated
    from the start) is out where it lies farthest out: the lane check maps that pose and the start, not the
    whole path; for a path in the lane, one just out and one far out it answers as the full check does."""
    import planner.validation as validation
    from planner.lateral import _Paths
    from solvers.lateral_qp_problem import LateralQPResult
    from solvers.result import SolveInfo

    car = {} if wheelbase is None else {"wheelbase": wheelbase, "rear_axle_offset": 1.35}
    problem = _on_a_straight(Ego(x=5.0, y=0.0, heading=0.0, speed=10.0), length=4.5, width=1.8, **car)
    ref = build_reference(problem.reference_line)
    s = np.linspace(5.0, 65.0, 121)
    info = SolveInfo(
        status=SolverStatus.MAX_ITERATIONS, iterations=200, solve_time_ms=0.0, objective=None, message=""
    )

    def answer(d: np.ndarray) -> LateralQPResult:
        dd = np.gradient(d, s)
        return LateralQPResult.of(np.concatenate([d, dd, np.gradient(dd, s)]), info)

    ahead = s - s[0]
    cases = {
        "in the lane": (answer(0.3 * np.sin(ahead / 10.0)), True),
        "just out": (answer(np.minimum(ahead / 20.0, 1.2)), False),
        "far off": (answer(0.025 * ahead**2), False),
    }
    mapped: list[int] = []
    to_frenet = validation.to_frenet

    def counted(ref_: object, points: np.ndarray, **kwargs: object) -> object:
        mapped.append(len(points))
        return to_frenet(ref_, points, **kwargs)

    monkeypatch.setattr(validation, "to_frenet", counted)
    for name, (qp, inside) in cases.items():
        mapped.clear()
        assert _Paths(ref, problem).in_lane(s, qp, problem.lane) is inside, name
        if name == "far off":
            assert sum(mapped) == 2 * 10  # the start's outline and the farthest pose's
        full = _Paths(ref, problem).leaves(s, qp, problem.lane)
        assert (not full.any()) is inside, name


@pytest.mark.parametrize("road", [False, True])
@pytest.mark.parametrize("ahead", [4.8, 4.9])
def test_a_relaxed_path_that_would_run_into_an_obstacle_stops_before_it(road: bool, ahead: float) -> None:
    # A car standing with its front 3–13 cm from the corner of a parked car turned 0.3 rad into its lane
    # (a recorded PRI_Barceloneta scene with a swapped ego): the bounds open a way past on the right that
    # the car cannot steer into from where it stands, the relaxed QP's path breaks them and would drive
    # into the parked car. It stands, and says what blocks (before: a fallback, "footprint hits obstacle").
    car = Vehicle(
        length=4.508, width=1.61, max_acceleration=3.0, max_deceleration=8.0, max_curvature=0.7,
        wheelbase=2.579, rear_axle_offset=1.4227, max_steering_angle=1.066, max_steering_rate=0.4,
    )  # fmt: skip
    corners = box_corners(np.array(20.0 + ahead), np.array(2.12), np.array(-2.836), 5.0, 2.0)
    problem = PlanningProblem(
        reference_line=straight(200.0),
        lane=Lane(1.75, 1.75),
        ego=Ego(x=20.0, y=0.011, heading=0.0, speed=0.0),
        obstacles=(PolygonObstacle("parked", corners),),
        vehicle=car,
        options=Options(target_speed=19.15, lateral_margin=0.2),
        road=WholeRoad(5.15, 1.75) if road else None,
    )
    result = plan(problem)
    assert result.status == "stopped"
    assert result.diagnostics.decision.reason.obstacle_id == "parked"
    assert float(np.ptp(result.trajectory.x)) < 1e-6
