"""app.errors: every client mistake is a 4xx in the one error shape naming the field, a planner error
gets the code of its nearest class in the table, and a bug is a logged 500."""

from __future__ import annotations

import json
import logging
from typing import Any

import pytest
from fastapi.testclient import TestClient

from planner.errors import InvalidInputError, PlannerError
from tests.app.helpers import error_fields, expect, fail_candidates, post


def test_malformed_json(client: TestClient) -> None:
    r = post(client, '{"reference_line": [[0, 0],')
    expect(r, 422, "malformed_json", "")
    assert "line 1" in r.json()["error"]["details"][0]["message"]


def test_huge_integer_literal(client: TestClient, demo: dict[str, Any]) -> None:
    text = json.dumps(demo).replace('"seed": 0', '"seed": 1' + "0" * 5000, 1)
    expect(post(client, text), 422, "malformed_json", "")


def test_deeply_nested_json(client: TestClient) -> None:
    expect(post(client, "[" * 100_000), 422, "malformed_json", "")


@pytest.mark.parametrize("body", ["", "[1, 2]", "null", '"text"'])
def test_body_not_an_object(client: TestClient, body: str) -> None:
    expect(post(client, body), 422, "invalid_request", "")


def test_a_long_list_stops_at_its_first_bad_item(client: TestClient) -> None:
    r = post(client, {"reference_line": [["a", "b"]] * 5000, "points": [[0, 0]]}, "/v1/frenet")
    assert r.status_code == 422
    assert error_fields(r) == ["reference_line.0.0", "reference_line.0.1"]


def test_many_problems_are_capped(client: TestClient, demo: dict[str, Any]) -> None:
    demo["obstacles"] = [{"id": f"o{i}", "circle": {"center": [0, 0], "radius": "x"}} for i in range(300)]
    r = post(client, demo, "/v1/plan")
    assert r.status_code == 422
    fields = error_fields(r)
    assert len(fields) == 50 and fields[0] == "obstacles.0.circle.radius"
    assert "300 problems" in r.json()["error"]["message"]


@pytest.mark.parametrize(
    ("text", "field"),
    [
        ('{"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]], "points": [[1, 1]]}', "points"),
        (
            '{"reference_line": [[0, 0], [10, 0]], "lane": {"left_width": 1, "right_width": 1}, '
            '"ego": {"x": 1, "y": 0, "heading": 0}, '
            '"obstacles": [{"id": "a", "circle": {"center": [5, 0], "radius": 1, "radius": 2}}]}',
            "obstacles.0.circle.radius",
        ),
    ],
)
def test_a_duplicate_key_is_named(client: TestClient, text: str, field: str) -> None:
    path = "/v1/frenet" if '"points"' in text else "/v1/plan"
    r = post(client, text, path)
    expect(r, 422, "duplicate_key", field)
    assert repr(field.rsplit(".", 1)[-1]) in r.json()["error"]["details"][0]["message"]


def test_a_body_with_more_arrays_than_any_request_is_refused_unparsed(client: TestClient) -> None:
    text = '{"reference_line": [' + ",".join(["[]"] * 200_000) + '], "points": [[0, 0]]}'
    r = post(client, text, "/v1/frenet")
    expect(r, 422, "invalid_request", "")
    assert "200003 JSON arrays" in r.json()["error"]["details"][0]["message"]


@pytest.mark.parametrize(
    ("road", "field"),
    [
        ([[0, 0], [10, 0], [5, 0]], "reference_line.1"),
        ([[0, 0], [5, 5], [5, 5], [1, 1]], "reference_line.1"),
    ],
)
def test_reference_turning_straight_back(client: TestClient, road: Any, field: str) -> None:
    r = post(client, {"reference_line": road, "points": [[0, 0]]}, "/v1/frenet")
    expect(r, 422, "invalid_reference", field)


def test_reference_without_two_distinct_points(client: TestClient) -> None:
    r = post(client, {"reference_line": [[1, 1], [1, 1]], "points": [[0, 0]]}, "/v1/frenet")
    expect(r, 422, "invalid_reference", "reference_line")


def test_ego_against_the_driving_direction(client: TestClient, demo: dict[str, Any]) -> None:
    demo["ego"]["heading"] = 3.0
    expect(post(client, demo), 422, "invalid_input", "ego.heading")


def test_ego_past_the_end(client: TestClient, demo: dict[str, Any]) -> None:
    demo["ego"].update(x=-60.0, y=16.0, heading=3.14159)
    expect(post(client, demo), 422, "invalid_input", "ego")


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
    fail_candidates(monkeypatch, error)
    expect(post(client, demo), 422, code, "obstacles")


def test_bug_is_a_logged_500(
    client: TestClient,
    demo: dict[str, Any],
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    fail_candidates(monkeypatch, ZeroDivisionError("secret internals"))
    with caplog.at_level(logging.ERROR, logger="app"):
        r = post(client, demo)
    assert r.status_code == 500
    assert r.json()["error"]["code"] == "internal_error"
    assert "secret" not in r.text
    error_fields(r)
    assert any(rec.exc_info and rec.exc_info[0] is ZeroDivisionError for rec in caplog.records)


def test_unknown_path_and_method(client: TestClient) -> None:
    r = client.get("/v1/nowhere")
    assert r.status_code == 404 and r.json()["error"]["code"] == "not_found"
    r = client.get("/v1/candidates")
    assert r.status_code == 405 and r.json()["error"]["code"] == "method_not_allowed"
