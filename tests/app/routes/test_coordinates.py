"""POST /v1/frenet and /v1/cartesian: exact on straight references, inverse of each other on the
U-turn; a non-finite result is a 500, never null."""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app import jobs as coordinates_route
from tests.app.helpers import post


@pytest.mark.parametrize("heading", [0.0, 0.7, -2.5])
def test_frenet_of_points_on_a_straight_reference_is_exact(
    client: TestClient, heading: float
) -> None:
    e = np.array([math.cos(heading), math.sin(heading)])
    n = np.array([-e[1], e[0]])
    origin = np.array([100.0, -50.0])
    sd = [(10.0, 2.0), (50.0, -3.0), (99.0, 0.5), (0.0, 0.0)]
    points = [(origin + s * e + d * n).tolist() for s, d in sd]
    body = {"reference_line": [origin.tolist(), (origin + 100 * e).tolist()], "points": points}
    r = client.post("/v1/frenet", json=body)
    assert r.status_code == 200, r.text
    out = r.json()
    assert out["s"] == pytest.approx([s for s, _ in sd], abs=1e-9)
    assert out["d"] == pytest.approx([d for _, d in sd], abs=1e-9)


def test_cartesian_on_a_straight_reference_is_exact(client: TestClient) -> None:
    body = {"reference_line": [[0, 0], [0, 100]], "frenet": [[10, 2], [50, -3], [120, 1]]}
    r = client.post("/v1/cartesian", json=body)
    assert r.status_code == 200, r.text
    # heading +y: the left normal is −x
    assert np.allclose(r.json()["points"], [[-2, 10], [3, 50], [-1, 120]], atol=1e-9)


def test_cartesian_frenet_round_trip_on_the_u_turn(
    client: TestClient, demo: dict[str, Any]
) -> None:
    road = demo["reference_line"]
    frenet = [[s, d] for s in (5.0, 30.0, 55.0, 80.0) for d in (-3.0, 0.0, 2.5)]
    r = client.post("/v1/cartesian", json={"reference_line": road, "frenet": frenet})
    assert r.status_code == 200, r.text
    points = r.json()["points"]
    assert len(points) == len(frenet)
    r = client.post("/v1/frenet", json={"reference_line": road, "points": points})
    assert r.status_code == 200, r.text
    assert r.json()["s"] == pytest.approx([s for s, _ in frenet], abs=1e-6)
    assert r.json()["d"] == pytest.approx([d for _, d in frenet], abs=1e-6)


def test_non_finite_result_is_a_500_not_null(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    def nan_frenet(ref: Any, points: Any) -> Any:
        return SimpleNamespace(s=np.full(len(points), np.nan), d=np.zeros(len(points)))

    monkeypatch.setattr(coordinates_route, "to_frenet", nan_frenet)
    r = post(client, {"reference_line": [[0, 0], [1, 0]], "points": [[0, 0]]}, "/v1/frenet")
    assert r.status_code == 500
    assert r.json()["error"]["code"] == "internal_error"
