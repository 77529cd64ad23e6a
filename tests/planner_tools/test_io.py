"""The JSON request reader (``planner_tools.io``): the same problems as the HTTP layer's, every bad field
named."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from app.conversions import demo_request, to_problem
from app.models.planning import PlanningRequest
from planner.errors import InvalidInputError
from planner.problem import PlanningProblem
from planner_tools.io import problem_from_json, problem_to_json

ROOT = Path(__file__).resolve().parents[2]
COMMONROAD = sorted(p for p in (ROOT / "tests/data/commonroad").glob("*.json") if p.name != "index.json")


def _same(a: PlanningProblem, b: PlanningProblem) -> None:
    np.testing.assert_array_equal(a.reference_line, b.reference_line)
    assert (a.road is None) == (b.road is None)
    for widths_a, widths_b in ((a.lane, b.lane), (a.road, b.road)):
        for side in ("left_width", "right_width"):
            np.testing.assert_array_equal(getattr(widths_a, side, 0), getattr(widths_b, side, 0))
    assert (a.goal is None) == (b.goal is None)
    if a.goal is not None and b.goal is not None:
        assert (a.goal.time, a.goal.speed) == (b.goal.time, b.goal.speed)
        assert type(a.goal.position) is type(b.goal.position)
        for name in ("polygon", "center", "radius"):
            if hasattr(a.goal.position, name):
                np.testing.assert_array_equal(getattr(a.goal.position, name), getattr(b.goal.position, name))
    assert (a.ego, a.vehicle, a.options) == (b.ego, b.vehicle, b.options)
    assert [type(o) for o in a.obstacles] == [type(o) for o in b.obstacles]
    for x, y in zip(a.obstacles, b.obstacles, strict=True):
        assert x.id == y.id
        for name in ("polygon", "center", "radius", "prediction", "length", "width"):
            if hasattr(x, name):
                np.testing.assert_array_equal(getattr(x, name), getattr(y, name))


@pytest.mark.parametrize("path", COMMONROAD, ids=[p.stem for p in COMMONROAD])
def test_reader_agrees_with_the_http_layer(path: Path) -> None:
    data = json.loads(path.read_text())
    _same(problem_from_json(data), to_problem(PlanningRequest.model_validate(data)))


def test_reader_round_trips_the_demo() -> None:
    data = demo_request().model_dump(mode="json")
    problem = problem_from_json(data)
    _same(problem, to_problem(demo_request()))
    _same(problem_from_json(json.loads(json.dumps(problem_to_json(problem)))), problem)
    data["options"].update(time_budget_ms=50.0, generator="naive", target_speed=None)
    _same(problem_from_json(data), to_problem(PlanningRequest.model_validate(data)))


def test_reader_reads_a_car_as_the_http_layer_does() -> None:
    data = demo_request().model_dump(mode="json")  # the point model's car fields are null
    assert problem_from_json(data).vehicle.wheelbase is None
    data["vehicle"].update(wheelbase=2.7, rear_axle_offset=0.0, max_steering_rate=0.4)
    problem = problem_from_json(data)
    _same(problem, to_problem(PlanningRequest.model_validate(data)))
    assert problem.vehicle.is_car and problem.vehicle.max_steering_angle is None
    _same(problem_from_json(json.loads(json.dumps(problem_to_json(problem)))), problem)
    data["vehicle"]["rear_axle_offset"] = None
    with pytest.raises(InvalidInputError) as err:
        problem_from_json(data)
    assert err.value.field == "vehicle.rear_axle_offset"


@pytest.mark.parametrize(
    "extra",
    [
        {"road": {"left_width": 19.0, "right_width": 8.0}, "goal": {"time": [0.0, 4.0], "speed": [0.0, 2.0]}},
        {"goal": {"position": {"polygon": [[0, 0], [5, 0], [5, 5]]}}},
        {"goal": {"position": {"circle": {"center": [3, 4], "radius": 2}}, "time": [-1.0, 1.0]}},
    ],
)
def test_reader_reads_road_goal_and_speed_limit_as_the_http_layer_does(extra: dict[str, Any]) -> None:
    data = {**_demo(), **extra}
    data["options"].update(target_speed=5.0, speed_limit=9.0)
    problem = problem_from_json(data)
    _same(problem, to_problem(PlanningRequest.model_validate(data)))
    _same(problem_from_json(json.loads(json.dumps(problem_to_json(problem)))), problem)
    assert problem.options.speed_limit == 9.0


#: a polygon without area
LINE = [[0, 0], [1, 0], [2, 0]]
NO_RADIUS = {"center": [0, 0]}


def _demo() -> dict[str, Any]:
    return demo_request().model_dump(mode="json")


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d.pop("ego"), "ego"),
        (lambda d: d["ego"].update(speed=True), "ego.speed"),
        (lambda d: d["ego"].update(x="1"), "ego.x"),
        (lambda d: d["ego"].update(speed=-1.0), "ego.speed"),
        (lambda d: d.update(colour="red"), "colour"),
        (lambda d: d["options"].update(generator="magic"), "options.generator"),
        (lambda d: d["options"].update(num_candidates=2.5), "options.num_candidates"),
        (lambda d: d["vehicle"].update(length=0.0), "vehicle.length"),
        (lambda d: d["lane"].update(left_width=[1.0, 2.0]), "lane.left_width"),
        (lambda d: d["obstacles"][0].update(polygon=[[0, 0], [1, 0], [0, 1]]), "obstacles[0]"),
        (lambda d: d["obstacles"][0]["circle"].update(radius=-1.0), "obstacles[0].circle.radius"),
        (lambda d: d["reference_line"][3].append(1.0), "reference_line[3]"),
        (lambda d: d["reference_line"][0].__setitem__(0, float("nan")), "reference_line[0][0]"),
        (lambda d: d.update(road={"left_width": 0.5, "right_width": 9.0}), "road.left_width"),
        (lambda d: d.update(road={"left_width": 19.0}), "road.right_width"),
        (lambda d: d["options"].update(target_speed=5.0, speed_limit=4.0), "options.speed_limit"),
        (lambda d: d.update(goal={"time": [3.0, 1.0]}), "goal.time"),
        (lambda d: d.update(goal={"speed": [0.0]}), "goal.speed"),
        (lambda d: d.update(goal={"position": {"circle": NO_RADIUS}}), "goal.position.circle.radius"),
        (lambda d: d.update(goal={"position": {"polygon": LINE}}), "goal.position.polygon"),
    ],
)
def test_reader_names_the_bad_field(edit: Any, field: str) -> None:
    data = _demo()
    edit(data)
    with pytest.raises(InvalidInputError) as err:
        problem_from_json(data)
    assert err.value.field == field


def test_reader_checks_predictions() -> None:
    data = _demo()
    data["obstacles"].append(
        {
            "id": "car",
            "length": 4.0,
            "width": 2.0,
            "prediction": [
                {"t": 0.0, "x": 0, "y": 0, "heading": 0},
                {"t": 0.0, "x": 1, "y": 0, "heading": 0},
            ],
        }
    )
    with pytest.raises(InvalidInputError) as err:
        problem_from_json(data)
    assert err.value.field == "obstacles[1].prediction[1].t"
    data["obstacles"][1]["id"] = "cone"
    data["obstacles"][1]["prediction"][1]["t"] = 1.0
    with pytest.raises(InvalidInputError) as err:
        problem_from_json(data)
    assert err.value.field == "obstacles[1].id"
