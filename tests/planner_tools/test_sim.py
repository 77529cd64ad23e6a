"""Closed-loop simulator: the vehicle model, the tracker, moving obstacles, and whole runs."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

import planner_tools.sim as sim
from planner.collision import prediction_at
from planner.errors import InvalidInputError, PlannerError
from planner.goal import Goal as PlannerGoal
from planner.problem import (
    CircleObstacle,
    DynamicObstacle,
    Ego,
    Lane,
    Options,
    PlanningProblem,
    Vehicle,
)
from planner.roads import demo_problem, straight, u_turn
from planner.trajectory import Trajectory
from planner_tools.sim import (
    BicycleModel,
    Goal,
    PlanPath,
    TrackerGains,
    VehicleState,
    advance,
    initial_state,
    problem_at,
    shift_obstacle,
    simulate,
    step_exact,
    track,
)

MODEL = BicycleModel(wheelbase=2.7, rear_to_centre=1.35, max_steering=0.6)


def _start(speed: float, steering: float = 0.0, model: BicycleModel = MODEL) -> VehicleState:
    beta = model.slip_angle(steering)
    return VehicleState(0.0, 0.0, 0.0, -beta, steering, speed, 0.0, 0.0, model.curvature(steering))


# --------------------------------------------------------------------------------------------------
# Vehicle model
# --------------------------------------------------------------------------------------------------


def test_bicycle_model_runs_exactly_on_a_circle() -> None:
    steering, speed, h = 0.2, 5.0, 0.01
    state = _start(speed, steering)
    states = [state]
    for _ in range(300):  # 3 s: more than half a turn
        state = step_exact(MODEL, state, 0.0, steering, h)
        states.append(state)
    # independently: the centre turns about the instantaneous centre of rotation on the rear axle's
    # line, a distance ℓ/tan δ from the rear axle
    r_rear = MODEL.wheelbase / math.tan(steering)
    radius = math.hypot(r_rear, MODEL.rear_to_centre)
    centre = np.array([0.0, radius])  # starting at the origin, travelling along +x, turning left
    t = np.array([st.t for st in states])
    xy = np.array([[st.x, st.y] for st in states])
    phi = speed * t / radius
    expected = np.column_stack((radius * np.sin(phi), radius * (1.0 - np.cos(phi))))
    np.testing.assert_allclose(np.hypot(*(xy - centre).T), radius, atol=1e-9)
    np.testing.assert_allclose(xy, expected, atol=1e-9)
    np.testing.assert_allclose([st.course for st in states], phi, atol=1e-9)
    # the rear axle moves along the body's yaw, on its own circle of radius ℓ/tan δ
    yaw = np.array([st.yaw for st in states])
    rear = xy - MODEL.rear_to_centre * np.column_stack((np.cos(yaw), np.sin(yaw)))
    np.testing.assert_allclose(np.hypot(*(rear - centre).T), r_rear, atol=1e-9)
    assert states[-1].curvature == pytest.approx(1.0 / radius, rel=1e-12)


def test_bicycle_model_accelerates_along_the_arc_and_stops_without_reversing() -> None:
    steering = -0.1
    state = _start(4.0, steering)
    radius = 1.0 / abs(MODEL.curvature(steering))
    for _ in range(100):
        state = step_exact(MODEL, state, 1.0, steering, 0.01)
    arc = 4.0 * 1.0 + 0.5 * 1.0 * 1.0**2
    assert state.speed == pytest.approx(5.0)
    assert state.course == pytest.approx(-arc / radius)
    assert math.hypot(state.x, state.y + radius) == pytest.approx(radius)  # right turn: centre (0, −R)
    braking = _start(3.0)
    for _ in range(200):
        braking = step_exact(MODEL, braking, -2.0, 0.0, 0.01)
    assert braking.speed == 0.0 and braking.acceleration == 0.0
    assert braking.x == pytest.approx(3.0**2 / (2 * 2.0))


def test_steering_follows_commands_within_its_rate_and_range() -> None:
    vehicle = Vehicle()
    model = BicycleModel.for_vehicle(vehicle)
    assert model.wheelbase == pytest.approx(0.6 * vehicle.length)
    assert model.curvature(model.max_steering) == pytest.approx(vehicle.max_curvature)
    assert model.curvature(model.steering_for(0.1)) == pytest.approx(0.1)
    state = initial_state(model, Ego(0.0, 0.0, 0.0, speed=5.0), vehicle)
    nxt = advance(model, vehicle, state, 100.0, 1.0, 0.01)
    assert nxt.steering == pytest.approx(model.max_steering_rate * 0.01)
    assert nxt.speed == pytest.approx(5.0 + vehicle.max_acceleration * 0.01)
    for _ in range(300):
        nxt = advance(model, vehicle, nxt, 0.0, 1.0, 0.01)
    assert nxt.curvature == pytest.approx(vehicle.max_curvature)


def test_centre_on_the_rear_axle_has_no_slip_angle() -> None:
    model = BicycleModel.for_vehicle(Vehicle(), rear_to_centre=0.0)
    assert model.slip_angle(0.3) == 0.0
    assert model.curvature(0.3) == pytest.approx(math.tan(0.3) / model.wheelbase)
    assert model.curvature(model.steering_for(0.15)) == pytest.approx(0.15)


# --------------------------------------------------------------------------------------------------
# Tracker
# --------------------------------------------------------------------------------------------------


def _plan(x: np.ndarray, y: np.ndarray, heading: np.ndarray, curvature: np.ndarray, v: float) -> Trajectory:
    t = np.arange(x.shape[0]) * 0.1
    zeros = np.zeros_like(t)
    return Trajectory(t, x, y, heading, curvature, np.full_like(t, v), zeros, zeros, zeros)


def _follow(plan: Trajectory, state: VehicleState, seconds: float) -> tuple[VehicleState, float]:
    """Track one plan (no replanning) for ``seconds``; the last lateral error."""
    vehicle = Vehicle()
    path = PlanPath.of(plan)
    h = 0.01
    out = track(path, 0.0, state, TrackerGains())
    for i in range(round(seconds / h)):
        out = track(path, i * h, state, TrackerGains())
        state = advance(MODEL, vehicle, state, out.acceleration, out.curvature, h)
    return state, out.lateral_error


def test_tracker_pulls_onto_a_straight() -> None:
    t = np.arange(121) * 0.1
    plan = _plan(5.0 * t, np.zeros_like(t), np.zeros_like(t), np.zeros_like(t), 5.0)
    start = replace(_start(4.0), y=0.6, yaw=0.05, course=0.05)
    state, error = _follow(plan, start, 8.0)
    assert abs(error) < 0.02 and abs(state.y) < 0.02
    assert abs(state.course) < 0.01
    assert state.speed == pytest.approx(5.0, abs=0.05)
    assert state.x == pytest.approx(40.0, abs=0.5)  # the station error is taken out too


def test_tracker_follows_an_arc() -> None:
    radius, speed = 12.0, 4.0
    t = np.arange(81) * 0.1
    phi = speed * t / radius
    plan = _plan(radius * np.sin(phi), radius * (1 - np.cos(phi)), phi, np.full_like(t, 1 / radius), speed)
    steering = MODEL.steering_for(1 / radius)
    state, error = _follow(plan, _start(speed, steering), 6.0)
    assert abs(error) < 0.01
    assert math.hypot(state.x, state.y - radius) == pytest.approx(radius, abs=0.01)
    assert state.course == pytest.approx(speed * 6.0 / radius, abs=0.01)


# --------------------------------------------------------------------------------------------------
# Obstacles, goals
# --------------------------------------------------------------------------------------------------

MOVER = DynamicObstacle(
    "car",
    4.0,
    1.8,
    np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 5.0, 0.0, 0.1], [2.0, 10.0, 1.0, 0.2], [3.0, 15.0, 2.0, 0.3]]),
)


def test_predictions_are_shifted_to_the_sim_time() -> None:
    shifted = shift_obstacle(MOVER, 1.5)
    assert isinstance(shifted, DynamicObstacle)
    np.testing.assert_allclose(shifted.prediction[:, 0], [0.0, 0.5, 1.5])
    np.testing.assert_allclose(shifted.prediction[0, 1:], [7.5, 0.5, 0.15])
    tau = np.linspace(0.0, 4.0, 41)
    np.testing.assert_allclose(prediction_at(shifted, tau), prediction_at(MOVER, 1.5 + tau), atol=1e-12)
    gone = shift_obstacle(MOVER, 5.0)
    assert isinstance(gone, DynamicObstacle)
    np.testing.assert_allclose(gone.prediction, [[0.0, 15.0, 2.0, 0.3]])
    exact = shift_obstacle(MOVER, 2.0)
    assert isinstance(exact, DynamicObstacle)
    np.testing.assert_allclose(exact.prediction[:, 0], [0.0, 1.0])
    cone = CircleObstacle("cone", np.array([1.0, 2.0]), 0.5)
    assert shift_obstacle(cone, 3.0) is cone


def test_problem_at_uses_the_vehicle_and_shifted_predictions() -> None:
    problem = PlanningProblem(straight(60.0), Lane(3.5, 3.5), Ego(0.0, 0.0, 0.0), (MOVER,))
    state = replace(_start(3.0), t=1.0, x=2.0, y=0.1, course=0.02)
    asked = problem_at(problem, state)
    assert asked.ego == Ego(2.0, 0.1, 0.02, 3.0, 0.0, state.curvature)
    moved = asked.obstacles[0]
    assert isinstance(moved, DynamicObstacle)
    np.testing.assert_allclose(moved.prediction[0], [0.0, 5.0, 0.0, 0.1])
    # a request's goal window is in seconds from now: from the cycle's time on
    timed = replace(problem, goal=PlannerGoal(time=(4.0, 6.0), speed=(0.0, 1.0)))
    goal = problem_at(timed, state).goal
    assert goal is not None and goal.time == (3.0, 5.0) and goal.speed == (0.0, 1.0)
    assert problem_at(problem, state).goal is None


def test_goal_criteria() -> None:
    with pytest.raises(InvalidInputError):
        Goal()
    with pytest.raises(InvalidInputError):
        Goal(position=np.array([0.0, 0.0]))
    square = Goal(polygon=np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]]))
    assert square.reached(1.0, 1.0, 0.0) and not square.reached(3.0, 1.0, 0.0)
    both = Goal(s_min=10.0, position=np.array([0.0, 0.0]), radius=1.0)
    assert both.reached(0.5, 0.0, 11.0)
    assert not both.reached(0.5, 0.0, 9.0) and not both.reached(2.0, 0.0, 11.0)


# --------------------------------------------------------------------------------------------------
# Whole runs
# --------------------------------------------------------------------------------------------------

SHORT_ROAD = u_turn(radius=8.0, leg=12.0, step=2.0)


def _short_demo(generator: str = "transf_kappa") -> PlanningProblem:
    """The demo U-turn (same radius, lane and cone) with 12 m legs, the ego 6 m before the turn."""
    problem = demo_problem()
    return replace(
        problem,
        reference_line=SHORT_ROAD,
        ego=Ego(x=-6.0, y=0.0, heading=0.0, speed=5.0),
        options=replace(problem.options, generator=generator),  # type: ignore[arg-type]
    )


def test_transf_kappa_drives_the_u_turn() -> None:
    """The default vehicle does not slip at its centre: its body turns with the path, as the planner's
    footprint assumes."""
    problem = _short_demo()
    result = simulate(problem)
    assert result.model == BicycleModel.for_vehicle(problem.vehicle)
    assert result.model.rear_to_centre == 0.0
    m = result.metrics
    assert m.termination == "goal" and m.goal_reached
    assert m.collisions == 0 and m.min_clearance is not None and m.min_clearance > 0.0
    assert m.backward_steps == 0 and m.fold_steps == 0
    assert m.folded_candidates["cycles"] == 0
    assert m.final_s >= result.goal.s_min  # type: ignore[operator]
    assert m.max_tracking_error < 0.05
    assert m.max_lateral_acceleration <= problem.vehicle.max_lateral_acceleration + 0.1
    assert sum(m.status_counts.values()) == m.steps == len(result.steps)
    # the cycles chain up: every plan starts where the vehicle was (to the lateral QP's tolerance on its
    # initial-state rows, micrometres)
    for st in result.steps:
        assert st.trajectory is not None
        assert math.hypot(st.trajectory.x[0] - st.state.x, st.trajectory.y[0] - st.state.y) < 1e-4
    json.dumps(m.to_dict())


def test_a_car_planned_as_a_car_drives_the_demo_u_turn_clear_of_the_cone() -> None:
    """The car of ``--centre-midway`` (wheelbase 0.6·length, rear axle midway between the axles, behind
    the centre) planned as the car it is: its footprint from the rear axle along the yaw."""
    problem = demo_problem()
    midway = BicycleModel.for_vehicle(problem.vehicle, centre_midway=True)
    vehicle = replace(problem.vehicle, wheelbase=midway.wheelbase, rear_axle_offset=midway.rear_to_centre)
    car = replace(problem, vehicle=vehicle)
    result = simulate(car)
    assert result.model.at_rear_axle and result.model.wheelbase == pytest.approx(2.7)
    m = result.metrics
    assert m.termination == "goal" and m.collisions == 0
    assert m.min_clearance is not None and m.min_clearance > 0.2
    assert m.max_lane_departure < 0.0 and m.max_tracking_error < 0.05
    assert m.status_counts["ok"] == m.steps
    assert m.max_lateral_acceleration <= vehicle.max_lateral_acceleration + 0.1
    # the body is yawed against the centre's path in the turn (no slip at the rear axle)
    slip = np.abs(np.angle(np.exp(1j * (result.motion.course - result.motion.yaw))))
    assert slip.max() == 0.0
    step = np.diff(np.column_stack((result.motion.x, result.motion.y)), axis=0)
    centre_course = np.arctan2(step[:, 1], step[:, 0])
    moving = np.hypot(*step.T) > 1e-3
    yaw_mid = 0.5 * (result.motion.yaw[:-1] + result.motion.yaw[1:])
    assert np.degrees(np.abs(np.angle(np.exp(1j * (centre_course - yaw_mid))))[moving].max()) > 5.0


def test_the_same_car_planned_as_a_point_touches_the_cone() -> None:
    """What planning the car as a point does: its body is yawed by the slip angle (≈ 10° here), which
    swings its outer front corner ~0.4 m further out than the point model's footprint, into the cone."""
    problem = demo_problem()
    result = simulate(problem, model=BicycleModel.for_vehicle(problem.vehicle, centre_midway=True))
    assert result.metrics.collisions > 0 and result.metrics.collided_with == ("cone",)


def test_a_car_model_takes_the_vehicles_geometry_and_steering() -> None:
    car = {"wheelbase": 2.578, "rear_axle_offset": 1.422, "max_steering_angle": 1.066}
    car["max_steering_rate"] = 0.4
    vehicle = Vehicle(**car)
    model = BicycleModel.for_vehicle(vehicle)
    assert (model.wheelbase, model.rear_to_centre, model.max_steering, model.max_steering_rate) == tuple(
        car.values()
    )
    assert model.at_rear_axle and model.slip_angle(0.5) == 0.0
    assert model.curvature(0.3) == pytest.approx(math.tan(0.3) / 2.578)
    ratio = float(model.centre_speed_ratio(np.array(0.3)))
    assert ratio == pytest.approx(math.hypot(1.0, 1.422 * math.tan(0.3) / 2.578))
    with pytest.raises(InvalidInputError):
        BicycleModel.for_vehicle(vehicle, centre_midway=True)
    # on a circle, the centre is placed from the rear axle along the yaw
    state = initial_state(model, Ego(1.422, 0.0, 0.0, speed=5.0, curvature=0.1), vehicle)
    for _ in range(100):
        state = step_exact(model, state, 0.0, state.steering, 0.01)
    rear = np.array([state.x, state.y]) - 1.422 * np.array([math.cos(state.yaw), math.sin(state.yaw)])
    assert math.hypot(rear[0], rear[1] - 10.0) == pytest.approx(10.0, abs=1e-9)  # radius 1/κ about (0, 10)
    assert state.yaw == pytest.approx(5.0 * 1.0 * 0.1) and state.course == state.yaw


def test_a_car_from_behind_is_a_collision_and_ends_the_run() -> None:
    """The planner leaves a faster car from behind to its driver; the simulator still scores the hit."""
    rammer = DynamicObstacle("rammer", 4.5, 1.8, np.array([[0.0, -2.0, 0.0, 0.0], [10.0, 148.0, 0.0, 0.0]]))
    problem = PlanningProblem(
        straight(200.0, step=5.0),
        Lane(3.5, 3.5),
        Ego(10.0, 0.0, 0.0, speed=5.0),
        (rammer,),
        Vehicle(),
        Options(target_speed=5.0),
    )
    result = simulate(problem, duration=5.0)
    m = result.metrics
    assert m.termination == "collision" and not m.goal_reached
    assert m.collided_with == ("rammer",) and m.collisions >= 1 and m.min_clearance == 0.0
    assert m.sim_time < 2.0  # 15 m/s against 5 m/s from 7.5 m behind: ~0.75 s
    assert result.steps[-1].obstacles[0][0] == "rammer"


def test_an_outside_collision_check_decides_when_a_collision_ends_the_run() -> None:
    """With an outside judge of collisions (CommonRoad's checker), the simulator's own contacts are counted
    but end nothing; the judge's collision ends the run at the cycle it finds it in."""
    rammer = DynamicObstacle("rammer", 4.5, 1.8, np.array([[0.0, -2.0, 0.0, 0.0], [10.0, 148.0, 0.0, 0.0]]))
    problem = PlanningProblem(
        straight(200.0, step=5.0), Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, speed=5.0), (rammer,), Vehicle(),
        Options(target_speed=5.0),
    )  # fmt: skip
    asked: list[float] = []

    def late(state: VehicleState) -> bool:
        asked.append(state.t)
        return state.t >= 1.5 - 1e-9

    result = simulate(problem, duration=3.0, collision=late)
    m = result.metrics
    assert m.termination == "collision" and m.sim_time == pytest.approx(1.5)
    assert m.collided_with == ("rammer",) and m.collisions >= 1  # the simulator's own, counted
    assert asked[0] == 0.0 and len(asked) == 1 + 150  # every sub-step up to 1.5 s
    never = simulate(problem, duration=1.0, collision=lambda state: False)
    assert never.metrics.termination == "timeout" and never.metrics.collisions > 0


def test_an_obstacle_that_leaves_the_scene_is_gone_for_the_planner_and_the_contact_check() -> None:
    """A recorded car whose recording ends (it left the recorded area) is held at its last state by the
    prediction's contract: without ``leaves`` it is a car stopped in the lane that the vehicle stops
    behind; with ``leaves`` it is gone from the cycle after its time on, for the planner and the
    simulator's own contact check."""
    ahead = DynamicObstacle("ahead", 4.5, 1.8, np.array([[0.0, 40.0, 0.0, 0.0], [1.0, 45.0, 0.0, 0.0]]))
    problem = PlanningProblem(
        straight(200.0, step=5.0), Lane(1.75, 1.75), Ego(10.0, 0.0, 0.0, speed=8.0), (ahead,), Vehicle(),
        Options(target_speed=8.0),
    )  # fmt: skip
    held = simulate(problem, duration=6.0)
    gone = simulate(problem, duration=6.0, leaves={"ahead": 1.0})
    assert held.metrics.status_counts["stopped"] + held.metrics.status_counts["fallback"] > 0
    assert held.metrics.final_s < 45.0 - 2.25  # stopped behind the held car
    assert gone.metrics.final_s > 45.0 + 2.25 and gone.metrics.collisions == 0  # drove through where it was
    seen = [[oid for oid, _ in step.obstacles] for step in gone.steps]
    assert seen[10] == ["ahead"] and all(ids == [] for ids in seen[11:])  # from the cycle after t = 1 s
    assert sim.in_scene(problem, {}, 5.0) is problem
    assert sim.in_scene(problem, {"ahead": 1.0}, 1.0) is problem  # still there at its last state
    assert sim.in_scene(problem, {"ahead": 1.0}, 1.1).obstacles == ()


def test_each_cycles_request_carries_the_goal_with_its_times_from_now() -> None:
    goal = PlannerGoal(time=(3.0, 4.0), speed=(0.0, 2.0))
    problem = replace(PlanningProblem(straight(60.0), Lane(3.5, 3.5), Ego(0.0, 0.0, 0.0)), goal=goal)
    asked = problem_at(problem, replace(_start(3.0), t=1.5))
    assert asked.goal == PlannerGoal(time=(1.5, 2.5), speed=(0.0, 2.0))
    assert problem_at(problem, _start(3.0)).goal == goal


def test_a_planning_error_brakes_instead_of_crashing(monkeypatch: pytest.MonkeyPatch) -> None:
    def failing(problem: PlanningProblem) -> None:
        raise PlannerError("no luck")

    monkeypatch.setattr(sim, "plan", failing)
    problem = PlanningProblem(straight(100.0), Lane(3.5, 3.5), Ego(10.0, 0.0, 0.0, speed=6.0))
    result = simulate(problem, duration=0.5)
    assert [st.status for st in result.steps] == ["error"] * 5
    assert result.steps[0].message == "no luck"
    assert result.metrics.status_counts["error"] == 5
    assert result.motion.v[-1] == pytest.approx(6.0 - problem.vehicle.max_deceleration * 0.5)
    assert result.metrics.termination == "timeout"


def test_bad_settings_are_domain_errors() -> None:
    problem = PlanningProblem(straight(50.0), Lane(3.5, 3.5), Ego(0.0, 0.0, 0.0))
    with pytest.raises(InvalidInputError):
        simulate(problem, duration=0.0)
    with pytest.raises(InvalidInputError):
        simulate(problem, replan_period=-0.1)
