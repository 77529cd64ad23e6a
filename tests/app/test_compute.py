"""app.compute: the wait for a plan process is bounded by the request's own budget, found in the body
without parsing it; every computing answer says how long it waited and ran (Server-Timing)."""

from __future__ import annotations

import re
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.compute import requested_budget_ms


@pytest.mark.parametrize(
    ("body", "budget"),
    [
        (b'{"options": {"time_budget_ms": 250}}', 250.0),
        (b'{"options": {"time_budget_ms" :\n 2.5e3, "seed": 1}}', 2500.0),
        (b'{"options": {"time_budget_ms": null}}', 1000.0),  # the server's
        (b'{"options": {"time_budget_ms": 0.5}}', 1000.0),  # out of range: refused by validation later
        (b'{"options": {"time_budget_ms": 1e9}}', 1000.0),
        (b'{"options": {}}', 1000.0),
        (b'{"options": {"time_budget_ms": "5"}}', 1000.0),
    ],
)
def test_the_budget_is_found_in_the_body(body: bytes, budget: float) -> None:
    assert requested_budget_ms(body, 1000.0) == budget


def test_every_computing_answer_has_server_timing(client: TestClient, demo: dict[str, Any]) -> None:
    road = {"reference_line": [[0, 0], [10, 0]]}
    answers = [
        client.post("/v1/plan", json=demo),
        client.post("/v1/candidates", json=demo),
        client.post("/v1/frenet", json={**road, "points": [[1, 1]]}),
        client.post("/v1/cartesian", json={**road, "frenet": [[1, 1]]}),
    ]
    for r in answers:
        assert r.status_code == 200
        timing = dict(re.findall(r"(\w+);dur=([0-9.]+)", r.headers["Server-Timing"]))
        assert set(timing) == {"wait", "run", "total"}
        assert float(timing["total"]) >= float(timing["run"])
