"""Degenerate and extreme inputs to the planner as a library (the API fuzzer's findings, and beyond).

For every :class:`PlanningProblem` that ``planner.problem`` accepts, :func:`plan` and
:func:`generate_candidates` return a finite result (a planning failure is a ``fallback`` with a
message); what it refuses raises :class:`InvalidInputError` naming the field. Never an
``IndexError``, an overflow, a GEOS or OSQP error, or NaN.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.bounds import BEYOND_LANE, lateral_bounds
from planner.candidates import MAX_PATH_LENGTH, CandidateSet, generate_candidates, path_length
from planner.collision import frenet_boxes, obstacle_shape
from planner.errors import InvalidInputError
from planner.frenet import to_frenet
from planner.pipeline import PlanResult, plan, static_shapes
from planner.problem import (
    MAX_ACCELERATION,
    MAX_SIZE,
    SMALLEST_LIMIT,
    CircleObstacle,
    DynamicObstacle,
    Ego,
    Lane,
    Obstacle,
    Options,
    PlanningProblem,
    PolygonObstacle,
    Vehicle,
)
from planner.reference import build_reference
from planner.roads import demo_problem, straight
from planner.validation import trajectory_violations

DENORMAL = 5e-324
LARGEST = float(np.finfo(np.float64).max)
_TRAJECTORY_FIELDS = ("t", "x", "y", "heading", "curvature", "v", "a", "s", "d")


def _vehicle(**limits: float) -> Callable[[], PlanningProblem]:
    def make() -> PlanningProblem:
        base = demo_problem()
        return replace(base, vehicle=replace(base.vehicle, **limits))

    return make


def _obstacles(*obstacles: Obstacle) -> Callable[[], PlanningProblem]:
    return lambda: replace(demo_problem(), obstacles=obstacles)


def _box(size: float, x: float, y: float) -> DynamicObstacle:
    return DynamicObstacle("b", size, size, np.array([[0.0, x, y, 0.0]]))


def _planned(problem: PlanningProblem) -> PlanResult:
    """``plan(problem)`` and the contract on its answer."""
    result = plan(problem)
    assert result.status in ("ok", "stopped", "fallback")
    assert result.message
    traj = result.trajectory
    assert traj.size >= 2
    for name in _TRAJECTORY_FIELDS:
        values = getattr(traj, name)
        assert values.shape == (traj.size,), name
        assert np.isfinite(values).all(), f"{name} is not finite: {result.status}, {result.message}"
    return result


def _candidates(problem: PlanningProblem) -> CandidateSet:
    """``generate_candidates`` of ``problem`` and the contract on its answer."""
    ref = build_reference(problem.reference_line)
    cands = generate_candidates(ref, problem.lane, problem.ego, problem.vehicle, problem.options)
    shape = (problem.options.num_candidates, problem.options.num_points)
    assert cands.s.shape == cands.d.shape == cands.kappa.shape == shape
    for values in (cands.s, cands.d, cands.xy, cands.kappa, cands.transition):
        assert np.isfinite(values).all()
    assert cands.valid[:, 0].all()
    return cands


# --------------------------------------------------------------------------------------------------
# The fuzzer's findings (tests/app/test_fuzz_findings.py), called on the library
# --------------------------------------------------------------------------------------------------

FINDINGS = [
    # a denormal is no vehicle limit: refused, naming the field (it crashed in offset_basis: v²/a = inf)
    pytest.param(_vehicle(max_deceleration=DENORMAL), "vehicle.max_deceleration", id="denormal-deceleration"),
    pytest.param(_vehicle(max_curvature=DENORMAL), "vehicle.max_curvature", id="denormal-curvature"),
    pytest.param(_vehicle(max_acceleration=DENORMAL), "vehicle.max_acceleration", id="denormal-acceleration"),
    pytest.param(
        _vehicle(max_lateral_acceleration=DENORMAL), "vehicle.max_lateral_acceleration", id="denormal-lateral"
    ),
    # tiny normal limits plan: the braking distance is capped (it overflowed the k-d tree), the κ·d
    # bound stays finite (OSQP refused its 1e300 bounds)
    pytest.param(_vehicle(max_deceleration=1e-300), None, id="1e-300-deceleration"),
    pytest.param(_vehicle(max_curvature=1e-300), None, id="1e-300-curvature"),
    pytest.param(_vehicle(max_acceleration=1e-300), None, id="1e-300-acceleration"),
    pytest.param(_vehicle(max_lateral_acceleration=1e-300), None, id="1e-300-lateral"),
    pytest.param(
        _vehicle(max_deceleration=SMALLEST_LIMIT, max_curvature=SMALLEST_LIMIT), None, id="smallest-limits"
    ),
    # no reciprocal of these is taken: a denormal footprint or speed limit plans (as the API lets it)
    pytest.param(
        _vehicle(length=DENORMAL, width=DENORMAL, max_speed=DENORMAL), None, id="denormal-footprint"
    ),
    # a vanishing obstacle is a point (an empty outline made minimum.reduceat fail, a box of coincident
    # corners made GEOS refuse to densify it)
    pytest.param(_obstacles(CircleObstacle("c", np.array([9.0, 8.0]), 1e-9)), None, id="1e-9-circle"),
    pytest.param(_obstacles(CircleObstacle("c", np.array([9.0, 8.0]), 0.0)), None, id="zero-circle"),
    pytest.param(_obstacles(_box(DENORMAL, 0.0, 9999999.0)), None, id="denormal-box-far"),
    pytest.param(_obstacles(_box(DENORMAL, 0.0, 0.5)), None, id="denormal-box-near"),
    pytest.param(_obstacles(_box(DENORMAL, 9.0, 8.0)), None, id="denormal-box-in-the-turn"),
]


@pytest.mark.parametrize(("make", "field"), FINDINGS)
def test_a_fuzz_finding_plans_or_is_refused_naming_its_field(
    make: Callable[[], PlanningProblem], field: str | None
) -> None:
    if field is not None:
        with pytest.raises(InvalidInputError) as err:
            _planned(make())
        assert err.value.field == field
        return
    problem = make()
    _planned(problem)
    _candidates(problem)


@pytest.mark.parametrize(
    ("limits", "field"),
    [
        ({"max_deceleration": np.nextafter(SMALLEST_LIMIT, 0.0)}, "vehicle.max_deceleration"),
        ({"max_curvature": 0.0}, "vehicle.max_curvature"),
        ({"max_speed": -1.0}, "vehicle.max_speed"),
        ({"max_acceleration": np.inf}, "vehicle.max_acceleration"),
        ({"max_lateral_acceleration": np.nan}, "vehicle.max_lateral_acceleration"),
        ({"max_deceleration": np.nextafter(MAX_ACCELERATION, np.inf)}, "vehicle.max_deceleration"),
        ({"length": 2 * MAX_SIZE}, "vehicle.length"),
        ({"width": "1.8"}, "vehicle.width"),
    ],
)
def test_a_meaningless_vehicle_is_refused_naming_its_field(limits: dict[str, object], field: str) -> None:
    with pytest.raises(InvalidInputError) as err:
        Vehicle(**limits)  # type: ignore[arg-type]
    assert err.value.field == field


@pytest.mark.parametrize(
    ("obstacle", "field"),
    [
        (CircleObstacle("c", np.array([9.0, 8.0]), -1.0), "obstacles.1.circle.radius"),
        (CircleObstacle("c", np.array([9.0, np.nan]), 1.0), "obstacles.1.circle.center"),
        (DynamicObstacle("b", 2 * MAX_SIZE, 1.0, np.zeros((1, 4))), "obstacles.1.length"),
        (DynamicObstacle("b", 1.0, np.inf, np.zeros((1, 4))), "obstacles.1.width"),
        (DynamicObstacle("b", 1.0, 1.0, np.zeros((2, 4))), "obstacles.1.prediction.1.t"),
        (DynamicObstacle("b", 1.0, 1.0, np.zeros((1, 3))), "obstacles.1.prediction"),
        (PolygonObstacle("p", np.zeros((2, 2))), "obstacles.1.polygon"),
    ],
)
def test_a_meaningless_obstacle_is_refused_naming_its_field(obstacle: Obstacle, field: str) -> None:
    base = demo_problem()
    with pytest.raises(InvalidInputError) as err:
        replace(base, obstacles=(*base.obstacles, obstacle))
    assert err.value.field == field


# --------------------------------------------------------------------------------------------------
# The root causes, one by one
# --------------------------------------------------------------------------------------------------


def test_a_weak_brake_caps_the_path_instead_of_overflowing() -> None:
    problem = _vehicle(max_deceleration=SMALLEST_LIMIT)()
    options = replace(problem.options, min_path_length=1e300)
    assert path_length(problem.ego, problem.vehicle, options) == MAX_PATH_LENGTH
    cands = _candidates(replace(problem, options=options))
    assert np.ptp(cands.s[0]) <= MAX_PATH_LENGTH


def test_a_vehicle_that_cannot_turn_is_blocked_by_finite_bounds_near_the_lane() -> None:
    problem = _vehicle(max_curvature=1e-300)()
    left, right = float(problem.lane.left_width), float(problem.lane.right_width)
    ref = build_reference(problem.reference_line)
    s = np.linspace(0.0, ref.length, 200)
    bounds = lateral_bounds(
        ref,
        problem.lane,
        s,
        problem.vehicle,
        margin=0.2,
        boxes=frenet_boxes(ref, []),
        left_of=np.zeros(0, dtype=bool),
    )
    for side in (bounds.lower, bounds.upper):
        assert np.all((side >= -right - BEYOND_LANE) & (side <= left + BEYOND_LANE))
    assert bounds.blocked is not None
    assert bounds.blocked <= int(np.argmax(np.abs(ref.kappa_at(s)) > 0.05))
    assert _planned(problem).status in ("stopped", "fallback")


@pytest.mark.parametrize(
    ("obstacle", "center", "kind"),
    [
        # a radius below the rounding of its centre's coordinates buffers to nothing
        (CircleObstacle("c", np.array([1e7, 1e7 + 3.0]), 1e-9), (1e7, 1e7 + 3.0), "Point"),
        (CircleObstacle("c", np.array([50.0, 3.0]), 0.0), (50.0, 3.0), "Point"),
        (DynamicObstacle("b", DENORMAL, DENORMAL, np.array([[0.0, 50.0, 3.0, 0.3]])), (50.0, 3.0), "Point"),
        (DynamicObstacle("b", 4.0, 0.0, np.array([[0.0, 50.0, 3.0, 0.3]])), (50.0, 3.0), "LineString"),
        (PolygonObstacle("p", np.array([[48.0, 3.0], [50.0, 3.0], [52.0, 3.0]])), (50.0, 3.0), "LineString"),
        (PolygonObstacle("p", np.array([[50.0, 3.0], [50.0, 3.0], [50.0, 3.0]])), (50.0, 3.0), "Point"),
    ],
)
def test_an_obstacle_without_area_is_a_point_or_a_segment_with_a_frenet_box(
    obstacle: Obstacle, center: tuple[float, float], kind: str
) -> None:
    shape = obstacle_shape(obstacle)
    assert shape.geom_type.removeprefix("Multi") == kind and not shape.is_empty
    # a straight road along +x passing 3 m to the right of the obstacle
    ref = build_reference(straight(200.0, step=5.0) + (np.asarray(center) - [50.0, 3.0]))
    boxes = frenet_boxes(ref, [("empty", shapely.Polygon()), (obstacle.id, shape)], reach=10.0)
    assert boxes.ids == (obstacle.id,)
    assert boxes.s_min[0] - 2.0 - 1e-6 <= 50.0 <= boxes.s_max[0] + 2.0 + 1e-6
    assert boxes.d_min[0] - 1e-6 <= 3.0 <= boxes.d_max[0] + 1e-6


def test_a_polygon_crossing_itself_keeps_both_lobes() -> None:
    """``buffer(0)``, the repair before, kept one lobe of a bow tie and dropped the other."""
    bow_tie = PolygonObstacle("p", np.array([[5.0, 5.0], [12.0, 12.0], [12.0, 5.0], [6.0, 12.0]]))
    shape = obstacle_shape(bow_tie)
    assert shape.is_valid
    assert shape.contains(shapely.Point(6.0, 8.5)) and shape.contains(shapely.Point(11.0, 8.5))


@pytest.mark.parametrize("radius", [0.0, DENORMAL, 1e-9])
def test_a_point_obstacle_on_the_path_is_driven_around(radius: float) -> None:
    problem = PlanningProblem(
        reference_line=straight(200.0, step=5.0),
        lane=Lane(3.5, 3.5),
        ego=Ego(x=10.0, y=0.0, heading=0.0, speed=8.0),
        obstacles=(CircleObstacle("pole", np.array([40.0, 0.0]), radius),),
        options=Options(target_speed=10.0),
    )
    result = _planned(problem)
    assert result.status == "ok", result.message
    ref = build_reference(problem.reference_line)
    assert trajectory_violations(ref, problem, result.trajectory, static_shapes(problem)) == []
    traj = result.trajectory
    passing = np.abs(traj.x - 40.0) < 0.5 * problem.vehicle.length
    assert passing.any() and np.all(np.abs(traj.y[passing]) >= 0.5 * problem.vehicle.width)


def test_a_point_beyond_squared_overflow_still_has_frenet_coordinates() -> None:
    ref = build_reference(demo_problem().reference_line)
    far = to_frenet(ref, [[1e200, 0.0], [0.0, -1e300]])
    assert np.isfinite(far.s).all() and np.isfinite(far.d).all()
    assert np.all(far.nearest < ref.size)
    with pytest.raises(InvalidInputError) as err:
        plan(replace(demo_problem(), ego=Ego(x=1e200, y=0.0, heading=0.0, speed=5.0)))
    assert err.value.field == "ego"


# --------------------------------------------------------------------------------------------------
# Extreme but accepted limits and sizes
# --------------------------------------------------------------------------------------------------


def _log_uniform(low: float, high: float, *special: float) -> st.SearchStrategy[float]:
    """Half the time a float in ``[low, high]`` with a uniform exponent, half the time ``low``, ``high``
    or one of the ``special`` values."""
    exponents = st.floats(float(np.log10(low)), float(np.log10(high)))
    drawn = exponents.map(lambda e: float(np.clip(10.0 ** min(e, 308.0), low, high)))
    return st.one_of(st.sampled_from([low, high, *special]), drawn)


ACCELERATIONS = _log_uniform(SMALLEST_LIMIT, MAX_ACCELERATION, 1e-300, 1e-3, 3.0)
CURVATURES = _log_uniform(SMALLEST_LIMIT, LARGEST, 1e-300, 0.2, 1e300)
SPEEDS = _log_uniform(SMALLEST_LIMIT, LARGEST, DENORMAL, 1e-300, 20.0, 1e300)
SIZES = _log_uniform(1e-300, MAX_SIZE, 0.0, DENORMAL, 1e-9, 1.0, 1e3)


@st.composite
def obstacles(draw: st.DrawFn, index: int) -> Obstacle:
    """An obstacle of extreme size somewhere around the demo's U-turn (static or moving)."""
    center = np.array([draw(st.floats(-30.0, 30.0)), draw(st.floats(-10.0, 25.0))])
    kind = draw(st.sampled_from(["circle", "box", "moving", "triangle"]))
    if kind == "circle":
        return CircleObstacle(f"c{index}", center, draw(SIZES))
    if kind == "triangle":
        corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.3, 0.8]])
        return PolygonObstacle(f"p{index}", center + draw(SIZES) * corners)
    heading = draw(st.floats(-np.pi, np.pi))
    states = [[0.0, *center, heading]]
    if kind == "moving":
        speed = draw(st.floats(-10.0, 10.0))
        end = center + 8.0 * speed * np.array([np.cos(heading), np.sin(heading)])
        states.append([8.0, *end, heading])
    return DynamicObstacle(f"b{index}", draw(SIZES), draw(SIZES), np.array(states))


@st.composite
def extreme_problems(draw: st.DrawFn) -> PlanningProblem:
    """The demo with a vehicle and up to three obstacles from anywhere in the ranges accepted."""
    base = demo_problem()
    vehicle = Vehicle(
        length=draw(_log_uniform(SMALLEST_LIMIT, MAX_SIZE, DENORMAL, 4.5)),
        width=draw(_log_uniform(SMALLEST_LIMIT, MAX_SIZE, DENORMAL, 1.8)),
        max_speed=draw(SPEEDS),
        max_acceleration=draw(ACCELERATIONS),
        max_deceleration=draw(ACCELERATIONS),
        max_lateral_acceleration=draw(ACCELERATIONS),
        max_curvature=draw(CURVATURES),
    )
    count = draw(st.integers(0, 3))
    drawn = tuple(draw(obstacles(i)) for i in range(count))
    target = draw(st.sampled_from([None, 7.0]))
    return replace(base, vehicle=vehicle, obstacles=drawn, options=replace(base.options, target_speed=target))


@settings(max_examples=30, deadline=None)
@given(problem=extreme_problems())
def test_extreme_accepted_limits_and_sizes_plan(problem: PlanningProblem) -> None:
    _planned(problem)
    _candidates(problem)
