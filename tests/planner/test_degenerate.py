"""Degenerate and extreme inputs to the planner as a library (the API fuzzer's findings, and beyond).

For every :class:`PlanningProblem` that ``planner.problem`` accepts, :func:`plan` and
:func:`generate_candidates` return a finite result (a planning failure is a ``fallback`` with a
message); what it refuses raises :class:`InvalidInputError` naming the field. Never an
``IndexError``, an overflow, a GEOS or OSQP error, or NaN.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import annotated_types
import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from app import conversions, limits
from app.models import planning as api
from planner.bounds import BEYOND_LANE, lateral_bounds
from planner.candidates import MAX_PATH_LENGTH, CandidateSet, generate_candidates, path_length
from planner.collision import frenet_boxes, obstacle_shape
from planner.errors import InvalidInputError
from planner.frenet import to_frenet
from planner.pipeline import plan
from planner.problem import (
    CAR_FIELDS,
    MAX_ACCELERATION,
    MAX_CANDIDATE_POINTS,
    MAX_EGO_CURVATURE,
    MAX_EGO_SPEED,
    MAX_HORIZON_TIME,
    MAX_NUM_POINTS,
    MAX_SIZE,
    MAX_TRAJECTORY_POINTS,
    MIN_DT,
    SMALLEST_LIMIT,
    STANDSTILL_TOLERANCE,
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
from planner.result import PlanResult
from planner.roads import demo_problem, straight
from planner.st_bounds import static_shapes
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
    assert result.message
    traj = result.trajectory
    # a step longer than the horizon samples the start alone (the API accepts horizon 0.01 s, dt 1 s)
    assert traj.size >= (1 if problem.options.dt > problem.options.horizon_time else 2)
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


def _refused_naming_or_planned(make: Callable[[], PlanningProblem], field: str | None) -> None:
    """``make()`` (or its plan) raises the domain error naming ``field``; with ``field`` None it plans
    and its candidates keep their contract."""
    if field is not None:
        with pytest.raises(InvalidInputError) as err:
            _planned(make())
        assert err.value.field == field
        return
    problem = make()
    _planned(problem)
    _candidates(problem)


@pytest.mark.parametrize(("make", "field"), FINDINGS)
def test_a_fuzz_finding_plans_or_is_refused_naming_its_field(
    make: Callable[[], PlanningProblem], field: str | None
) -> None:
    _refused_naming_or_planned(make, field)


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
    assert _planned(problem).status == "stopped"


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


# --------------------------------------------------------------------------------------------------
# Ego, lane, options and reference line: every field checked
# --------------------------------------------------------------------------------------------------

NAN, INF = float("nan"), float("inf")
#: points of the demo's reference line (one lane width each, when given per point)
_DEMO_POINTS = demo_problem().reference_line.shape[0]


def _ego(**fields: Any) -> Callable[[], PlanningProblem]:
    def make() -> PlanningProblem:
        base = demo_problem()
        return replace(base, ego=replace(base.ego, **fields))

    return make


def _options(**fields: Any) -> Callable[[], PlanningProblem]:
    def make() -> PlanningProblem:
        base = demo_problem()
        return replace(base, options=replace(base.options, **fields))

    return make


def _lane(**widths: Any) -> Callable[[], PlanningProblem]:
    def make() -> PlanningProblem:
        base = demo_problem()
        return replace(base, lane=replace(base.lane, **widths))

    return make


def _widths(*edits: tuple[int, float], count: int = _DEMO_POINTS) -> np.ndarray:
    """3.5 m per reference point, with ``(index, value)`` edits."""
    widths = np.full(count, 3.5)
    for index, value in edits:
        widths[index] = value
    return widths


def _reference(points: Any) -> Callable[[], PlanningProblem]:
    return lambda: replace(demo_problem(), reference_line=points)


INPUTS = [
    # the ego: finite, a forward speed, accelerations and curvatures no vehicle exceeds (NaN went
    # into the k-d tree, the QP's d_ref or the speed solver; 1e300 m/s overflowed v²)
    *(
        pytest.param(_ego(**{k: v}), f"ego.{k}", id=f"ego.{k}={v}")
        for k in ("x", "y", "heading")
        for v in (NAN, INF)
    ),
    pytest.param(_ego(x="1"), "ego.x", id="ego.x-string"),
    pytest.param(_ego(heading=-INF), "ego.heading", id="ego.heading=-inf"),
    pytest.param(_ego(speed=NAN), "ego.speed", id="ego.speed=nan"),
    pytest.param(_ego(speed=INF), "ego.speed", id="ego.speed=inf"),
    pytest.param(_ego(speed=-1.0), "ego.speed", id="ego.speed=-1"),
    pytest.param(_ego(speed=1e300), "ego.speed", id="ego.speed=1e300"),
    pytest.param(_ego(speed=np.nextafter(MAX_EGO_SPEED, INF)), "ego.speed", id="ego.speed-above-max"),
    pytest.param(_ego(acceleration=NAN), "ego.acceleration", id="ego.acceleration=nan"),
    pytest.param(_ego(acceleration=-1e300), "ego.acceleration", id="ego.acceleration=-1e300"),
    pytest.param(_ego(curvature=NAN), "ego.curvature", id="ego.curvature=nan"),
    pytest.param(_ego(curvature=INF), "ego.curvature", id="ego.curvature=inf"),
    pytest.param(_ego(curvature=1e300), "ego.curvature", id="ego.curvature=1e300"),
    # far off the road or pointing away: refused by the planner, which knows the road
    pytest.param(_ego(x=1e300), "ego", id="ego.x=1e300"),
    pytest.param(_ego(heading=1e300), "ego.heading", id="ego.heading=1e300"),
    # what the simulator can produce plans: standstill, a rounding below it, any heading
    pytest.param(_ego(speed=0.0), None, id="ego.speed=0"),
    pytest.param(_ego(speed=-1e-12), None, id="ego.speed=-1e-12"),
    pytest.param(_ego(speed=-STANDSTILL_TOLERANCE), None, id="ego.speed=-tolerance"),
    pytest.param(_ego(heading=4.0 * np.pi), None, id="ego.heading=4pi"),
    pytest.param(_ego(speed=MAX_EGO_SPEED, acceleration=MAX_ACCELERATION), None, id="ego-fastest"),
    pytest.param(_ego(acceleration=-MAX_ACCELERATION, curvature=MAX_EGO_CURVATURE), None, id="ego-sharpest"),
    pytest.param(_ego(curvature=-MAX_EGO_CURVATURE), None, id="ego.curvature=-max"),
    # options (dt = 0 divided by zero, NaN could not be rounded, 1e-9 s asked for 60 GiB, 0 candidates
    # or points had nothing to reduce or index, a negative seed or num_points reached numpy)
    *(pytest.param(_options(dt=v), "options.dt", id=f"options.dt={v}") for v in (0.0, -0.1, NAN, INF, 1e-9)),
    pytest.param(_options(dt=np.nextafter(MAX_HORIZON_TIME, INF)), "options.dt", id="options.dt-above-max"),
    pytest.param(_options(horizon_time=600.0, dt=0.01), "options.dt", id="options.dt-too-many-steps"),
    *(
        pytest.param(_options(horizon_time=v), "options.horizon_time", id=f"options.horizon_time={v}")
        for v in (0.0, -1.0, NAN, INF, 1e6)
    ),
    *(
        pytest.param(_options(target_speed=v), "options.target_speed", id=f"options.target_speed={v}")
        for v in (-1.0, NAN, INF)
    ),
    *(
        pytest.param(_options(num_candidates=v), "options.num_candidates", id=f"options.num_candidates={v!r}")
        for v in (0, -1, 1.5, True, np.float64(32.0))
    ),
    *(
        pytest.param(_options(num_points=v), "options.num_points", id=f"options.num_points={v!r}")
        for v in (0, 1, -5, 2.5, MAX_NUM_POINTS + 1)
    ),
    pytest.param(
        _options(num_candidates=MAX_CANDIDATE_POINTS // 100 + 1, num_points=100),
        "options.num_points",
        id="options-too-many-candidate-points",
    ),
    *(
        pytest.param(_options(**{k: v}), f"options.{k}", id=f"options.{k}={v}")
        for k in ("lateral_margin", "min_path_length")
        for v in (-1.0, NAN, INF)
    ),
    pytest.param(_options(lateral_margin=1e300), "options.lateral_margin", id="options.lateral_margin=1e300"),
    *(
        pytest.param(_options(time_budget_ms=v), "options.time_budget_ms", id=f"options.time_budget_ms={v}")
        for v in (0.0, -1.0, NAN)
    ),
    pytest.param(_options(seed=-1), "options.seed", id="options.seed=-1"),
    pytest.param(_options(seed=1.5), "options.seed", id="options.seed=1.5"),
    pytest.param(_options(generator="spline"), "options.generator", id="options.generator=spline"),
    pytest.param(
        _options(return_candidates="yes"), "options.return_candidates", id="options.return_candidates"
    ),
    # extreme options that plan
    pytest.param(_options(dt=MIN_DT, horizon_time=MIN_DT * MAX_TRAJECTORY_POINTS), None, id="options-finest"),
    pytest.param(_options(dt=1.0, horizon_time=0.01), None, id="options.dt-above-horizon"),
    pytest.param(_options(horizon_time=DENORMAL), None, id="options.horizon_time=denormal"),
    pytest.param(_options(num_candidates=1, num_points=2), None, id="options-fewest-candidates"),
    pytest.param(
        _options(target_speed=0.0, lateral_margin=MAX_SIZE, min_path_length=1e300), None, id="options-huge"
    ),
    pytest.param(_options(seed=2**70, time_budget_ms=1e300), None, id="options.seed=2**70"),
    # lane widths: a number in [0, MAX_SIZE] or one per reference point (NaN made NaN offsets, a short
    # array an IndexError, a long one was silently cut, a negative one made a lane of negative width)
    *(
        pytest.param(_lane(**{k: v}), f"lane.{k}", id=f"lane.{k}={v}")
        for k in ("left_width", "right_width")
        for v in (NAN, INF, -1.0, 2 * MAX_SIZE)
    ),
    pytest.param(_lane(left_width="3.5"), "lane.left_width", id="lane.left_width-string"),
    pytest.param(_lane(left_width=_widths(count=_DEMO_POINTS - 1)), "lane.left_width", id="lane-too-few"),
    pytest.param(_lane(left_width=_widths(count=_DEMO_POINTS + 1)), "lane.left_width", id="lane-too-many"),
    pytest.param(_lane(right_width=np.zeros(0)), "lane.right_width", id="lane-empty"),
    pytest.param(_lane(left_width=np.full((_DEMO_POINTS, 2), 3.5)), "lane.left_width", id="lane-2d"),
    pytest.param(_lane(left_width=_widths((3, NAN))), "lane.left_width.3", id="lane.left_width.3=nan"),
    pytest.param(_lane(left_width=_widths((3, -1.0))), "lane.left_width.3", id="lane.left_width.3=-1"),
    pytest.param(
        _lane(right_width=_widths((2, INF), (7, -1.0))), "lane.right_width.2", id="lane.right_width.2=inf"
    ),
    pytest.param(
        _lane(left_width=_widths((5, 2 * MAX_SIZE))), "lane.left_width.5", id="lane.left_width.5-huge"
    ),
    pytest.param(_lane(left_width=list(_widths())), None, id="lane-list"),
    pytest.param(_lane(left_width=np.zeros(_DEMO_POINTS), right_width=0.0), None, id="lane-zero"),
    pytest.param(_lane(left_width=MAX_SIZE), None, id="lane-widest"),
    # the reference line: refused by the problem (not numbers) or by build_reference when planning
    pytest.param(_reference("abc"), "reference_line", id="reference-string"),
    pytest.param(_reference([[0.0, 0.0], [1.0, NAN], [2.0, 0.0]]), "reference_line.1", id="reference-nan"),
    pytest.param(_reference([[0.0, 0.0]]), "reference_line", id="reference-one-point"),
    pytest.param(_reference(np.zeros((5, 3))), "reference_line", id="reference-3-columns"),
]


@pytest.mark.parametrize(("make", "field"), INPUTS)
def test_a_bad_input_is_refused_naming_its_field_or_plans(
    make: Callable[[], PlanningProblem], field: str | None
) -> None:
    _refused_naming_or_planned(make, field)


def test_a_speed_rounded_below_standstill_is_standstill() -> None:
    assert Ego(x=0.0, y=0.0, heading=0.0, speed=-1e-12).speed == 0.0
    assert Ego(x=0.0, y=0.0, heading=0.0, speed=-STANDSTILL_TOLERANCE).speed == 0.0
    with pytest.raises(InvalidInputError, match="forwards"):
        Ego(x=0.0, y=0.0, heading=0.0, speed=np.nextafter(-STANDSTILL_TOLERANCE, -INF))


def test_lane_widths_are_stored_as_float_arrays() -> None:
    lane = Lane([3, 4, 5], np.int64(2))  # type: ignore[arg-type]
    assert isinstance(lane.left_width, np.ndarray) and lane.left_width.dtype == np.float64
    assert lane.right_width == 2.0
    widths = np.array([3.0, 4.0])
    assert Lane(widths, widths).left_width is widths


def test_candidates_refuse_a_lane_not_matching_the_reference() -> None:
    """Called without a :class:`PlanningProblem` (which checks the count), a short lane is refused
    by the width lookup rather than indexed past its end."""
    problem = demo_problem()
    ref = build_reference(problem.reference_line)
    for count in (_DEMO_POINTS - 1, 0):
        lane = Lane(_widths(count=count), 3.5)
        with pytest.raises(InvalidInputError) as err:
            generate_candidates(ref, lane, problem.ego, problem.vehicle, problem.options)
        assert err.value.field == "lane.left_width"


@pytest.mark.parametrize(
    ("name", "kind"), [("lane", Lane), ("ego", Ego), ("vehicle", Vehicle), ("options", Options)]
)
def test_a_problem_refuses_a_part_of_the_wrong_type(name: str, kind: type) -> None:
    wrong: dict[str, Any] = {name: object()}
    with pytest.raises(InvalidInputError, match=kind.__name__) as err:
        replace(demo_problem(), **wrong)
    assert err.value.field == name


# --------------------------------------------------------------------------------------------------
# Never stricter than the API: every bound of its request plans
# --------------------------------------------------------------------------------------------------


def _api_bounds() -> list[Any]:
    """One case per bound of a numeric field of the API's ego, vehicle and options (and the lane
    widths): ``(section, field, value)``, the value at the bound (just inside it for ``gt``)."""
    cases = []
    for section, model in (("ego", api.Ego), ("vehicle", api.Vehicle), ("options", api.Options)):
        for name, info in model.model_fields.items():
            for meta in info.metadata:
                if isinstance(meta, annotated_types.Gt):
                    value: Any = np.nextafter(float(meta.gt), INF)  # type: ignore[arg-type]
                elif isinstance(meta, annotated_types.Ge | annotated_types.Le):
                    value = meta.ge if isinstance(meta, annotated_types.Ge) else meta.le
                else:
                    continue
                cases.append(pytest.param(section, name, value, id=f"{section}.{name}={value}"))
    for value in (0.0, limits.MAX_LANE_WIDTH):
        cases.append(pytest.param("lane", "left_width", value, id=f"lane.left_width={value}"))
        cases.append(
            pytest.param("lane", "right_width", [value] * _DEMO_POINTS, id=f"lane.right_width=[{value}]")
        )
    return cases


@pytest.mark.parametrize(("section", "name", "value"), _api_bounds())
def test_every_bound_the_api_accepts_the_library_accepts(section: str, name: str, value: Any) -> None:
    body = conversions.from_problem(demo_problem()).model_dump()
    if section == "vehicle" and name in CAR_FIELDS:  # a car: the demo's vehicle with a wheelbase
        body["vehicle"].update(wheelbase=2.7, rear_axle_offset=1.35)
    body[section][name] = value
    if name == "speed_limit":  # at least the target speed
        body["options"]["target_speed"] = min(body["options"]["target_speed"], value)
    if body["options"]["dt"] > body["options"]["horizon_time"]:  # refused as a whole by the API
        with pytest.raises(ValidationError, match=r"options\.dt"):
            api.PlanningRequest.model_validate(body)
        return
    if (name, value) == ("rear_axle_offset", limits.MAX_VEHICLE_LENGTH / 2):  # behind a 4.5 m vehicle
        with pytest.raises(ValidationError, match=r"vehicle\.rear_axle_offset"):
            api.PlanningRequest.model_validate(body)
        body["vehicle"]["length"] = limits.MAX_VEHICLE_LENGTH
        # the 100 m vehicle's rear axle, 50 m behind the ego's centre, is off the road
        with pytest.raises(InvalidInputError, match="before the start of the reference line"):
            plan(conversions.to_problem(api.PlanningRequest.model_validate(body)))
        return
    problem = conversions.to_problem(api.PlanningRequest.model_validate(body))
    if section == "ego" and name in ("x", "y", "heading"):
        return  # the road judges a position or a heading: 10⁷ m off it is refused by the planner
    _planned(problem)


# --------------------------------------------------------------------------------------------------
# Extreme but accepted options (and ego states)
# --------------------------------------------------------------------------------------------------


def _counts(low: int, high: int, *special: int) -> st.SearchStrategy[int]:
    """Half the time an integer in ``[low, high]``, half the time ``low``, ``high`` or a ``special``."""
    return st.one_of(st.sampled_from([low, high, *special]), st.integers(low, high))


@st.composite
def extreme_options(draw: st.DrawFn) -> Options:
    """Options from anywhere in the ranges :class:`Options` accepts."""
    dt = draw(_log_uniform(MIN_DT, MAX_HORIZON_TIME, 0.02, 0.1, 1.0))
    # just inside the bound on the steps (dt × MAX_TRAJECTORY_POINTS may round above it)
    longest = min(MAX_HORIZON_TIME, dt * MAX_TRAJECTORY_POINTS * (1.0 - 1e-12))
    horizon = draw(_log_uniform(SMALLEST_LIMIT, longest, DENORMAL, 8.0))
    points = draw(_counts(2, MAX_NUM_POINTS, 100))
    candidates = draw(_counts(1, MAX_CANDIDATE_POINTS // points, 32))
    return Options(
        horizon_time=horizon,
        dt=dt,
        target_speed=draw(st.one_of(st.none(), _log_uniform(SMALLEST_LIMIT, LARGEST, 0.0, 7.0))),
        num_candidates=candidates,
        num_points=points,
        generator=draw(st.sampled_from(["naive", "transf_kappa"])),
        seed=draw(st.integers(0, 2**64)),
        return_candidates=draw(st.booleans()),
        lateral_margin=draw(_log_uniform(SMALLEST_LIMIT, MAX_SIZE, 0.0, 0.2)),
        min_path_length=draw(_log_uniform(SMALLEST_LIMIT, LARGEST, 0.0, 20.0)),
        time_budget_ms=draw(st.one_of(st.none(), _log_uniform(SMALLEST_LIMIT, 1e6))),
    )


@st.composite
def extreme_egos(draw: st.DrawFn) -> Ego:
    """The demo's ego position with a speed, acceleration, curvature and heading from anywhere in the
    ranges :class:`Ego` accepts (the heading within 80° of the road's, which is the +x axis there)."""
    curvature = st.floats(-MAX_EGO_CURVATURE, MAX_EGO_CURVATURE)
    return Ego(
        x=-15.0,
        y=draw(st.floats(-3.0, 3.0)),
        heading=draw(st.floats(-1.4, 1.4)) + 2.0 * np.pi * draw(st.integers(-3, 3)),
        speed=draw(_log_uniform(SMALLEST_LIMIT, MAX_EGO_SPEED, 0.0, -STANDSTILL_TOLERANCE, 5.0)),
        acceleration=draw(st.floats(-MAX_ACCELERATION, MAX_ACCELERATION)),
        curvature=draw(
            st.one_of(st.none(), curvature, st.sampled_from([-MAX_EGO_CURVATURE, MAX_EGO_CURVATURE]))
        ),
    )


@settings(max_examples=25, deadline=None)
@given(options=extreme_options())
def test_extreme_accepted_options_plan(options: Options) -> None:
    problem = replace(demo_problem(), options=options)
    _planned(problem)
    _candidates(problem)


@settings(max_examples=25, deadline=None)
@given(ego=extreme_egos())
def test_extreme_accepted_ego_states_plan(ego: Ego) -> None:
    problem = replace(demo_problem(), ego=ego)
    _planned(problem)
    _candidates(problem)
