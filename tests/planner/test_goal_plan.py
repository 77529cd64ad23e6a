"""The goal in the plan: stopping inside a region, being inside in a time window (hurrying up to the speed
limit, slowing down not to be early), a region beside the reference, a goal beyond a parked car in a
curve; and the pieces (the speed cap, the candidates' term, the moved offsets, the speed terms).

Every trajectory is checked by the independent checker of :mod:`tests.planner.test_scenarios` and the goal
by :func:`tests.planner.goal_cases.meets`, not by the planner's own judgement.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planner.candidates import generate_candidates
from planner.collision import frenet_boxes
from planner.config import DEFAULT_CONFIG
from planner.ego import start_state
from planner.goal import Goal, GoalCircle, GoalStatus
from planner.goal_plan import (
    candidate_cost,
    candidate_options,
    goal_setup,
    reach,
    slow_distance,
    speed_aim,
    stop_distance,
    toward_region,
)
from planner.goal_region import inside
from planner.pipeline import plan
from planner.problem import Ego, Lane, Options, PlanningProblem, PolygonObstacle
from planner.reference import build_reference
from planner.st_bounds import static_shapes
from planner.trajectory import frenet_path
from tests.planner.goal_cases import EGO_X, box, meets, straight_problem
from tests.planner.scenario_roads import Road, arc_piece, box_on_road, straight_piece
from tests.planner.test_scenarios import _vehicle, planned


@pytest.fixture(params=["point", "car"])
def model(request: pytest.FixtureRequest) -> str:
    return str(request.param)


# -- whole plans -------------------------------------------------------------------------------


def test_stops_inside_a_goal_region_50_to_60_m_ahead(model: str) -> None:
    region = box(EGO_X + 50.0, EGO_X + 60.0, -1.75, 1.75)
    goal = Goal(region, speed=(0.0, 0.0))
    problem = straight_problem(goal, model=model)
    free = plan(straight_problem(model=model))
    assert free.trajectory.x[-1] > EGO_X + 70.0  # without the goal it drives on
    result = planned(problem)
    assert result.status == "ok", result.message
    traj = result.trajectory
    assert traj.v[-1] < 1e-3 and abs(traj.a[-1]) < 0.05  # it ends standing
    held = meets(goal, traj)
    assert held[-1] and result.diagnostics.goal is not None
    assert result.diagnostics.goal.status is GoalStatus.REACHED
    assert result.diagnostics.goal.t == pytest.approx(traj.t[np.argmax(held)])
    # within limits (the checker), and it did not brake harder than it had to
    assert traj.a.min() >= -problem.vehicle.max_deceleration - 1e-6


def test_is_inside_between_6_and_8_s_when_the_target_alone_would_be_late(model: str) -> None:
    # 95–115 m ahead: at its target of 10 m/s the vehicle is 80 m on at 8 s
    region = box(EGO_X + 95.0, EGO_X + 115.0, -1.75, 1.75)
    goal = Goal(region, time=(6.0, 8.0))
    free = plan(straight_problem(model=model))
    assert not meets(goal, free.trajectory).any()
    result = planned(straight_problem(goal, model=model, speed_limit=16.0))
    assert result.status == "ok", result.message
    held = meets(goal, result.trajectory)
    assert held.any(), "not inside in the window"
    report = result.diagnostics.goal
    assert report is not None and report.status is GoalStatus.REACHED
    assert report.t == pytest.approx(result.trajectory.t[np.argmax(held)])
    v = result.trajectory.v
    assert v.max() > 10.5  # faster than the target …
    assert v.max() <= 16.0 + 1e-3  # … within the speed limit
    # without a speed limit above the target it cannot be done, and the plan says so
    late = plan(straight_problem(goal, model=model))
    assert not meets(goal, late.trajectory).any()
    assert late.diagnostics.goal is not None and late.diagnostics.goal.reason == "too_far"
    assert late.trajectory.v.max() <= 10.0 + 1e-3


def test_slows_down_not_to_be_early(model: str) -> None:
    # 35–50 m ahead: at 10 m/s the vehicle would be through it by 5 s
    region = box(EGO_X + 35.0, EGO_X + 50.0, -1.75, 1.75)
    goal = Goal(region, time=(6.0, 8.0))
    free = plan(straight_problem(model=model))
    assert not meets(goal, free.trajectory).any()
    result = planned(straight_problem(goal, model=model))
    held = meets(goal, result.trajectory)
    assert held.any(), "not inside in the window"
    assert result.diagnostics.goal is not None and result.diagnostics.goal.status is GoalStatus.REACHED
    at_6 = np.flatnonzero(np.isclose(result.trajectory.t, 6.0))[0]
    assert result.trajectory.x[at_6] < free.trajectory.x[at_6] - 10.0  # it slowed down
    assert result.trajectory.v.min() > 0.5  # … without stopping: the goal asks for no stop


def test_a_goal_region_beside_the_reference_is_driven_into(model: str) -> None:
    # the left half of the lane, 50–70 m ahead: the reference runs outside it
    region = box(EGO_X + 50.0, EGO_X + 70.0, 1.2, 3.5)
    goal = Goal(region)
    free = plan(straight_problem(model=model))
    assert np.abs(free.trajectory.d).max() < 0.3 and not meets(goal, free.trajectory).any()
    result = planned(straight_problem(goal, model=model))
    assert result.status == "ok", result.message
    held = meets(goal, result.trajectory)
    assert held.any(), f"never inside; largest offset {result.trajectory.d.max():.2f} m"
    assert result.diagnostics.goal is not None and result.diagnostics.goal.status is GoalStatus.REACHED


def test_a_region_beside_the_reference_filled_by_a_parked_car_is_not_driven_into() -> None:
    region = box(EGO_X + 50.0, EGO_X + 70.0, 1.2, 3.5)
    car = PolygonObstacle("parked", np.array([[55.0, 1.0], [75.0, 1.0], [75.0, 3.4], [55.0, 3.4]]))
    problem = replace(straight_problem(Goal(region)), obstacles=(car,))
    result = planned(problem)  # clear of the car (the checker)
    assert result.status == "ok", result.message
    report = result.diagnostics.goal
    assert report is not None
    if meets(problem.goal, result.trajectory).any():  # type: ignore[arg-type]
        assert report.status is GoalStatus.REACHED  # (the car leaves 50–55 m free: it may get in there)
    else:
        assert report.status is GoalStatus.UNREACHABLE and report.reason == "missed"


def test_a_goal_beyond_a_parked_car_in_a_curve(model: str) -> None:
    road = Road([straight_piece(20.0), arc_piece(40.0, np.radians(90.0)), straight_piece(60.0)])
    # a car parked on the right of the lane in the curve, reaching 1.2 m into its 3.5 m half
    parked = PolygonObstacle("parked", box_on_road(road, 40.0, -3.5 + 1.2 + 0.9, 4.5, 1.8))
    goal = Goal(GoalCircle(road.point(67.0, 0.0), 3.0), speed=(0.0, 0.5))
    x0, y0, h0 = road.pose(10.0)
    problem = PlanningProblem(
        reference_line=road.polyline(1.0),
        lane=Lane(3.5, 3.5),
        ego=Ego(x0, y0, h0, 8.0),
        obstacles=(parked,),
        vehicle=_vehicle(model),
        options=Options(horizon_time=10.0, target_speed=8.0),
        goal=goal,
    )
    result = planned(problem)  # clear of the car, within the lane and the limits
    assert result.status == "ok", result.message
    traj = result.trajectory
    held = meets(goal, traj)
    assert held.any() and held[-1] and traj.v[-1] < 0.5, "does not end inside, slow"
    assert result.diagnostics.goal is not None and result.diagnostics.goal.status is GoalStatus.REACHED
    assert inside(goal.position, traj.x[-1:], traj.y[-1:])[0]  # type: ignore[arg-type]


def test_a_goal_far_ahead_is_on_the_way_and_changes_nothing_before_it() -> None:
    goal = Goal(box(300.0, 320.0, -1.75, 1.75), speed=(0.0, 0.0))
    free = plan(straight_problem())
    result = planned(straight_problem(goal))
    assert result.diagnostics.goal is not None and result.diagnostics.goal.status is GoalStatus.ON_THE_WAY
    np.testing.assert_allclose(result.trajectory.x, free.trajectory.x, atol=0.05)


def test_without_a_goal_the_diagnostics_have_none() -> None:
    assert plan(straight_problem()).diagnostics.goal is None


# -- the pieces --------------------------------------------------------------------------------


def test_the_speed_cap_is_the_speed_limit_only_where_the_goal_needs_it() -> None:
    ref = build_reference(straight_problem().reference_line)
    region = box(100.0, 110.0, -1.0, 1.0)
    cases = [
        (Goal(region), 16.0, 10.0),  # no window: the target is the cap
        (Goal(region, time=(6.0, 8.0)), 16.0, 16.0),  # a window: up to the limit
        (Goal(region, time=(6.0, 8.0)), None, 10.0),  # no limit given: the target is the limit
        (Goal(speed=(12.0, 14.0)), 16.0, 16.0),  # a range above the target
    ]
    for goal, limit, cap in cases:
        setup = goal_setup(ref, straight_problem(goal, speed_limit=limit))
        assert setup is not None and setup.cap == cap, goal
    fast = goal_setup(ref, straight_problem(Goal(speed=(12.0, 14.0)), speed_limit=16.0))
    assert fast is not None and fast.v_target == 12.0  # cruises at the range's low end
    slow = goal_setup(ref, straight_problem(Goal(speed=(2.0, 4.0))))
    assert slow is not None and slow.v_target == 4.0
    capped = straight_problem(Goal(region, time=(6.0, 8.0)), speed_limit=16.0)
    setup = goal_setup(ref, capped)
    assert candidate_options(setup, capped.options).target_speed == 16.0  # the candidates reach as far
    assert candidate_options(None, capped.options) is capped.options


@pytest.mark.parametrize(("v", "a"), [(10.0, 0.0), (10.0, 1.5), (3.0, -2.0), (8.0, -5.0), (25.0, 0.0)])
def test_the_stop_distance_is_the_speed_profiles_braking_margin(v: float, a: float) -> None:
    decel, jerk = 3.0, 8.0
    # simulated: release a positive acceleration, ramp to −decel at the jerk (or hold a harder brake)
    dt, s, speed, acc = 1e-4, 0.0, v, a
    target = -max(decel, -a)
    while speed > 0.0:
        acc = max(acc - jerk * dt, target)
        speed += acc * dt
        s += max(speed, 0.0) * dt
    assert stop_distance(v, a, decel, jerk) >= s - 0.05  # never short of it …
    if a <= 0.0:  # … exact when braking already
        assert stop_distance(v, a, decel, jerk) == pytest.approx(s, abs=0.01)
    else:  # … and not much beyond it after releasing an acceleration
        assert stop_distance(v, a, decel, jerk) <= s + 0.05 + v * a / jerk
    assert slow_distance(v, a, v + 1.0 + max(a, 0.0), decel, jerk) == 0.0
    assert 0.0 < slow_distance(v, a, 0.5 * v, decel, jerk) < stop_distance(v, a, decel, jerk)


def test_reach_is_the_farthest_drive() -> None:
    assert reach(10.0, 2.0, 16.0, 8.0) == pytest.approx(10.0 * 3.0 + 9.0 + 16.0 * 5.0)
    assert reach(20.0, 2.0, 16.0, 2.0) == pytest.approx(40.0)  # faster than the cap: kept
    assert reach(0.0, 2.0, 16.0, 2.0) == pytest.approx(4.0)
    assert reach(5.0, 2.0, 16.0, -1.0) == 0.0


def _stages(problem: PlanningProblem) -> tuple:  # type: ignore[type-arg]
    ref = build_reference(problem.reference_line)
    start = start_state(ref, problem)
    setup = goal_setup(ref, problem)
    cands = generate_candidates(
        ref,
        problem.lane,
        problem.ego,
        problem.vehicle,
        candidate_options(setup, problem.options),
        start=start,
    )
    return ref, start, setup, cands


def test_candidates_running_into_a_region_beside_the_reference_cost_less() -> None:
    problem = straight_problem(Goal(box(EGO_X + 50.0, EGO_X + 70.0, 1.2, 3.5)))
    ref, _, setup, cands = _stages(problem)
    cost = candidate_cost(setup, cands, problem)
    assert cost is not None and cost.shape == (cands.count,)
    end = np.array([cands.points(i)[1][-1] for i in range(cands.count)])
    # those ending inside the region's offsets cost nothing, those on the right the most
    assert np.all(cost[end > 1.8] < cost[end < -1.0].min())
    assert candidate_cost(None, cands, problem) is None
    plain = goal_setup(ref, straight_problem(Goal(box(EGO_X + 50.0, EGO_X + 70.0, -1.0, 1.0))))
    lane_wide = candidate_cost(plain, cands, problem)
    assert lane_wide is not None and np.all(lane_wide[np.abs(end) < 0.5] == 0.0)


def test_offsets_move_into_the_region_unless_that_meets_an_obstacle() -> None:
    region = box(EGO_X + 50.0, EGO_X + 70.0, 1.2, 3.5)
    problem = straight_problem(Goal(region))
    ref, start, setup, _ = _stages(problem)
    s = np.linspace(start.s, start.s + 120.0, 241)
    d = np.zeros_like(s)
    empty = frenet_boxes(ref, [])
    moved = toward_region(setup, ref, s, d, empty, problem)
    over = (s >= EGO_X + 50.0) & (s <= EGO_X + 70.0)
    assert np.all(moved[over] >= 1.2 + 0.3) and np.all(moved[over] <= 3.5 - 0.9 - 0.2 + 1e-9)
    assert np.all(moved[s < EGO_X + 50.0 - 1.5 * 10.0 - 1e-9] == 0.0)  # blended in over 1.5 s of driving
    assert np.all(np.diff(moved[s < EGO_X + 50.0]) >= -1e-12)
    assert np.all(moved[s > EGO_X + 70.0 + 0.5] == 0.0)  # back to the candidate's after it (the QP smooths)
    assert toward_region(None, ref, s, d, empty, problem) is d
    car = PolygonObstacle("parked", np.array([[55.0, 1.0], [75.0, 1.0], [75.0, 3.4], [55.0, 3.4]]))
    blocked = replace(problem, obstacles=(car,))
    boxes = frenet_boxes(ref, static_shapes(blocked))
    assert toward_region(setup, ref, s, d, boxes, blocked) is d


def test_the_speed_terms_stop_inside_and_bound_the_window_at_its_knots() -> None:
    region = box(EGO_X + 50.0, EGO_X + 60.0, -1.75, 1.75)
    problem = straight_problem(Goal(region, time=(6.0, 8.0), speed=(0.0, 0.0)))
    ref, start, setup, _ = _stages(problem)
    s = np.linspace(start.s, start.s + 150.0, 301)
    path = frenet_path(ref, s, 0 * s, 0 * s, 0 * s)
    aim = speed_aim(setup, path, problem)
    assert aim is not None
    margin = DEFAULT_CONFIG.goal.margin
    assert 50.0 + margin - 1e-6 <= aim.stop <= 60.0 - margin + 1e-6  # a stop inside (σ from the ego)
    assert aim.upper is None  # a stop inside may arrive early: it waits
    assert aim.lower is not None
    k = np.flatnonzero(np.isfinite(aim.lower)).tolist()
    assert 75 in k  # the window: 8 s less its margin (0.5 s), on the 0.1 s grid
    assert aim.lower[75] == pytest.approx(50.0 + margin, abs=0.1)
    # and the comfortable approach: at the stop about 7.3 s from now (cruise 3.2 s, brake at 3 m/s²)
    (approach,) = set(k) - {75}
    assert 6.5 <= approach * 0.1 <= 8.0 and aim.lower[approach] == aim.stop
    through = straight_problem(Goal(region, time=(6.0, 8.0), speed=(3.0, 5.0)))
    aim = speed_aim(goal_setup(ref, through), path, through)
    assert aim is not None and aim.stop == np.inf and aim.upper is not None
    assert np.flatnonzero(np.isfinite(aim.upper)).tolist() == [65]  # 6 s and the window's margin
    assert aim.ceiling is not None  # the range's top over the region, and the braking curve before it
    over = (path.sigma >= 50.0 + margin) & (path.sigma <= 59.9)
    assert np.all(aim.ceiling[over] <= 5.0 + 1e-9) and np.all(np.isinf(aim.ceiling[path.sigma > 60.1]))
    assert np.all(np.diff(aim.ceiling[path.sigma < 50.0]) <= 1e-12)
    assert speed_aim(None, path, through) is None


def _closed_loop(problem: PlanningProblem, seconds: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Replan every 0.1 s from the plan's own state 0.1 s on (perfect tracking), the goal's window
    moving with the clock: the times, and the centre's x and speed then."""
    goal = problem.goal
    assert goal is not None
    t, x, v = [], [], []
    for k in range(round(seconds / 0.1)):
        now = 0.1 * k
        window = None if goal.time is None else (goal.time[0] - now, goal.time[1] - now)
        traj = plan(replace(problem, goal=replace(goal, time=window))).trajectory
        t.append(now)
        x.append(traj.x[0])
        v.append(traj.v[0])
        ego = Ego(traj.x[1], traj.y[1], traj.heading[1], traj.v[1], traj.a[1], traj.curvature[1])
        problem = replace(problem, ego=ego)
    return np.array(t), np.array(x), np.array(v)


def test_in_closed_loop_a_stop_inside_stays_put_and_a_window_is_met() -> None:
    # the stop: at the region's entry once and for all (a stop point relative to the vehicle would creep on)
    stop = straight_problem(Goal(box(EGO_X + 50.0, EGO_X + 60.0, -1.75, 1.75), speed=(0.0, 0.0)))
    t, x, v = _closed_loop(stop, 10.0)
    standing = t >= 8.0
    assert np.all(v[standing] < 1e-3), v[standing]
    assert np.all((x[standing] >= EGO_X + 50.0) & (x[standing] <= EGO_X + 60.0))
    assert np.ptp(x[standing]) < 1e-3
    # the window: inside between 6 and 8 s (from the start), above the target, within the limit
    region = box(EGO_X + 95.0, EGO_X + 115.0, -1.75, 1.75)
    hurry = straight_problem(Goal(region, time=(6.0, 8.0)), speed_limit=16.0)
    t, x, v = _closed_loop(hurry, 8.05)
    inside_then = (x >= EGO_X + 95.0) & (x <= EGO_X + 115.0) & (t >= 6.0 - 1e-9)
    assert inside_then.any() and v.max() <= 16.0 + 1e-3


def test_a_speed_range_from_0_reaching_higher_allows_a_stop_but_does_not_ask_for_one(model: str) -> None:
    # a long region 30–200 m ahead, to be inside 10–10.5 s from now at 0–9 m/s: at its target of 10 m/s
    # the vehicle drives in and on (it is inside then at a speed in the range after easing to 9 m/s)
    region = box(EGO_X + 30.0, EGO_X + 200.0, -1.75, 1.75)
    goal = Goal(region, time=(10.0, 10.5), speed=(0.0, 9.0))
    problem = straight_problem(goal, model=model)
    setup = goal_setup(build_reference(problem.reference_line), problem)
    assert setup is not None and not setup.stops_inside
    result = planned(problem)
    assert result.status == "ok", result.message
    assert result.trajectory.v.min() > 5.0  # it does not stop at the region's entry
    report = result.diagnostics.goal
    assert report is not None and report.status is GoalStatus.ON_THE_WAY, report
    # a range from 0 to below the stop speed is a stop
    slow = straight_problem(Goal(region, speed=(0.0, 0.5 * DEFAULT_CONFIG.goal.stop_speed)), model=model)
    slow_setup = goal_setup(build_reference(slow.reference_line), slow)
    assert slow_setup is not None and slow_setup.stops_inside


def test_a_stop_inside_keeps_its_approach_when_the_window_lies_beyond_the_horizon() -> None:
    # stop 50–60 m ahead, inside 20–21 s from now: the window asks nothing within the 8 s horizon, the
    # stop's own approach bound stays (without it the profile may dawdle and stop short of the region)
    region = box(EGO_X + 50.0, EGO_X + 60.0, -1.75, 1.75)
    problem = straight_problem(Goal(region, time=(20.0, 21.0), speed=(0.0, 0.0)))
    ref, start, setup, _ = _stages(problem)
    s = np.linspace(start.s, start.s + 150.0, 301)
    path = frenet_path(ref, s, 0 * s, 0 * s, 0 * s)
    aim = speed_aim(setup, path, problem)
    assert aim is not None and aim.lower is not None
    k = np.flatnonzero(np.isfinite(aim.lower))
    assert k.size == 1 and aim.lower[k[0]] == aim.stop


def test_offsets_blend_into_a_region_beyond_a_parked_car_after_the_car() -> None:
    # a car parked in the right of the lane 27–32 m ahead; the candidate passes it on the left (d = 2.3)
    # and stays at d = 2, beside the region (the lane up to d = 1, from 40 m ahead on): the blend into
    # the region (1.5 s at 10 m/s before it) would begin on the car, so it begins after the car
    region = box(EGO_X + 40.0, EGO_X + 115.0, -1.75, 1.0)
    car = PolygonObstacle("parked", np.array([[37.0, -1.75], [42.0, -1.75], [42.0, 0.6], [37.0, 0.6]]))
    problem = replace(straight_problem(Goal(region, time=(3.5, 4.5))), obstacles=(car,))
    ref, _, setup, _ = _stages(problem)
    s = np.linspace(EGO_X, EGO_X + 120.0, 241)
    d = np.interp(s, [EGO_X, 30.0, 36.0, 43.0, 48.0], [0.0, 0.0, 2.3, 2.3, 2.0])
    boxes = frenet_boxes(ref, static_shapes(problem))
    moved = toward_region(setup, ref, s, d, boxes, problem)
    assert moved is not d
    by_car = s <= 42.0 + 0.5 * problem.vehicle.length
    assert np.array_equal(moved[by_car], d[by_car])  # not moved where it passes the car
    over = (s >= EGO_X + 40.0) & (s <= EGO_X + 110.0)
    assert np.all(moved[over] < 1.0)  # inside (the aim's margin in, scaled against the QP's pull)
