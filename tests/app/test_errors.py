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


def test_many_problems_are_capped(client: TestClient) -> None:
    r = post(client, {"reference_line": [["a", "b"]] * 500, "points": [[0, 0]]}, "/v1/frenet")
    assert r.status_code == 422
    assert len(error_fields(r)) == 50
    assert "1000 problems" in r.json()["error"]["message"]


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
