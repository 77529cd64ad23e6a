"""POST /v1/candidates: the candidates of Algorithm 5 (or 4) and their diagnostics."""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.conversions import to_problem
from app.models.planning import PlanningRequest
from planner.ego import ego_frenet, start_state
from planner.reference import build_reference

SCENARIOS = Path(__file__).resolve().parents[2] / "data" / "commonroad"


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
    diag = out["diagnostics"]
    assert diag["generated"] == 32
    assert diag["generator"] == "transf_kappa"
    assert diag["repaired"] == sum(c["repaired"] for c in out["candidates"])
    assert diag["repaired"] > 0  # the demo's wide inner side folds naive candidates
    assert {c["repaired"] for c in out["candidates"]} == {True, False}  # not all of them
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


@pytest.mark.skipif(not SCENARIOS.is_dir(), reason="tests/data/commonroad is missing")
def test_real_scenario_requests(client: TestClient) -> None:
    files = sorted(p for p in SCENARIOS.glob("*.json") if p.name != "index.json")
    assert files
    for path in files:
        request = json.loads(path.read_text())
        r = client.post("/v1/candidates", json=request)
        assert r.status_code == 200, (path.name, r.text[:500])
        assert len(r.json()["candidates"]) == 32


def test_candidates_are_the_plans_where_the_start_curvature_is_clipped(
    client: TestClient, demo: dict[str, Any]
) -> None:
    """An ego of unknown curvature in the U-turn, too fast for the road's curvature: the plan takes the
    curvature it can drive at its speed, and /v1/candidates starts from that same state."""
    demo["ego"].pop("curvature", None)
    demo["ego"].update(x=8.0, y=8.0, heading=np.pi / 2, speed=12.0)  # in the demo U-turn (radius 8 m)
    demo["options"].update(num_candidates=8, return_candidates=True)
    problem = to_problem(PlanningRequest.model_validate(demo))
    ref = build_reference(problem.reference_line)
    clipped, unclipped = start_state(ref, problem), ego_frenet(ref, problem.ego)
    assert abs(clipped.ddd - unclipped.ddd) > 1e-3  # the clip matters here, so the test can fail
    planned = client.post("/v1/plan", json=demo).json()["candidates"]
    alone = client.post("/v1/candidates", json=demo).json()["candidates"]
    assert alone == planned
