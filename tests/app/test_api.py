"""Happy paths of every endpoint, with assertions on what they compute."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.conversions import from_problem, to_problem
from planner.roads import demo_problem

SCENARIOS = Path(__file__).resolve().parents[1] / "data" / "commonroad"


def test_healthz(client: TestClient) -> None:
    r = client.get("/healthz")
    assert r.status_code == 200
    assert r.json() == {"status": "ok"}


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


def test_candidates_transf_kappa(client: TestClient, demo: dict[str, Any]) -> None:
    demo["options"]["num_candidates"] = 32
    r = client.post("/v1/candidates", json=demo)
    assert r.status_code == 200, r.text
    out = r.json()
    assert len(out["candidates"]) == 32
    for candidate in out["candidates"]:
        s = [p["s"] for p in candidate["points"]]
        assert len(s) >= 2
        assert all(b > a for a, b in itertools.pairwise(s)), "s must strictly increase"
        assert all(math.isfinite(p[k]) for p in candidate["points"] for k in "sdxy")
        assert isinstance(candidate["repaired"], bool)
    diag = out["diagnostics"]
    assert diag["generated"] == 32
    assert diag["generator"] == "transf_kappa"
    assert diag["repaired"] == sum(c["repaired"] for c in out["candidates"])
    assert diag["repaired"] > 0  # the demo's wide inner side folds naive candidates
    assert diag["kept_points"] == sum(len(c["points"]) for c in out["candidates"])
    assert diag["reference_samples"] >= len(demo["reference_line"])
    assert diag["reference_spacing"] > 0
    assert diag["ego_s"] == pytest.approx(25.0, abs=1e-3)  # ego at x = −30 on the first leg (−40)
    # the first point of every candidate is the ego's Frenet position
    first = {
        (round(c["points"][0]["s"], 6), round(c["points"][0]["d"], 6)) for c in out["candidates"]
    }
    assert len(first) == 1


def test_candidates_naive_keeps_every_point(client: TestClient, demo: dict[str, Any]) -> None:
    demo["options"].update(generator="naive", num_candidates=5, num_points=40)
    r = client.post("/v1/candidates", json=demo)
    assert r.status_code == 200, r.text
    out = r.json()
    assert [len(c["points"]) for c in out["candidates"]] == [40] * 5
    assert out["diagnostics"]["repaired"] == 0
    assert out["diagnostics"]["generator"] == "naive"


def test_candidates_depend_on_seed_only(client: TestClient, demo: dict[str, Any]) -> None:
    demo["options"]["num_candidates"] = 4
    a = client.post("/v1/candidates", json=demo).json()
    b = client.post("/v1/candidates", json=demo).json()
    demo["options"]["seed"] = 1
    c = client.post("/v1/candidates", json=demo).json()
    assert a == b
    assert a != c


def test_per_point_widths_with_zeros(client: TestClient) -> None:
    road = [[float(x), 0.0] for x in range(0, 101, 5)]
    left = [0.0 if i in (0, 7) else 3.5 for i in range(len(road))]
    body = {
        "reference_line": road,
        "lane": {"left_width": left, "right_width": 2.0},
        "ego": {"x": 1.0, "y": 0.0, "heading": 0.0},
        "options": {"num_candidates": 3},
    }
    r = client.post("/v1/candidates", json=body)
    assert r.status_code == 200, r.text
    assert len(r.json()["candidates"]) == 3


def test_demo_posts_back(client: TestClient) -> None:
    r = client.get("/v1/demo")
    assert r.status_code == 200
    request = r.json()
    assert {"reference_line", "lane", "obstacles", "ego", "vehicle", "options"} <= set(request)
    r = client.post("/v1/candidates", json=request)
    assert r.status_code == 200, r.text
    assert len(r.json()["candidates"]) == request["options"]["num_candidates"]


def test_demo_pipes_into_curl_without_a_content_type(client: TestClient) -> None:
    """`curl …/v1/demo | curl -X POST …/v1/candidates -d @-` sends a form Content-Type."""
    raw = client.get("/v1/demo").content
    for content_type in ("application/x-www-form-urlencoded", "text/plain", None):
        headers = {"content-type": content_type} if content_type else {}
        r = client.post("/v1/candidates", content=raw, headers=headers)
        assert r.status_code == 200, (content_type, r.text)


def test_problem_round_trip() -> None:
    problem = demo_problem()
    again = to_problem(from_problem(problem))
    assert np.array_equal(again.reference_line, problem.reference_line)
    assert again.lane == problem.lane
    assert again.ego == problem.ego
    assert again.vehicle == problem.vehicle
    assert again.options == problem.options
    assert len(again.obstacles) == len(problem.obstacles)
    for a, b in zip(again.obstacles, problem.obstacles, strict=True):
        assert type(a) is type(b) and a.id == b.id


@pytest.mark.skipif(not SCENARIOS.is_dir(), reason="tests/data/commonroad is missing")
def test_real_scenario_requests(client: TestClient) -> None:
    files = sorted(p for p in SCENARIOS.glob("*.json") if p.name != "index.json")
    assert files
    for path in files:
        request = json.loads(path.read_text())
        r = client.post("/v1/candidates", json=request)
        assert r.status_code == 200, (path.name, r.text[:500])
        assert len(r.json()["candidates"]) == 32
