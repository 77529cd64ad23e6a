"""app.models.planning: a planning request that breaks the schema is a 422 naming the field."""

from __future__ import annotations

from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.app.helpers import expect, post


@pytest.mark.parametrize(
    ("section", "key", "value", "field"),
    [
        ("ego", "speed", "5", "ego.speed"),
        ("ego", "heading", None, "ego.heading"),
        ("ego", "x", True, "ego.x"),
        ("options", "num_candidates", 3.5, "options.num_candidates"),
        ("options", "return_candidates", "yes", "options.return_candidates"),
        ("options", "generator", "fancy", "options.generator"),
        ("options", "unknown_option", 1, "options.unknown_option"),
        ("vehicle", "width", 0, "vehicle.width"),
        ("options", "dt", 0.001, "options.dt"),
        ("options", "num_candidates", 10**30, "options.num_candidates"),
        ("ego", "x", 1e12, "ego.x"),
    ],
)
def test_wrong_type_or_range(
    client: TestClient, demo: dict[str, Any], section: str, key: str, value: Any, field: str
) -> None:
    demo[section][key] = value
    expect(post(client, demo), 422, "invalid_request", field)


def test_missing_field(client: TestClient, demo: dict[str, Any]) -> None:
    del demo["ego"]
    expect(post(client, demo), 422, "invalid_request", "ego")


@pytest.mark.parametrize("side", ["left_width", "right_width"])
def test_widths_of_wrong_length(client: TestClient, demo: dict[str, Any], side: str) -> None:
    demo["lane"][side] = [3.0] * (len(demo["reference_line"]) - 1)
    r = post(client, demo)
    expect(r, 422, "invalid_request", f"lane.{side}")
    assert str(len(demo["reference_line"])) in r.json()["error"]["details"][0]["message"]


def test_negative_width_in_a_list(client: TestClient, demo: dict[str, Any]) -> None:
    demo["lane"]["left_width"] = [3.0] * len(demo["reference_line"])
    demo["lane"]["left_width"][4] = -1.0
    expect(post(client, demo), 422, "invalid_request", "lane.left_width.4")


def test_width_of_wrong_type(client: TestClient, demo: dict[str, Any]) -> None:
    demo["lane"]["right_width"] = "wide"
    expect(post(client, demo), 422, "invalid_request", "lane.right_width")


@pytest.mark.parametrize(
    "polygon", [[[0, 0], [1, 1], [2, 2]], [[5, 5], [5, 5], [5, 5], [5, 5]], [[0, 0], [1, 0]]]
)
def test_degenerate_polygon(client: TestClient, demo: dict[str, Any], polygon: Any) -> None:
    demo["obstacles"] = [{"id": "p", "polygon": polygon}]
    expect(post(client, demo), 422, "invalid_request", "obstacles.0.polygon")


def test_prediction_time_not_increasing(client: TestClient, demo: dict[str, Any]) -> None:
    states = [{"t": t, "x": 0.0, "y": 0.0, "heading": 0.0} for t in (0.0, 0.5, 0.5, 1.0)]
    demo["obstacles"].append({"id": "car", "length": 4.0, "width": 2.0, "prediction": states})
    expect(post(client, demo), 422, "invalid_request", "obstacles.1.prediction.2.t")


def test_empty_prediction(client: TestClient, demo: dict[str, Any]) -> None:
    demo["obstacles"] = [{"id": "car", "length": 4.0, "width": 2.0, "prediction": []}]
    expect(post(client, demo), 422, "invalid_request", "obstacles.0.prediction")


@pytest.mark.parametrize(
    "obstacle", [{"id": "x"}, {"id": "x", "circle": {"center": [0, 0], "radius": 1}, "polygon": []}]
)
def test_obstacle_without_one_shape(
    client: TestClient, demo: dict[str, Any], obstacle: dict[str, Any]
) -> None:
    demo["obstacles"] = [obstacle]
    expect(post(client, demo), 422, "invalid_request", "obstacles.0")


def test_circle_of_zero_radius(client: TestClient, demo: dict[str, Any]) -> None:
    demo["obstacles"][0]["circle"]["radius"] = 0
    expect(post(client, demo), 422, "invalid_request", "obstacles.0.circle.radius")


def test_duplicate_obstacle_ids(client: TestClient, demo: dict[str, Any]) -> None:
    demo["obstacles"].append(demo["obstacles"][0])
    expect(post(client, demo), 422, "invalid_request", "obstacles.1.id")


def test_answer_size_limit(client: TestClient, demo: dict[str, Any]) -> None:
    demo["options"].update(num_candidates=2000, num_points=1000)
    expect(post(client, demo), 422, "invalid_request", "options.num_points")


def test_a_step_longer_than_the_horizon_is_refused(client: TestClient, demo: dict[str, Any]) -> None:
    demo["options"].update(horizon_time=0.5, dt=1.0)
    expect(post(client, demo), 422, "invalid_request", "options.dt")
    demo["options"].update(horizon_time=1.0, dt=1.0)
    assert post(client, demo).status_code == 200


#: a goal with every key, beside the demo road
GOAL = {
    "position": {"circle": {"center": [30.0, 0.0], "radius": 3.0}},
    "time": [2.0, 8.0],
    "speed": [0.0, 3.0],
}
DISC = {"center": [0, 0], "radius": 0}
LINE = [[0, 0], [1, 1], [2, 2]]


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d["options"].update(target_speed=8.0, speed_limit=7.0), "options.speed_limit"),
        (lambda d: d["options"].update(speed_limit=-1.0), "options.speed_limit"),
        (lambda d: d.update(road={"left_width": 1.0, "right_width": 20.0}), "road.left_width"),
        (lambda d: d.update(road={"left_width": [20.0, 20.0], "right_width": 20.0}), "road.left_width"),
        (lambda d: d.update(road={"left_width": 20.0}), "road.right_width"),
        (lambda d: d.update(goal={**GOAL, "time": [8.0, 2.0]}), "goal.time"),
        (lambda d: d.update(goal={**GOAL, "speed": [-1.0, 2.0]}), "goal.speed.0"),
        (lambda d: d.update(goal={**GOAL, "speed": [1.0]}), "goal.speed.1"),
        (lambda d: d.update(goal={"position": {"circle": DISC}}), "goal.position.circle.radius"),
        (lambda d: d.update(goal={"position": {"polygon": LINE}}), "goal.position.polygon"),
        (lambda d: d.update(goal={"position": {}}), "goal.position"),
        (lambda d: d.update(goal={"where": [0, 0]}), "goal.where"),
    ],
)  # fmt: skip
def test_speed_limit_road_and_goal_are_checked(
    client: TestClient, demo: dict[str, Any], edit: Any, field: str
) -> None:
    edit(demo)
    expect(post(client, demo), 422, "invalid_request", field)


def test_a_road_narrower_than_the_lane_at_one_point_is_named_by_its_index(
    client: TestClient, demo: dict[str, Any]
) -> None:
    n = len(demo["reference_line"])
    left = [20.0] * n
    left[3] = 0.5  # the demo's lane is wider there
    demo["road"] = {"left_width": left, "right_width": 20.0}
    expect(post(client, demo), 422, "invalid_request", "road.left_width.3")


def test_speed_limit_road_and_goal_are_accepted(client: TestClient, demo: dict[str, Any]) -> None:
    demo["options"].update(target_speed=5.0, speed_limit=8.0)
    demo["road"] = {"left_width": 20.0, "right_width": 12.0}
    demo["goal"] = GOAL
    response = post(client, demo)
    assert response.status_code == 200, response.text
