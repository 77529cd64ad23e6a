"""Every client mistake is a 4xx in the one error shape naming the field; bugs are a logged 500."""

from __future__ import annotations

import json
import logging
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.main import create_app
from app.routes import candidates as candidates_route
from app.routes import coordinates as coordinates_route
from app.settings import Settings
from planner.errors import InvalidInputError, PlannerError


def error_fields(response: Any) -> list[str]:
    """The fields named by an error answer, after checking it has the one error shape."""
    body = response.json()
    assert set(body) == {"error"}
    error = body["error"]
    assert set(error) == {"code", "message", "details"}
    assert isinstance(error["code"], str) and error["code"]
    assert isinstance(error["message"], str) and error["message"]
    for detail in error["details"]:
        assert set(detail) == {"field", "message"}
        assert isinstance(detail["field"], str) and detail["message"]
    return [d["field"] for d in error["details"]]


def _post(client: TestClient, body: Any, path: str = "/v1/candidates") -> Any:
    content = body if isinstance(body, str | bytes) else json.dumps(body)
    return client.post(path, content=content, headers={"content-type": "application/json"})


def _expect(response: Any, status: int, code: str, field: str) -> None:
    assert response.status_code == status, response.text
    assert response.json()["error"]["code"] == code
    assert field in error_fields(response)


def test_malformed_json(client: TestClient) -> None:
    r = _post(client, '{"reference_line": [[0, 0],')
    _expect(r, 422, "malformed_json", "")
    assert "line 1" in r.json()["error"]["details"][0]["message"]


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_non_finite_number(client: TestClient, demo: dict[str, Any], literal: str) -> None:
    text = json.dumps(demo).replace('"speed": 5.0', f'"speed": {literal}', 1)
    assert literal in text
    _expect(_post(client, text), 422, "invalid_request", "ego.speed")


def test_non_finite_in_a_list(client: TestClient) -> None:
    r = _post(client, '{"reference_line": [[0, 0], [NaN, 1]], "points": [[0, 0]]}', "/v1/frenet")
    _expect(r, 422, "invalid_request", "reference_line.1.0")


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
    _expect(_post(client, demo), 422, "invalid_request", field)


def test_huge_integer_literal(client: TestClient, demo: dict[str, Any]) -> None:
    text = json.dumps(demo).replace('"seed": 0', '"seed": 1' + "0" * 5000, 1)
    _expect(_post(client, text), 422, "malformed_json", "")


def test_deeply_nested_json(client: TestClient) -> None:
    _expect(_post(client, "[" * 100_000), 422, "malformed_json", "")


@pytest.mark.parametrize("body", ["", "[1, 2]", "null", '"text"'])
def test_body_not_an_object(client: TestClient, body: str) -> None:
    _expect(_post(client, body), 422, "invalid_request", "")


def test_missing_field(client: TestClient, demo: dict[str, Any]) -> None:
    del demo["ego"]
    _expect(_post(client, demo), 422, "invalid_request", "ego")


@pytest.mark.parametrize("points", [[], [[0, 0]]])
def test_too_few_reference_points(client: TestClient, points: list[Any]) -> None:
    r = _post(client, {"reference_line": points, "points": [[0, 0]]}, "/v1/frenet")
    _expect(r, 422, "invalid_request", "reference_line")


@pytest.mark.parametrize("path", ["/v1/frenet", "/v1/cartesian"])
def test_empty_query(client: TestClient, path: str) -> None:
    key = "points" if path.endswith("frenet") else "frenet"
    r = _post(client, {"reference_line": [[0, 0], [1, 0]], key: []}, path)
    _expect(r, 422, "invalid_request", key)


def test_point_with_three_coordinates(client: TestClient) -> None:
    r = _post(client, {"reference_line": [[0, 0], [1, 0, 2]], "points": [[0, 0]]}, "/v1/frenet")
    _expect(r, 422, "invalid_request", "reference_line.1")


@pytest.mark.parametrize(
    ("road", "field"),
    [
        ([[0, 0], [10, 0], [5, 0]], "reference_line.1"),
        ([[0, 0], [5, 5], [5, 5], [1, 1]], "reference_line.1"),
    ],
)
def test_reference_turning_straight_back(client: TestClient, road: Any, field: str) -> None:
    r = _post(client, {"reference_line": road, "points": [[0, 0]]}, "/v1/frenet")
    _expect(r, 422, "invalid_reference", field)


def test_reference_too_long(client: TestClient) -> None:
    r = _post(client, {"reference_line": [[0, 0], [1e7, 0]], "points": [[0, 0]]}, "/v1/frenet")
    _expect(r, 422, "invalid_request", "reference_line")


@pytest.mark.parametrize("side", ["left_width", "right_width"])
def test_widths_of_wrong_length(client: TestClient, demo: dict[str, Any], side: str) -> None:
    demo["lane"][side] = [3.0] * (len(demo["reference_line"]) - 1)
    r = _post(client, demo)
    _expect(r, 422, "invalid_request", f"lane.{side}")
    assert str(len(demo["reference_line"])) in r.json()["error"]["details"][0]["message"]


def test_negative_width_in_a_list(client: TestClient, demo: dict[str, Any]) -> None:
    demo["lane"]["left_width"] = [3.0] * len(demo["reference_line"])
    demo["lane"]["left_width"][4] = -1.0
    _expect(_post(client, demo), 422, "invalid_request", "lane.left_width.4")


def test_width_of_wrong_type(client: TestClient, demo: dict[str, Any]) -> None:
    demo["lane"]["right_width"] = "wide"
    _expect(_post(client, demo), 422, "invalid_request", "lane.right_width")


@pytest.mark.parametrize(
    "polygon", [[[0, 0], [1, 1], [2, 2]], [[5, 5], [5, 5], [5, 5], [5, 5]], [[0, 0], [1, 0]]]
)
def test_degenerate_polygon(client: TestClient, demo: dict[str, Any], polygon: Any) -> None:
    demo["obstacles"] = [{"id": "p", "polygon": polygon}]
    _expect(_post(client, demo), 422, "invalid_request", "obstacles.0.polygon")


def test_prediction_time_not_increasing(client: TestClient, demo: dict[str, Any]) -> None:
    states = [{"t": t, "x": 0.0, "y": 0.0, "heading": 0.0} for t in (0.0, 0.5, 0.5, 1.0)]
    demo["obstacles"].append({"id": "car", "length": 4.0, "width": 2.0, "prediction": states})
    _expect(_post(client, demo), 422, "invalid_request", "obstacles.1.prediction.2.t")


def test_empty_prediction(client: TestClient, demo: dict[str, Any]) -> None:
    demo["obstacles"] = [{"id": "car", "length": 4.0, "width": 2.0, "prediction": []}]
    _expect(_post(client, demo), 422, "invalid_request", "obstacles.0.prediction")


@pytest.mark.parametrize(
    "obstacle", [{"id": "x"}, {"id": "x", "circle": {"center": [0, 0], "radius": 1}, "polygon": []}]
)
def test_obstacle_without_one_shape(
    client: TestClient, demo: dict[str, Any], obstacle: dict[str, Any]
) -> None:
    demo["obstacles"] = [obstacle]
    _expect(_post(client, demo), 422, "invalid_request", "obstacles.0")


def test_circle_of_zero_radius(client: TestClient, demo: dict[str, Any]) -> None:
    demo["obstacles"][0]["circle"]["radius"] = 0
    _expect(_post(client, demo), 422, "invalid_request", "obstacles.0.circle.radius")


def test_duplicate_obstacle_ids(client: TestClient, demo: dict[str, Any]) -> None:
    demo["obstacles"].append(demo["obstacles"][0])
    _expect(_post(client, demo), 422, "invalid_request", "obstacles.1.id")


def test_answer_size_limit(client: TestClient, demo: dict[str, Any]) -> None:
    demo["options"].update(num_candidates=2000, num_points=1000)
    _expect(_post(client, demo), 422, "invalid_request", "options.num_points")


def test_a_step_longer_than_the_horizon_is_refused(client: TestClient, demo: dict[str, Any]) -> None:
    demo["options"].update(horizon_time=0.5, dt=1.0)
    _expect(_post(client, demo), 422, "invalid_request", "options.dt")
    demo["options"].update(horizon_time=1.0, dt=1.0)
    assert _post(client, demo).status_code == 200


def test_many_problems_are_capped(client: TestClient) -> None:
    r = _post(client, {"reference_line": [["a", "b"]] * 500, "points": [[0, 0]]}, "/v1/frenet")
    assert r.status_code == 422
    assert len(error_fields(r)) == 50
    assert "1000 problems" in r.json()["error"]["message"]


# -- errors of the planner ---------------------------------------------------------------------


def test_reference_without_two_distinct_points(client: TestClient) -> None:
    r = _post(client, {"reference_line": [[1, 1], [1, 1]], "points": [[0, 0]]}, "/v1/frenet")
    _expect(r, 422, "invalid_reference", "reference_line")


def test_ego_against_the_driving_direction(client: TestClient, demo: dict[str, Any]) -> None:
    demo["ego"]["heading"] = 3.0
    _expect(_post(client, demo), 422, "invalid_input", "ego.heading")


def test_ego_past_the_end(client: TestClient, demo: dict[str, Any]) -> None:
    demo["ego"].update(x=-60.0, y=16.0, heading=3.14159)
    _expect(_post(client, demo), 422, "invalid_input", "ego")


class _NarrowInputError(InvalidInputError):
    """A planner error class the table does not list."""


@pytest.mark.parametrize(
    ("error", "code"),
    [
        (PlannerError("no way through", field="obstacles"), "planner_error"),
        (_NarrowInputError("no way through", field="obstacles"), "invalid_input"),
    ],
)
def test_a_planner_error_is_422_with_the_code_of_its_nearest_class(
    client: TestClient, demo: dict[str, Any], monkeypatch: pytest.MonkeyPatch, error: Exception, code: str
) -> None:
    def fail(*args: Any, **kwargs: Any) -> Any:
        raise error

    monkeypatch.setattr(candidates_route, "generate_candidates", fail)
    _expect(_post(client, demo), 422, code, "obstacles")


def test_bug_is_a_logged_500(
    client: TestClient,
    demo: dict[str, Any],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    def crash(*args: Any, **kwargs: Any) -> Any:
        raise ZeroDivisionError("secret internals")

    monkeypatch.setattr(candidates_route, "generate_candidates", crash)
    with caplog.at_level(logging.ERROR, logger="app"):
        r = _post(client, demo)
    assert r.status_code == 500
    assert r.json()["error"]["code"] == "internal_error"
    assert "secret" not in r.text
    error_fields(r)
    assert any(rec.exc_info and rec.exc_info[0] is ZeroDivisionError for rec in caplog.records)


def test_non_finite_result_is_a_500_not_null(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    def nan_frenet(ref: Any, points: Any) -> Any:
        return SimpleNamespace(s=np.full(len(points), np.nan), d=np.zeros(len(points)))

    monkeypatch.setattr(coordinates_route, "to_frenet", nan_frenet)
    r = _post(client, {"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]]}, "/v1/frenet")
    assert r.status_code == 500
    assert r.json()["error"]["code"] == "internal_error"


# -- HTTP-level refusals -----------------------------------------------------------------------


def test_unknown_path_and_method(client: TestClient) -> None:
    r = client.get("/v1/nowhere")
    assert r.status_code == 404 and r.json()["error"]["code"] == "not_found"
    r = client.get("/v1/candidates")
    assert r.status_code == 405 and r.json()["error"]["code"] == "method_not_allowed"


def test_body_too_large() -> None:
    small = TestClient(create_app(Settings(max_body_bytes=2048)))
    body = json.dumps({"reference_line": [[i, 0] for i in range(400)], "points": [[0, 0]]})
    r = small.post("/v1/frenet", content=body)  # declared Content-Length
    assert r.status_code == 413 and r.json()["error"]["code"] == "payload_too_large"

    def chunks() -> Any:
        yield body[:1500].encode()
        yield body[1500:].encode()

    r = small.post("/v1/frenet", content=chunks())  # streamed, no Content-Length
    assert r.status_code == 413 and r.json()["error"]["code"] == "payload_too_large"
    assert (
        small.post(
            "/v1/frenet", json={"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]]}
        ).status_code
        == 200
    )
