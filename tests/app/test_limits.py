"""app.limits: every range the API accepts lies inside the planner's own caps; the requests .ci/fuzz.sh
(schemathesis) and its follow-up found answered 500 or hanging are refused with a 422 naming the field;
the smallest accepted values still plan.

(That every bound of a request field plans as a library problem: tests/planner/test_degenerate.py.)"""

from __future__ import annotations

import json
import math
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app import limits as api
from app.limits import (
    MAX_OBSTACLE_OUTLINE,
    MIN_OBSTACLE_SIZE,
    MIN_VEHICLE_ACCELERATION,
    MIN_VEHICLE_CURVATURE,
)
from app.settings import Settings
from planner import problem as planner

#: a denormal: positive, so `gt=0` let it through; braking distances v²/a overflowed to inf
DENORMAL = 5e-324


#: (the API's limit, the planner's cap on the same quantity, whether the API's is an upper bound)
PAIRS = [
    (api.MAX_LANE_WIDTH, planner.MAX_SIZE, True),
    (api.MAX_OBSTACLE_SIZE, planner.MAX_SIZE, True),
    (api.MAX_VEHICLE_LENGTH, planner.MAX_SIZE, True),
    (api.MAX_VEHICLE_WIDTH, planner.MAX_SIZE, True),
    (api.MAX_WHEELBASE, planner.MAX_SIZE, True),
    (api.MAX_STEERING_ANGLE, 0.5 * math.pi, True),
    (api.MIN_STEERING_RATE, planner.SMALLEST_LIMIT, False),
    (api.MAX_VEHICLE_SPEED, planner.MAX_EGO_SPEED, True),
    (api.MAX_VEHICLE_ACCELERATION, planner.MAX_ACCELERATION, True),
    (api.MAX_VEHICLE_CURVATURE, planner.MAX_EGO_CURVATURE, True),
    (api.MAX_PLAN_HORIZON, planner.MAX_HORIZON_TIME, True),
    (api.MAX_TRAJECTORY_STEP, planner.MAX_HORIZON_TIME, True),
    (api.MAX_PLAN_HORIZON / api.MIN_TRAJECTORY_STEP, planner.MAX_TRAJECTORY_POINTS, True),
    (api.MAX_POINTS_PER_CANDIDATE, planner.MAX_NUM_POINTS, True),
    (api.MAX_TOTAL_CANDIDATE_POINTS, planner.MAX_CANDIDATE_POINTS, True),
    (api.MIN_TRAJECTORY_STEP, planner.MIN_DT, False),
    (api.MIN_VEHICLE_ACCELERATION, planner.SMALLEST_LIMIT, False),
    (api.MIN_VEHICLE_CURVATURE, planner.SMALLEST_LIMIT, False),
]


@pytest.mark.parametrize(("limit", "cap", "upper"), PAIRS)
def test_the_api_accepts_only_what_the_planner_accepts(limit: float, cap: float, upper: bool) -> None:
    assert limit < cap if upper else limit > cap


def _set(body: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    *parents, key = path.split(".")
    node = body
    for p in parents:
        node = node[int(p)] if p.isdigit() else node[p]
    node[key] = value
    return body


def _circle(radius: float) -> list[dict[str, Any]]:
    return [{"id": "c", "circle": {"center": [9.0, 8.0], "radius": radius}}]


def _box(size: float) -> list[dict[str, Any]]:
    state = {"t": 0.0, "x": 0.0, "y": 9999999.0, "heading": 0.0}
    return [{"id": "b", "length": size, "width": size, "prediction": [state]}]


@pytest.mark.parametrize(
    ("path", "value", "field"),
    [
        ("vehicle.max_deceleration", DENORMAL, "vehicle.max_deceleration"),  # IndexError in offset_basis
        ("vehicle.max_deceleration", 1e-300, "vehicle.max_deceleration"),  # kd-tree overflow
        ("vehicle.max_curvature", DENORMAL, "vehicle.max_curvature"),  # non-finite d_ref
        ("vehicle.max_curvature", 1e-300, "vehicle.max_curvature"),  # OSQP setup error
        ("vehicle.max_acceleration", DENORMAL, "vehicle.max_acceleration"),
        ("vehicle.max_lateral_acceleration", DENORMAL, "vehicle.max_lateral_acceleration"),
        ("obstacles", _circle(1e-9), "obstacles.0.circle.radius"),  # minimum.reduceat on nothing
        ("obstacles", _box(DENORMAL), "obstacles.0.length"),  # GEOS: point array of one element
    ],
)
def test_a_degenerate_value_is_refused(
    client: TestClient, demo: dict[str, Any], path: str, value: Any, field: str
) -> None:
    for endpoint in ("/v1/plan", "/v1/candidates"):
        answer = client.post(endpoint, json=_set(demo, path, value))
        assert answer.status_code == 422, answer.text
        assert field in [d["field"] for d in answer.json()["error"]["details"]]


def test_obstacles_too_long_to_outline_are_refused(client: TestClient, demo: dict[str, Any]) -> None:
    """A 20 000 km square around everything: the planner densified its outline to 3·10⁸ points."""
    demo["obstacles"] = [{"id": "p", "polygon": [[-1e7, -1e7], [1e7, -1e7], [1e7, 1e7], [-1e7, 1e7]]}]
    answer = client.post("/v1/plan", json=demo)
    assert answer.status_code == 422, answer.text
    assert answer.json()["error"]["details"][0]["field"] == "obstacles"
    # just within the budget: many circles, far from the road
    radius = MAX_OBSTACLE_OUTLINE / (2 * 3.15 * 10)
    demo["obstacles"] = [
        {"id": f"c{i}", "circle": {"center": [200.0 * i, 500.0], "radius": radius}} for i in range(10)
    ]
    assert client.post("/v1/candidates", json=demo).status_code == 200


def test_the_smallest_accepted_values_plan(client: TestClient, demo: dict[str, Any]) -> None:
    demo["vehicle"].update(
        max_deceleration=MIN_VEHICLE_ACCELERATION,
        max_acceleration=MIN_VEHICLE_ACCELERATION,
        max_lateral_acceleration=MIN_VEHICLE_ACCELERATION,
        max_curvature=MIN_VEHICLE_CURVATURE,
    )
    demo["obstacles"] = _circle(MIN_OBSTACLE_SIZE) + _box(MIN_OBSTACLE_SIZE)
    answer = client.post("/v1/plan", json=demo)
    assert answer.status_code == 200, answer.text
    # no vehicle that cannot turn tighter than a 10 km radius drives the demo's U-turn: it brakes, and
    # says why (it would leave the lane, or turn tighter than it can)
    assert answer.json()["status"] == "fallback"
    message = answer.json()["message"]
    assert "leaves the lane" in message or "max_curvature" in message, message


#: numbers with the longest repr the limits allow (17 significant digits, sign, exponent-free)
_LONG = -1234567.8901234567


def largest_request() -> dict[str, Any]:
    """A valid planning request at every size limit of the schema, each number as long as JSON writes
    a float and each id escaped to six bytes a character: the largest body a client can need."""
    n = api.MAX_REFERENCE_POINTS
    road = [[_LONG + 0.9876543210987654 * i, 0.012345678901234567 * (-1) ** i] for i in range(n)]
    per = api.MAX_OBSTACLE_POINTS // api.MAX_OBSTACLES
    states = [
        {"t": -123456.78901234567 + k, "x": _LONG, "y": _LONG, "heading": -123.45678901234568}
        for k in range(per)
    ]
    obstacles = [
        {
            "id": f"{i:04d}" + "é" * (api.MAX_ID_LENGTH - 4),
            "length": 4.1234567890123457,
            "width": 1.8765432109876543,
            "prediction": states,
        }
        for i in range(api.MAX_OBSTACLES)
    ]
    width = [3.1234567890123457] * n
    wider = [13.123456789012346] * n
    goal = [
        [_LONG + 0.12345678901234567 * k, _LONG + 0.0012345678901234567 * k**2]
        for k in range(api.MAX_POLYGON_POINTS)
    ]
    return {
        "reference_line": road,
        "lane": {"left_width": width, "right_width": width},
        "road": {"left_width": wider, "right_width": wider},
        "goal": {
            "position": {"polygon": goal},
            "time": [-123456.78901234567, 123456.78901234567],
            "speed": [1.2345678901234567, 12.345678901234567],
        },
        "obstacles": obstacles,
        "ego": {
            "x": _LONG,
            "y": _LONG,
            "heading": -123.45678901234568,
            "speed": 12.345678901234567,
            "acceleration": -1.2345678901234567,
            "curvature": -0.012345678901234567,
        },
        "vehicle": {
            "length": 4.1234567890123457,
            "width": 1.8765432109876543,
            "max_speed": 12.345678901234567,
            "max_acceleration": 1.2345678901234567,
            "max_deceleration": 1.2345678901234567,
            "max_lateral_acceleration": 1.2345678901234567,
            "max_curvature": 0.12345678901234567,
        },
        "options": {
            "horizon_time": 12.345678901234567,
            "dt": 0.12345678901234567,
            "target_speed": 12.345678901234567,
            "speed_limit": 123.45678901234568,
            "num_candidates": api.MAX_TOTAL_CANDIDATE_POINTS // api.MAX_POINTS_PER_CANDIDATE,
            "num_points": api.MAX_POINTS_PER_CANDIDATE,
            "generator": "transf_kappa",
            "seed": api.MAX_SEED,
            "return_candidates": False,
            "time_budget_ms": 12345.678901234567,
        },
    }


def test_the_largest_valid_request_fits_the_body_limit() -> None:
    from app.models.planning import PlanningRequest

    data = largest_request()
    body = json.dumps(data).encode()  # ", " and ": " separators, ASCII escapes: no smaller than a client's
    assert len(body) <= api.MAX_BODY_BYTES == Settings().max_body_bytes, len(body)
    request = PlanningRequest.model_validate(json.loads(body))
    assert (
        len(request.obstacles) == api.MAX_OBSTACLES
        and len(request.reference_line) == api.MAX_REFERENCE_POINTS
        and request.road is not None
        and request.goal is not None
    )


def test_one_predicted_state_more_than_the_limit_is_refused(client: TestClient, demo: dict[str, Any]) -> None:
    per = api.MAX_OBSTACLE_POINTS // api.MAX_OBSTACLES
    demo["obstacles"] = [
        {
            "id": f"o{i}",
            "length": 1.0,
            "width": 1.0,
            "prediction": [
                {"t": float(k), "x": 0.0, "y": 30.0, "heading": 0.0} for k in range(per + (i == 0))
            ],
        }
        for i in range(api.MAX_OBSTACLES)
    ]
    r = client.post("/v1/plan", json=demo)
    assert r.status_code == 422 and r.json()["error"]["details"][0]["field"] == "obstacles"
    assert f"at most {api.MAX_OBSTACLE_POINTS}" in r.json()["error"]["details"][0]["message"]
