"""The planning pipeline on small synthetic roads: every returned trajectory passes the checks."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planner.pipeline import plan
from planner.problem import (
    CircleObstacle,
    DynamicObstacle,
    Ego,
    Lane,
    Options,
    PlanningProblem,
    PolygonObstacle,
    Vehicle,
)
from planner.reference import build_reference
from planner.roads import demo_problem, straight
from planner.st_bounds import static_shapes
from planner.timing import STAGES, TOTAL
from planner.validation import trajectory_violations

ROAD = straight(200.0, step=5.0)  # a coarse 5 m polyline
EGO = Ego(x=10.0, y=0.0, heading=0.0, speed=8.0)
OPTIONS = Options(target_speed=10.0)


def _box(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=float)


def _checked(problem: PlanningProblem):  # type: ignore[no-untyped-def]
    result = plan(problem)
    ref = build_reference(problem.reference_line)
    assert trajectory_violations(ref, problem, result.trajectory, static_shapes(problem)) == []
    assert np.isfinite(result.trajectory.x).all()
    return result


def test_free_road_reaches_the_target_speed() -> None:
    result = _checked(PlanningProblem(ROAD, Lane(3.5, 3.5), EGO, (), Vehicle(), OPTIONS))
    assert result.status == "ok"
    assert result.trajectory.v[-1] == pytest.approx(10.0, abs=0.2)
    assert np.max(np.abs(result.trajectory.d)) < 0.2
    assert result.diagnostics.lateral_qp.converged and result.diagnostics.speed.usable


def test_blocked_road_stops_before_the_block() -> None:
    wall = PolygonObstacle("wall", _box(60.0, 62.0, -4.0, 4.0))
    result = _checked(PlanningProblem(ROAD, Lane(3.5, 3.5), EGO, (wall,), Vehicle(), OPTIONS))
    assert result.status == "stopped"
    assert result.trajectory.v[-1] == pytest.approx(0.0, abs=1e-3)
    front = result.trajectory.x + 0.5 * Vehicle().length
    assert np.all(front < 60.0)


@pytest.mark.parametrize("gap", [0.3, 0.8, 1.5, 3.0])
@pytest.mark.parametrize("d0", [0.0, 0.4])
def test_standing_right_before_a_block_stays_stopped(gap: float, d0: float) -> None:
    """A vehicle already halted ``gap`` [m] before a wall (as after a stop in closed loop) stays
    ``stopped`` where it is, even where the lateral QP has no room left to steer."""
    wall = PolygonObstacle("wall", _box(60.0, 62.0, -4.0, 4.0))
    x0 = 60.0 - 0.5 * Vehicle().length - gap
    ego = Ego(x=x0, y=d0, heading=0.0, speed=0.0)
    result = _checked(PlanningProblem(ROAD, Lane(3.5, 3.5), ego, (wall,), Vehicle(), OPTIONS))
    assert result.status == "stopped", result.message
    assert np.all(result.trajectory.x + 0.5 * Vehicle().length < 60.0)
    assert np.max(result.trajectory.v) < 1.5


def test_replanning_while_stopped_before_a_block_does_not_creep_up_to_it() -> None:
    """Re-planned every 0.1 s from the plan's own state (a perfect tracker), a vehicle halted before a
    wall stays put: the stop is measured from the block, not from wherever the vehicle now is."""
    wall = PolygonObstacle("wall", _box(60.0, 62.0, -4.0, 4.0))
    ego = Ego(x=60.0 - 0.5 * Vehicle().length - 0.8, y=0.0, heading=0.0, speed=0.05)
    start = ego.x
    fast = Options(target_speed=30.0)  # a long path: knots further apart than 0.5 m
    for _ in range(40):
        result = _checked(PlanningProblem(ROAD, Lane(3.5, 3.5), ego, (wall,), Vehicle(), fast))
        assert result.status == "stopped", result.message
        t = result.trajectory
        ego = Ego(
            x=float(t.x[1]),
            y=float(t.y[1]),
            heading=float(t.heading[1]),
            speed=float(t.v[1]),
            acceleration=float(t.a[1]),
        )
    assert ego.x - start < 0.1
    assert ego.x + 0.5 * Vehicle().length < 60.0


def test_a_lane_narrower_than_the_vehicle_blocks_the_road() -> None:
    road = straight(200.0, step=5.0)
    x = road[:, 0]
    width = np.where((x >= 80.0) & (x <= 100.0), 0.8, 3.5)  # 1.6 m in all: narrower than 1.8 m
    problem = PlanningProblem(road, Lane(width, width), EGO, (), Vehicle(), OPTIONS)
    result = _checked(problem)
    assert result.status == "stopped", result.message
    assert np.all(result.trajectory.x + 0.5 * Vehicle().length < 80.0)


@pytest.mark.parametrize("x0", [100.0, 115.0])
@pytest.mark.parametrize("both", [False, True])
def test_a_lane_whose_width_falls_to_zero_at_its_last_point_just_ends(x0: float, both: bool) -> None:
    """A zero width at the last point (one side, as in converted CommonRoad data, or both) within the
    path's reach is the lane's end, not an infeasible lateral problem: the plan stays ``ok``."""
    road = np.vstack((straight(200.0, step=5.0), [[201.0, 0.0]]))  # the last segment 1 m long
    left = np.full(road.shape[0], 1.7)
    right = left.copy()
    right[-1] = 0.0
    if both:
        left[-1] = 0.0
    ego = Ego(x=x0, y=0.0, heading=0.0, speed=8.0)
    result = _checked(PlanningProblem(road, Lane(left, right), ego, (), Vehicle(), OPTIONS))
    assert result.status == "ok", result.message
    assert "the lane ends" in result.message  # 1.7 m in all at the last point: narrower than the car
    assert result.trajectory.x[-1] <= 200.0 + 1e-6


def test_parked_car_is_passed_on_the_side_with_room() -> None:
    car = PolygonObstacle("car", _box(50.0, 55.0, -1.5, 0.5))
    result = _checked(PlanningProblem(ROAD, Lane(5.0, 3.5), EGO, (car,), Vehicle(), OPTIONS))
    assert result.status == "ok"
    passing = (result.trajectory.x > 48.0) & (result.trajectory.x < 57.0)
    assert passing.any() and np.all(result.trajectory.d[passing] > 0.5 + Vehicle().width / 2)


def test_slow_leader_without_room_to_pass_is_followed() -> None:
    t = np.arange(0.0, 8.01, 0.5)
    lead = DynamicObstacle("lead", 4.5, 1.8, np.column_stack((t, 30.0 + 3.0 * t, 0 * t, 0 * t)))
    result = _checked(PlanningProblem(ROAD, Lane(1.8, 1.8), EGO, (lead,), Vehicle(), OPTIONS))
    assert result.status == "ok"
    gap = (30.0 + 3.0 * result.trajectory.t) - result.trajectory.x
    assert np.all(gap > Vehicle().length)  # centre-to-centre, both 4.5 m long
    assert result.trajectory.v[-1] < 5.0


def test_demo_u_turn_plans_around_the_corner() -> None:
    result = _checked(demo_problem())
    assert result.status == "ok"
    assert result.diagnostics.candidates.generated == demo_problem().options.num_candidates
    assert list(result.diagnostics.timing_ms) == [*STAGES[:-1], TOTAL]  # every stage but the fallback


def _random_problem(rng: np.random.Generator) -> PlanningProblem:
    """A random road (U-turn, arc, straight or clothoid, possibly noisy), ego, obstacles and limits."""
    from planner.problem import CircleObstacle
    from planner.roads import arc, clothoid, u_turn

    kind = rng.integers(0, 4)
    if kind == 0:
        road = u_turn(rng.uniform(2, 20), rng.uniform(5, 40), step=rng.choice([0.5, 1, 3]))
    elif kind == 1:
        road = arc(rng.uniform(3, 200), rng.uniform(-3, 3), step=rng.choice([0.5, 2, 5]))
    elif kind == 2:
        road = straight(rng.uniform(5, 300), heading=rng.uniform(-3, 3), step=rng.choice([0.5, 5]))
    else:
        road = clothoid(rng.uniform(10, 100), rng.uniform(-0.02, 0.02), step=1.0)
    road = road + rng.normal(0, rng.choice([0, 0.01, 0.2]), road.shape)
    k = min(int(rng.integers(1, len(road) - 1)) if len(road) > 3 else 1, len(road) - 2)
    heading = np.arctan2(*(road[k + 1] - road[k])[::-1]) + rng.normal(0, 0.3)
    ego = Ego(
        road[k][0] + rng.normal(0, 1),
        road[k][1] + rng.normal(0, 1),
        heading,
        speed=rng.uniform(0, 30),
        acceleration=rng.uniform(-3, 2),
    )
    obstacles: list[CircleObstacle | DynamicObstacle] = []
    for j in range(int(rng.integers(0, 5))):
        c = road[rng.integers(0, len(road))] + rng.normal(0, 2, 2)
        if rng.random() < 0.5:
            obstacles.append(CircleObstacle(f"c{j}", c, rng.uniform(0.2, 3)))
        else:
            t = np.arange(0, 8.1, 0.5)
            v, h = rng.uniform(-5, 15), rng.uniform(-3, 3)
            states = np.column_stack((t, c[0] + v * t * np.cos(h), c[1] + v * t * np.sin(h), t * 0 + h))
            obstacles.append(DynamicObstacle(f"d{j}", 4.5, 1.8, states))
    lane = Lane(rng.uniform(0, 8), rng.uniform(0, 8))
    vehicle = Vehicle(max_curvature=rng.uniform(0.05, 0.5), max_lateral_acceleration=rng.uniform(1, 6))
    options = Options(
        horizon_time=rng.uniform(1, 20),
        dt=rng.choice([0.05, 0.1, 0.2, 0.5]),
        target_speed=rng.uniform(0, 30),
        num_candidates=int(rng.integers(1, 64)),
        generator=rng.choice(["naive", "transf_kappa"]),
    )
    return PlanningProblem(road, lane, ego, tuple(obstacles), vehicle, options)


def test_random_problems_end_in_a_status_or_a_domain_error() -> None:
    """Whatever the input, planning answers with a status and a finite trajectory, or raises one of
    the planner's own errors (a 4xx): never anything else (a 5xx). Case 17 once had a zero-length path."""
    from planner.errors import PlannerError

    rng = np.random.default_rng(1)
    answered = 0
    for _ in range(30):
        problem = _random_problem(rng)
        try:
            result = plan(problem)
        except PlannerError:
            continue
        answered += 1
        assert np.isfinite(result.trajectory.x).all() and np.isfinite(result.trajectory.v).all()
        ref = build_reference(problem.reference_line)
        broken = trajectory_violations(ref, problem, result.trajectory, static_shapes(problem))
        # what the answer says it breaks is what it breaks; only a fallback may break anything
        assert list(result.violations) == broken
        assert result.status == "fallback" or broken == []
    assert answered >= 10


@pytest.mark.parametrize("budget_ms", [1.0, 1e5])
def test_time_budget_makes_an_overrun_a_braking_fallback(budget_ms: float) -> None:
    base = demo_problem()
    problem = replace(base, options=replace(base.options, time_budget_ms=budget_ms))
    result = plan(problem)
    if budget_ms > 1e4:  # never reached: the same answer as without a budget
        assert result.status == plan(base).status == "ok"
        return
    assert result.status == "fallback"
    assert "time budget of 1 ms spent" in result.message
    traj = result.trajectory
    assert traj.v[0] == pytest.approx(problem.ego.speed)
    assert np.all(np.diff(traj.v) <= 1e-9) and traj.v[-1] == pytest.approx(0.0, abs=1e-9)
    ref = build_reference(problem.reference_line)
    assert trajectory_violations(ref, problem, traj, static_shapes(problem)) == []


def test_same_request_same_answer() -> None:
    """No wall-clock limit inside a stage decides the answer: twice the same request, the same plan."""
    first, second = plan(demo_problem()), plan(demo_problem())
    assert first.status == second.status
    np.testing.assert_allclose(first.trajectory.x, second.trajectory.x, atol=1e-6)
    np.testing.assert_allclose(first.trajectory.v, second.trajectory.v, atol=1e-6)


def test_an_answer_does_not_depend_on_what_was_planned_before() -> None:
    """The lateral QP starts cold in every plan (no warm start, no adapted ADMM step carried over): the
    same request gets the same answer, iterations included, whatever the thread planned before it."""
    ref_line = straight(120.0, step=1.0)
    parked = PolygonObstacle("parked", ((40.0, 0.4), (45.0, 0.4), (45.0, 2.0), (40.0, 2.0)))
    other = PlanningProblem(ref_line, Lane(3.5, 3.5), Ego(x=5.0, y=0.5, heading=0.0, speed=8.0), (parked,))
    first = plan(demo_problem())
    for speed in (2.0, 6.0, 10.0):  # other plans of the same sizes in between
        plan(replace(other, ego=replace(other.ego, speed=speed)))
    again = plan(demo_problem())
    assert first.diagnostics.lateral_qp.iterations == again.diagnostics.lateral_qp.iterations
    assert (first.status, first.message) == (again.status, again.message)
    for name in ("x", "y", "heading", "v", "a", "s", "d"):
        assert np.array_equal(getattr(first.trajectory, name), getattr(again.trajectory, name)), name


def test_huge_and_far_obstacles_cost_only_what_lies_near_the_road(monkeypatch: pytest.MonkeyPatch) -> None:
    """A 20 km square around the road's far end and hundreds of far-off outlines: only the outline near
    the reference is mapped by TransF-κ, and the plan is the one without them where they are out of
    reach."""
    import planner.collision as collision

    mapped: list[int] = []
    original = collision.to_frenet

    def counting(ref, pts):  # type: ignore[no-untyped-def]
        mapped.append(len(pts))
        return original(ref, pts)

    monkeypatch.setattr(collision, "to_frenet", counting)
    # 200 × 126 m of outline, 5 km away
    far = tuple(CircleObstacle(f"far{i}", np.array([1000.0 + 50.0 * i, 5000.0]), 20.0) for i in range(200))
    base = PlanningProblem(ROAD, Lane(3.5, 3.5), EGO, (), Vehicle(), OPTIONS)
    with_far = replace(base, obstacles=far)
    assert _checked(with_far).status == "ok"
    assert sum(mapped) == 0
    # a field wall 20 km long crossing the road at x = 80 m: cut to the corridor, the road is blocked
    wall = PolygonObstacle("field", _box(80.0, 82.0, -10_000.0, 10_000.0))
    mapped.clear()
    result = _checked(replace(base, obstacles=(wall,)))
    assert result.status == "stopped"
    assert 0 < sum(mapped) < 500  # 2 × 2 m + 2 × (2 · 10 m corridor) of outline at 0.25 m steps


@pytest.mark.parametrize(
    ("x", "y", "heading", "speed", "acceleration", "curvature"),
    [
        # two states of the closed-loop demo entering the U-turn, where the optimised path grazed the cone
        (-5.7092, 0.3659, 0.0631, 5.4344, -0.9384, 0.00435),
        (-3.7513, 0.4966, 0.0701, 4.4174, -1.7045, 0.00485),
    ],
)
def test_an_obstacle_on_the_outside_of_a_curve_is_cleared_by_the_bulging_corners(
    x: float, y: float, heading: float, speed: float, acceleration: float, curvature: float
) -> None:
    """In a curve the footprint's outer corners stick out by the sagitta; the obstacle's bound keeps it.

    Regression: the lane bounds kept the bulge but the obstacles' did not, so the optimised path hit
    the demo's cone on the outside of the U-turn by a few millimetres and the answer was a braking
    fallback.
    """
    ego = Ego(x=x, y=y, heading=heading, speed=speed, acceleration=acceleration, curvature=curvature)
    result = _checked(replace(demo_problem(), ego=ego))
    assert result.status == "ok", result.message


def test_an_ego_already_inside_a_conservative_obstacle_bound_starts_from_where_it_is() -> None:
    """Passing the demo's cone, the ego is 7 cm inside the (conservative) bound the corners' bulge puts
    around it: the bounds open to the ego's offset at the start instead of making the QP infeasible.

    Regression: a closed-loop state of the demo that answered "lateral QP failed: infeasible".
    """
    ego = Ego(x=5.8343, y=5.2018, heading=1.2390, speed=3.8262, acceleration=-1.5830, curvature=0.17925)
    result = _checked(replace(demo_problem(), ego=ego))
    assert result.status == "ok", result.message
