"""The lane decision (issue 14): keep the lane, or borrow the road beyond it to get past what blocks it.

Scenes on a two-lane road (right-hand traffic: the opposite lane on the left, `planner.roads`): a
lane-wide parked truck with the opposite lane free (passes and returns), the same with an oncoming car
(waits, never shares the opposite lane with it), a slow tractor on a straight (overtakes when clear), a
right-hand hairpin tighter than the vehicle's smallest radius inside its lane (swings into the opposite
lane), each without `road` (stops or follows as before), and the car model where it matters.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planner import pipeline
from planner.candidates import generate_candidates
from planner.collision import box_corners, obstacle_shape, prediction_at
from planner.config import DEFAULT_CONFIG
from planner.decision import BlockKind, LaneChoice, ReasonKind
from planner.frenet import to_cartesian, to_frenet
from planner.goal import Goal as RequestGoal
from planner.goal import GoalPolygon
from planner.lateral import LateralPlan
from planner.pipeline import plan
from planner.problem import DynamicObstacle, Ego, Lane, Obstacle, PlanningProblem, Road, Vehicle
from planner.reference import build_reference
from planner.result import PlanResult
from planner.roads import (
    HALF_LANE,
    arc,
    box,
    demo_problem,
    driving,
    hairpin,
    straight,
    two_lane_problem,
    wide_u_turn_problem,
)
from planner.validation import ViolationKind, folds_back, trajectory_violations
from planner_tools.loops import along_reference
from planner_tools.sim import Goal, SimResult, simulate

#: the car of the issue: planned at its rear axle
CAR = Vehicle(wheelbase=2.7, rear_axle_offset=1.35)
VEHICLES = [pytest.param(None, id="point"), pytest.param(CAR, id="car")]


def truck(*extra: object, road: bool = True, vehicle: Vehicle | None = None) -> PlanningProblem:
    """A lane-wide truck parked 54–66 m ahead on a straight road, the ego at 10 m/s."""
    obstacles = (box("truck", 60.0, 0.0, 12.0, 3.2), *extra)
    return two_lane_problem(straight(200.0), obstacles=obstacles, road=road, vehicle=vehicle)  # type: ignore[arg-type]


def tractor(road: bool = True) -> PlanningProblem:
    """A 6 × 2.5 m tractor at 3 m/s 37 m ahead in the lane, the ego at 12 m/s."""
    slow = driving("tractor", 40.0, 0.0, 3.0, length=6.0, width=2.5)
    return two_lane_problem(straight(200.0), speed=12.0, obstacles=(slow,), road=road)


def tight_hairpin(road: bool = True, vehicle: Vehicle | None = None) -> PlanningProblem:
    """A right-hand U-turn of radius 4 m, tighter than the vehicle's 5 m, 15 m ahead of the ego at 5 m/s."""
    reference = hairpin(4.0, leg=15.0)
    return two_lane_problem(reference, speed=5.0, road=road, vehicle=vehicle)


def in_road(problem: PlanningProblem, result: PlanResult) -> None:
    """The answer passes every check: in the road, and in the lane unless it borrows."""
    ref = build_reference(problem.reference_line)
    static = [(ob.id, obstacle_shape(ob)) for ob in problem.obstacles]
    borrowing = result.diagnostics.decision.borrows
    assert trajectory_violations(ref, problem, result.trajectory, static, borrowing=borrowing) == []


def corners_d(run: SimResult) -> np.ndarray:
    """Every driven sample's footprint corners' offsets d [m], shape (n, 4)."""
    m, v = run.motion, run.problem.vehicle
    corners = box_corners(m.x, m.y, m.yaw, v.length, v.width).reshape(-1, 2)
    return np.asarray(to_frenet(run.reference, corners).d.reshape(-1, 4))


def test_nothing_in_the_way_keeps_the_lane() -> None:
    decision = plan(demo_problem()).diagnostics.decision
    assert decision.lane is LaneChoice.KEEP
    assert decision.reason.kind is ReasonKind.LANE_FREE
    assert decision.reason.message == "the lane is free"
    free = plan(two_lane_problem(straight(200.0))).diagnostics.decision
    assert free.lane is LaneChoice.KEEP and free.reason.kind is ReasonKind.LANE_FREE


def test_a_parked_truck_without_road_stops_as_before_and_says_what_blocks() -> None:
    result = plan(truck(road=False))
    assert result.status == "stopped"
    assert result.message.startswith("the road is blocked")
    reason = result.diagnostics.decision.reason
    assert result.diagnostics.decision.lane is LaneChoice.KEEP
    assert (reason.kind, reason.block, reason.obstacle_id) == (
        ReasonKind.NO_ROAD,
        BlockKind.OBSTACLE,
        "truck",
    )
    assert "obstacle truck blocks the lane" in reason.message
    assert "obstacle truck blocks the lane" in result.message  # the answer names what blocks


def test_a_parked_truck_with_the_opposite_lane_free_is_passed_on_the_left() -> None:
    problem = truck()
    result = plan(problem)
    decision = result.diagnostics.decision
    assert result.status == "ok"
    assert decision.lane is LaneChoice.BORROW_LEFT
    assert (decision.reason.kind, decision.reason.block) == (ReasonKind.PASSING, BlockKind.OBSTACLE)
    assert decision.reason.obstacle_id == "truck" and 45.0 < (decision.reason.s or 0.0) < 60.0
    assert "obstacle truck blocks the lane" in result.message
    assert float(np.max(result.trajectory.d)) > HALF_LANE  # into the opposite lane
    in_road(problem, result)


@pytest.mark.parametrize("vehicle", VEHICLES)
def test_a_parked_truck_is_passed_and_the_lane_taken_again(vehicle: Vehicle | None) -> None:
    run = simulate(truck(vehicle=vehicle), duration=16.0, goal=Goal(s_min=100.0))
    m = run.metrics
    assert m.termination == "goal" and m.collisions == 0
    assert m.status_counts["fallback"] == m.status_counts["error"] == 0
    assert m.max_lane_departure > 1.0  # it used the opposite lane
    assert m.max_road_departure <= 1e-3  # never off the road
    d = corners_d(run)
    assert abs(float(run.motion.d[-1])) < 0.3 and np.all(np.abs(d[-1]) <= HALF_LANE)  # back in its lane
    borrowed = [st for st in run.steps if st.decision is not None and st.decision.borrows]
    assert borrowed and run.steps[-1].decision is not None and not run.steps[-1].decision.borrows


def test_an_oncoming_car_is_waited_for_and_never_met_in_the_opposite_lane() -> None:
    car = driving("car", 160.0, 2.0 * HALF_LANE, -10.0)
    problem = truck(car)
    first = plan(problem)
    decision = first.diagnostics.decision
    assert first.status == "stopped" and decision.lane is LaneChoice.KEEP
    assert decision.reason.kind is ReasonKind.ONCOMING and decision.reason.oncoming_id == "car"
    assert decision.reason.obstacle_id == "truck" and decision.reason.t is not None
    assert "waiting" in first.message
    in_road(problem, first)
    run = simulate(problem, duration=30.0, goal=Goal(s_min=100.0))
    assert run.metrics.termination == "goal" and run.metrics.collisions == 0
    assert run.metrics.max_road_departure <= 1e-3
    # whenever a corner of the ego is in the opposite lane, the car has passed it
    out = np.any(corners_d(run) > HALF_LANE + 1e-3, axis=1)
    assert out.any()
    car_front = prediction_at(car, run.motion.t)[:, 0] - 0.5 * car.length
    ego_rear = run.motion.x - 0.5 * problem.vehicle.length
    assert np.all(car_front[out] < ego_rear[out])


def test_an_ego_already_in_the_opposite_lane_goes_back_and_waits_when_a_car_comes() -> None:
    car = driving("car", 160.0, 2.0 * HALF_LANE, -10.0)
    problem = truck(car)
    problem = replace(problem, ego=replace(problem.ego, y=2.0 * HALF_LANE))  # in the opposite lane
    result = plan(problem)
    decision = result.diagnostics.decision
    assert result.status == "stopped" and decision.lane is LaneChoice.BORROW_LEFT  # still outside
    assert decision.reason.kind is ReasonKind.ONCOMING and decision.reason.oncoming_id == "car"
    in_road(problem, result)
    # back in its lane (the footprint within it), stopped before the truck
    traj = result.trajectory
    assert abs(float(traj.d[-1])) + 0.5 * problem.vehicle.width < HALF_LANE
    assert float(traj.v[-1]) < 0.05 and float(traj.x[-1]) + 2.25 < 54.0


def test_a_slow_tractor_is_overtaken_when_the_opposite_lane_is_clear() -> None:
    problem = tractor()
    first = plan(problem)
    decision = first.diagnostics.decision
    assert decision.lane is LaneChoice.BORROW_LEFT
    assert (decision.reason.block, decision.reason.obstacle_id) == (BlockKind.SLOW_VEHICLE, "tractor")
    assert decision.passing == frozenset({"tractor"})
    run = simulate(problem, duration=14.0, goal=Goal(s_min=120.0))
    m = run.metrics
    assert m.termination == "goal" and m.collisions == 0 and m.max_road_departure <= 1e-3
    tractor_front = 40.0 + 3.0 * float(run.motion.t[-1]) + 3.0
    assert float(run.motion.x[-1]) - 2.25 > tractor_front  # ahead of it
    assert abs(float(run.motion.d[-1])) < 0.3  # back in its lane


def leaving_at(monkeypatch: pytest.MonkeyPatch, s: float) -> list[float]:
    """Make the plan in the lane leave it at its first knot at or beyond ``s`` [m] with nothing in the
    way there (:attr:`LateralPlan.leaves`, as a path steeper than its bounds' heading does); the list
    gets that knot's arc length [m]."""
    real = pipeline.lateral_stage
    leave_s: list[float] = []

    def leaving(*args: object, **kwargs: object) -> LateralPlan:
        plan = real(*args, **kwargs)  # type: ignore[arg-type]
        if leave_s or "lane" in kwargs:  # a borrow's plan
            return plan
        knot = int(np.searchsorted(plan.bounds.s, s))
        leave_s.append(float(plan.bounds.s[knot]))
        return replace(plan, blocked=knot, leaves=True)

    monkeypatch.setattr(pipeline, "lateral_stage", leaving)
    return leave_s


def test_a_lane_plan_leaving_the_lane_on_its_way_to_a_slow_tractor_passes_the_tractor(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Mid-swerve round the tractor the lane plan's path leaves the lane 15 m ahead with nothing in the way
    # there (its own heading): that is no bend to borrow the road for with the tractor as traffic in it,
    # the tractor is what the borrow passes (before, "oncoming tractor": stop in the lane, then fall back)
    leave_s = leaving_at(monkeypatch, 15.0)
    decision = plan(tractor()).diagnostics.decision
    assert decision.lane is LaneChoice.BORROW_LEFT and decision.reason.kind is ReasonKind.PASSING
    assert (decision.reason.block, decision.reason.obstacle_id) == (BlockKind.SLOW_VEHICLE, "tractor")
    assert decision.passing == frozenset({"tractor"})
    # the borrow from where the lane plan leaves the lane
    assert decision.corridor is not None and decision.corridor.start <= leave_s[0] + 1e-9


def test_a_lane_plan_leaving_the_lane_behind_a_tractor_it_cannot_pass_swings_out_for_the_bend(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The lane plan's path leaves the lane 15 m ahead with nothing in the way there (a bend tighter than
    # the car can take in its lane, say); the tractor 77 m ahead is not passed within the horizon. That
    # is no reason to stop at the bend (before: "no way back" past the tractor, stopped there, the way a
    # car with a recorded car close behind was run into at a right angle, DEU_Lohmar-26 converted from
    # its XML): the decision is the bend's, out through the road and back behind the tractor.
    leave_s = leaving_at(monkeypatch, 15.0)
    slow = driving("tractor", 80.0, 0.0, 3.0, length=6.0, width=2.5)
    problem = two_lane_problem(straight(200.0), speed=12.0, obstacles=(slow,), road=True)
    result = plan(problem)
    decision = result.diagnostics.decision
    assert result.status == "ok"
    assert decision.lane is LaneChoice.BORROW_LEFT and decision.reason.kind is ReasonKind.PASSING
    assert decision.reason.block is BlockKind.BEND and decision.passing == frozenset()
    assert decision.corridor is not None and decision.corridor.start <= leave_s[0] + 1e-9
    # a tractor it can pass is passed from there (above), and without a road it stops as before
    monkeypatch.undo()
    leaving_at(monkeypatch, 15.0)
    kept = plan(replace(problem, road=None)).diagnostics.decision
    assert kept.lane is LaneChoice.KEEP and kept.reason.kind is ReasonKind.NO_ROAD


@pytest.mark.parametrize(
    ("obstacle", "block"),
    [
        (driving("tractor", 40.0, 0.0, 3.0, length=6.0, width=2.5), BlockKind.SLOW_VEHICLE),
        (box("parked", 40.0, 0.0, 4.5, 1.8), BlockKind.OBSTACLE),
    ],
)
def test_a_lane_plan_leaving_the_lane_before_a_vehicle_names_the_vehicle_not_a_bend(
    monkeypatch: pytest.MonkeyPatch, obstacle: Obstacle, block: BlockKind
) -> None:
    # without road, the lane plan's path leaving the lane where its front is 5 m short of what it swerves
    # round (a straight: no bend) stops there, and the answer says what blocks: the vehicle, moving or
    # parked (its rear at 37.75 m; the front 2.25 m ahead of the planned point)
    leaving_at(monkeypatch, 37.75 - 5.0 - 2.25)
    problem = two_lane_problem(straight(200.0), speed=12.0, obstacles=(obstacle,), road=False)
    reason = plan(problem).diagnostics.decision.reason
    assert (reason.kind, reason.block, reason.obstacle_id) == (ReasonKind.NO_ROAD, block, obstacle.id)


def lane_region(x0: float, x1: float) -> RequestGoal:
    """A goal region across the lane (and only it) from ``x0`` to ``x1`` [m] along the straight road."""
    corners = [[x0, -HALF_LANE], [x1, -HALF_LANE], [x1, HALF_LANE], [x0, HALF_LANE]]
    return RequestGoal(GoalPolygon(np.array(corners)))


@pytest.mark.parametrize("problem", [truck(), tractor()], ids=["parked truck", "slow tractor"])
def test_a_goal_in_the_lane_before_the_block_is_reached_in_the_lane_not_through_the_road(
    problem: PlanningProblem,
) -> None:
    # passing the block would not bring the goal nearer (and would drive past it beside the lane)
    before = plan(replace(problem, goal=lane_region(20.0, 32.0))).diagnostics.decision
    assert before.lane is LaneChoice.KEEP and before.reason.kind is ReasonKind.GOAL_FIRST
    assert before.reason.obstacle_id in {"truck", "tractor"}
    assert "the goal lies in the lane before it" in before.reason.message
    beyond = plan(replace(problem, goal=lane_region(100.0, 112.0))).diagnostics.decision
    assert beyond.lane is LaneChoice.BORROW_LEFT
    # one already behind the vehicle says nothing about the block ahead
    passed = replace(
        problem, goal=lane_region(-20.0, -10.0), reference_line=problem.reference_line - [30.0, 0.0]
    )
    assert plan(passed).diagnostics.decision.lane is LaneChoice.BORROW_LEFT


def test_a_goal_before_a_bend_too_tight_for_the_lane_still_swings_out() -> None:
    # the swing-out is how the vehicle gets round the bend, not a pass beside the lane
    problem = replace(tight_hairpin(), goal=lane_region(-12.0, -5.0))  # its leg runs from x = −15 m
    assert plan(problem).diagnostics.decision.lane is plan(tight_hairpin()).diagnostics.decision.lane


def test_a_goal_before_a_parked_truck_is_reached_and_the_lane_kept() -> None:
    problem = replace(truck(), goal=lane_region(40.0, 50.0))
    run = simulate(problem, duration=10.0)
    inside = (run.motion.x >= 40.0) & (run.motion.x <= 50.0)
    assert inside.any() and run.metrics.collisions == 0
    assert float(np.max(np.abs(run.motion.d))) + 0.5 * problem.vehicle.width < HALF_LANE


def test_without_road_a_slow_tractor_is_followed() -> None:
    result = plan(tractor(road=False))
    assert result.status == "ok"
    assert result.diagnostics.decision.lane is LaneChoice.KEEP
    assert float(np.max(np.abs(result.trajectory.d))) < HALF_LANE


@pytest.mark.parametrize("vehicle", VEHICLES)
def test_a_hairpin_tighter_than_the_vehicle_swings_into_the_opposite_lane(vehicle: Vehicle | None) -> None:
    problem = tight_hairpin(vehicle=vehicle)
    first = plan(problem)
    decision = first.diagnostics.decision
    assert decision.lane is LaneChoice.BORROW_LEFT  # the outside of a right turn
    assert decision.reason.block is BlockKind.BEND and decision.reason.obstacle_id is None
    assert "the bend at s =" in decision.reason.message
    run = simulate(problem, duration=20.0, goal=Goal(s_min=35.0))
    m = run.metrics
    assert m.termination == "goal" and m.status_counts["fallback"] == 0
    assert m.max_lane_departure > 0.3 and m.max_road_departure <= 1e-3


def test_a_car_ahead_going_through_the_hairpin_is_followed_not_waited_for_as_oncoming() -> None:
    # A car 12 m ahead going the same way at 3 m/s swings out through the hairpin too (1.5 m left of the
    # centre line, its side in the opposite lane): no head-on conflict, the borrow follows it (before,
    # the car ahead in the borrowed space was "oncoming" and the vehicle waited for it to be gone).
    problem = tight_hairpin()
    ref = build_reference(problem.reference_line)
    ego_s = float(to_frenet(ref, np.array([[problem.ego.x, problem.ego.y]])).s[0])
    t = np.arange(0.0, 8.05, 0.1)
    ahead = DynamicObstacle("ahead", 4.5, 1.8, along_reference(ref, t, ego_s + 12.0 + 3.0 * t, 1.5))
    result = plan(replace(problem, obstacles=(ahead,)))
    decision = result.diagnostics.decision
    assert decision.lane is LaneChoice.BORROW_LEFT and decision.reason.block is BlockKind.BEND
    assert decision.passing == frozenset()
    in_road(problem, result)  # behind it all the way (the checks' moving obstacles included)
    # one coming the other way is waited for
    towards = DynamicObstacle("towards", 4.5, 1.8, along_reference(ref, t, ego_s + 40.0 - 3.0 * t, 2.0, True))
    waits = plan(replace(problem, obstacles=(towards,))).diagnostics.decision
    assert waits.lane is LaneChoice.KEEP and waits.reason.oncoming_id == "towards"


def test_without_road_the_hairpin_stops_before_the_bend() -> None:
    result = plan(tight_hairpin(road=False))
    assert result.status == "stopped"
    reason = result.diagnostics.decision.reason
    assert (reason.kind, reason.block) == (ReasonKind.NO_ROAD, BlockKind.BEND)
    assert "the bend at s = " in result.message and "tighter than the vehicle can take" in result.message


def test_a_road_no_wider_than_the_lane_keeps_it_and_says_so() -> None:
    problem = truck()
    narrow = replace(problem, road=Road(HALF_LANE, HALF_LANE))
    result = plan(narrow)
    assert result.status == "stopped"
    reason = result.diagnostics.decision.reason
    assert result.diagnostics.decision.lane is LaneChoice.KEEP
    assert (reason.kind, reason.obstacle_id) == (ReasonKind.ROAD_BLOCKED, "truck")
    assert "leaves no room" in result.message


def test_the_borrowed_corridor_on_a_wide_u_turn_folds_naive_candidates_not_repaired_ones() -> None:
    problem = wide_u_turn_problem()
    decision = plan(problem).diagnostics.decision
    assert decision.lane is LaneChoice.BORROW_LEFT and decision.corridor is not None
    ref = build_reference(problem.reference_line)
    s = np.linspace(decision.corridor.start, decision.corridor.end, 20)
    assert np.max(ref.kappa_at(s) * decision.corridor.widths(ref, s)[0]) > 1.0  # beyond the centre
    folded = {}
    for generator in ("naive", "transf_kappa"):
        options = replace(problem.options, generator=generator, num_candidates=40)
        cands = generate_candidates(ref, decision.corridor, problem.ego, problem.vehicle, options)
        folded[generator] = sum(folds_back(ref, cands.points(i)[2]) for i in range(cands.count))
    assert folded["naive"] >= 1
    assert folded["transf_kappa"] == 0


def test_the_decision_never_changes_a_lane_keeping_answer() -> None:
    """Without road, and with a road when nothing blocks the lane, the answer is the same."""
    base = demo_problem()
    widened = replace(base, road=Road(20.0, base.lane.right_width))
    for problem in (two_lane_problem(straight(200.0)), widened):
        without = plan(replace(problem, road=None))
        with_road = plan(problem)
        assert with_road.status == without.status and with_road.message == without.message
        for name in ("x", "y", "v", "d"):
            assert np.array_equal(getattr(with_road.trajectory, name), getattr(without.trajectory, name))


def test_a_borrow_that_leaves_the_road_is_a_violation() -> None:
    problem = truck()
    result = plan(problem)
    ref = build_reference(problem.reference_line)
    narrow = replace(problem, road=Road(2.0, HALF_LANE))
    kinds = {v.kind for v in trajectory_violations(ref, narrow, result.trajectory, [], borrowing=True)}
    assert ViolationKind.ROAD in kinds and ViolationKind.LANE not in kinds
    kinds = {v.kind for v in trajectory_violations(ref, problem, result.trajectory, [], borrowing=False)}
    assert kinds == {ViolationKind.LANE}


def test_an_ego_whose_side_is_over_the_lane_on_the_inside_of_a_bend_is_outside_it() -> None:
    """The ego (4.5 × 1.8 m) tangent to a left bend of radius 6 m, 1.25 m left of the reference: its corners
    are 0.21 m inside the lane's left edge (radius 4.25 m), the middle of its left side 0.40 m beyond it,
    in the road (more than the decision's 0.3 m tolerance). It is outside its lane on the left (and keeps
    borrowing until back), as the checks judge its outline."""
    from planner.decision import _outside_lane

    ref = build_reference(arc(6.0, 1.5, step=0.25))
    s = np.array([0.5 * ref.length])
    x, y = to_cartesian(ref, s, np.array([1.25]))[0]
    ego = Ego(x=float(x), y=float(y), heading=float(ref.heading_at(s)[0]), speed=5.0)
    problem = PlanningProblem(
        ref.points,
        Lane(HALF_LANE, HALF_LANE),
        ego,
        (),
        Vehicle(length=4.5, width=1.8),
        road=Road(4.0, HALF_LANE),
    )
    assert _outside_lane(ref, problem, Road(4.0, HALF_LANE), DEFAULT_CONFIG) == "left"


def crawler(
    half_width: float,
    vehicle: Vehicle | None = None,
    *,
    speed: float = 0.1,
    others: tuple[DynamicObstacle, ...] = (),
) -> PlanningProblem:
    """A car crawling at 0.1 m/s (or ``speed`` [m/s]) 25 m ahead on the reference line of a lane
    ``2·half_width`` wide (three lanes the converter merged, say), no road beyond it, the ego at 9 m/s."""
    slow = driving("crawler", 25.0, 0.0, speed, length=4.3, width=1.8)
    problem = two_lane_problem(
        straight(200.0), speed=9.0, obstacles=(slow, *others), road=False, vehicle=vehicle
    )
    return replace(problem, lane=Lane(half_width, half_width))


@pytest.mark.parametrize("vehicle", VEHICLES)
def test_a_crawling_car_with_room_beside_it_in_its_lane_is_passed_within_the_lane(
    vehicle: Vehicle | None,
) -> None:
    problem = crawler(4.5, vehicle)
    first = plan(problem)
    decision = first.diagnostics.decision
    assert first.status == "ok" and decision.lane is LaneChoice.KEEP
    reason = decision.reason
    assert (reason.kind, reason.block, reason.obstacle_id) == (
        ReasonKind.PASSING_IN_LANE,
        BlockKind.SLOW_VEHICLE,
        "crawler",
    )
    assert reason.side == "left" and reason.message.endswith("passing it within the lane on the left")
    assert decision.passing == frozenset({"crawler"})
    in_road(problem, first)
    run = simulate(problem, duration=8.0, goal=Goal(s_min=60.0))
    m = run.metrics
    assert m.termination == "goal" and m.collisions == 0 and m.max_lane_departure <= 1e-3
    crawler_front = 25.0 + 0.1 * float(run.motion.t[-1]) + 2.15
    assert float(run.motion.x[-1]) > crawler_front  # past it


def test_a_crawling_car_that_leaves_no_room_in_the_lane_is_followed_as_before() -> None:
    _followed(crawler(1.75))


def _followed(problem: PlanningProblem) -> None:
    """The plan keeps behind the crawler, passes nothing and says no pass."""
    result = plan(problem)
    decision = result.diagnostics.decision
    assert decision.lane is LaneChoice.KEEP and decision.reason.kind is not ReasonKind.PASSING_IN_LANE
    assert decision.passing == frozenset()
    crawler_rear = 25.0 + 0.1 * float(result.trajectory.t[-1]) - 2.15
    assert float(np.max(result.trajectory.x)) + 0.5 * problem.vehicle.length < crawler_rear


def test_a_crawling_car_is_passed_on_the_side_free_of_traffic_and_followed_where_neither_is() -> None:
    # the same wide lane, but cars drive beside the ego at its speed where it would pass
    for y, left in ((3.0, False), (-3.0, True)):
        problem = crawler(4.5, others=(driving("beside", 0.0, y, 9.0),))
        decision = plan(problem).diagnostics.decision
        assert decision.reason.kind is ReasonKind.PASSING_IN_LANE
        assert dict(decision.sides) == {"crawler": left}
        assert decision.reason.side == ("left" if left else "right")
    _followed(crawler(4.5, others=(driving("left", 0.0, 3.0, 9.0), driving("right", 0.0, -3.0, 9.0))))


def test_a_car_coming_towards_the_vehicle_in_a_wide_lane_is_not_overtaken() -> None:
    _followed(crawler(4.5, speed=-0.5))


def test_a_pass_within_the_lane_that_would_stop_before_the_slow_vehicle_is_dropped_for_following_it() -> None:
    # 2 cm to spare beside a 2.46 m wide crawler with no margin to the lane's edge: the lateral stage,
    # which keeps its margin, stops before the crawler's sweep; following it at 2.94 m/s is better
    slow = driving("crawler", 39.8, -0.78, 2.94, length=4.5, width=2.46)
    problem = two_lane_problem(straight(300.0), speed=11.39, obstacles=(slow,), road=False, vehicle=CAR)
    problem = replace(problem, lane=Lane(2.13, 4.43))
    result = plan(problem)
    assert result.status == "ok", result.message
    assert result.diagnostics.decision.reason.kind is ReasonKind.LANE_FREE
    assert float(result.trajectory.v[-1]) > 2.0  # follows it, does not stop
