"""app.models.common: strict finite numbers, points of two coordinates, and the reference polyline's
length limits."""

from __future__ import annotations

import json
from typing import Any

import pytest
from fastapi.testclient import TestClient

from tests.app.helpers import expect, post


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity", "1e999"])
def test_non_finite_number(client: TestClient, demo: dict[str, Any], literal: str) -> None:
    text = json.dumps(demo).replace('"speed": 5.0', f'"speed": {literal}', 1)
    assert literal in text
    expect(post(client, text), 422, "invalid_request", "ego.speed")


def test_non_finite_in_a_list(client: TestClient) -> None:
    r = post(client, '{"reference_line": [[0, 0], [NaN, 1]], "points": [[0, 0]]}', "/v1/frenet")
    expect(r, 422, "invalid_request", "reference_line.1.0")


@pytest.mark.parametrize("points", [[], [[0, 0]]])
def test_too_few_reference_points(client: TestClient, points: list[Any]) -> None:
    r = post(client, {"reference_line": points, "points": [[0, 0]]}, "/v1/frenet")
    expect(r, 422, "invalid_request", "reference_line")


def test_point_with_three_coordinates(client: TestClient) -> None:
    r = post(client, {"reference_line": [[0, 0], [1, 0, 2]], "points": [[0, 0]]}, "/v1/frenet")
    expect(r, 422, "invalid_request", "reference_line.1")


def test_reference_too_long(client: TestClient) -> None:
    r = post(client, {"reference_line": [[0, 0], [1e7, 0]], "points": [[0, 0]]}, "/v1/frenet")
    expect(r, 422, "invalid_request", "reference_line")
