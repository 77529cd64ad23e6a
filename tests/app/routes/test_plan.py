"""POST /v1/plan: the demo plans, candidates on request, a blocked road stops, errors keep their shape,
and every answer matches the OpenAPI document.

``candidates`` is omitted from the answer (the key is absent, never null) unless
``options.return_candidates`` is true.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app import jobs as plan_route
from app.deps import get_plan_executor
from app.executor import DeadlineExceeded, Overloaded, PlanExecutor
from app.main import app, create_app
from app.models.plan import STAGES, PlanResponse
from app.settings import Settings
from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.pipeline import plan
from planner.speed import ProfileKind
from solvers.result import SolveInfo, SolverStatus
from tests.regression.checks import plan_problems

TRAJECTORY_KEYS = {"t", "x", "y", "heading", "curvature", "v", "a", "s", "d"}
#: a car's geometry
CAR = {"wheelbase": 2.7, "rear_axle_offset": 1.0}
#: a straight road closed by a wall across it at x = 60 … 62
BLOCKED: dict[str, Any] = {
    "reference_line": [[0.0, 0.0], [200.0, 0.0]],
    "lane": {"left_width": 3.5, "right_width": 3.5},
    "obstacles": [{"id": "wall", "polygon": [[60.0, -4.0], [62.0, -4.0], [62.0, 4.0], [60.0, 4.0]]}],
    "ego": {"x": 10.0, "y": 0.0, "heading": 0.0, "speed": 8.0},
}


def _plan(client: TestClient, body: dict[str, Any]) -> dict[str, Any]:
    r = client.post("/v1/plan", json=body)
    assert r.status_code == 200, r.text
    # the answer is written without the model (app.routes.plan): it must be exactly the model's JSON
    model = PlanResponse.model_validate_json(r.content, strict=True)
    assert model.model_dump_json(exclude_none=True).encode() == r.content
    out: dict[str, Any] = r.json()
    return out


def _column(out: dict[str, Any], key: str) -> np.ndarray:
    return np.array([p[key] for p in out["trajectory"]])


def test_demo_plans_from_the_ego(client: TestClient, demo: dict[str, Any]) -> None:
    out = _plan(client, demo)
    assert out["status"] == "ok", out["message"]
    assert "candidates" not in out
    ego, options = demo["ego"], demo["options"]
    first = out["trajectory"][0]
    assert (first["x"], first["y"]) == pytest.approx((ego["x"], ego["y"]), abs=1e-6)
    assert first["heading"] == pytest.approx(ego["heading"], abs=1e-6)
    assert first["v"] == pytest.approx(ego["speed"], abs=1e-9)
    steps = round(options["horizon_time"] / options["dt"])
    t = _column(out, "t")
    assert t == pytest.approx(options["dt"] * np.arange(steps + 1), abs=1e-9)
    assert t[-1] == pytest.approx(options["horizon_time"])
    assert all(set(p) == TRAJECTORY_KEYS for p in out["trajectory"])
    assert all(math.isfinite(v) for p in out["trajectory"] for v in p.values())
    assert np.all(_column(out, "v") >= 0.0)
    assert np.all(np.diff(_column(out, "s")) >= 0.0)  # never backwards along the reference
    diag = out["diagnostics"]
    assert diag["candidates"]["generated"] == options["num_candidates"]
    assert 0 < diag["candidates"]["collision_free"] <= diag["candidates"]["generated"]
    assert diag["lateral_qp"]["status"] == "solved"
    assert SolverStatus(diag["speed"]["status"]).usable  # an `ok` plan drives a usable speed profile
    assert set(diag["timing_ms"]) == set(STAGES)
    timing = diag["timing_ms"]
    assert timing["total"] >= timing["reference"] + timing["candidates"] + timing["lateral"]


def test_candidates_only_on_request(client: TestClient, demo: dict[str, Any]) -> None:
    demo["options"].update(num_candidates=6, return_candidates=True)
    out = _plan(client, demo)
    assert len(out["candidates"]) == 6
    for candidate in out["candidates"]:
        assert set(candidate) == {"points", "repaired"}
        assert candidate["points"] and all(set(p) == set("sdxy") for p in candidate["points"])
    # the same serialisation as /v1/candidates, the same candidates (they depend on the seed only)
    alone = client.post("/v1/candidates", json=demo).json()
    assert out["candidates"] == alone["candidates"]

    demo["options"]["return_candidates"] = False
    out = _plan(client, demo)
    assert "candidates" not in out


def test_blocked_road_stops_before_the_block(client: TestClient) -> None:
    out = _plan(client, BLOCKED)
    assert out["status"] == "stopped", out["message"]
    vehicle = app.openapi()["components"]["schemas"]["Vehicle"]["properties"]
    front = _column(out, "x") + 0.5 * vehicle["length"]["default"]
    assert np.all(front < 60.0)
    v = _column(out, "v")
    assert np.all(v >= 0.0)
    assert v[-1] == pytest.approx(0.0, abs=0.05)


def _error_fields(r: Any, code: str) -> list[str]:
    """The fields an answer names, after checking it is a 422 ``code`` in the one error shape."""
    assert r.status_code == 422, r.text
    body: dict[str, Any] = r.json()
    assert set(body) == {"error"} and set(body["error"]) == {"code", "message", "details"}
    assert body["error"]["code"] == code
    assert all(set(d) == {"field", "message"} for d in body["error"]["details"])
    return [d["field"] for d in body["error"]["details"]]


def test_invalid_requests_are_422_in_the_error_shape(client: TestClient, demo: dict[str, Any]) -> None:
    r = client.post("/v1/plan", content=b"{", headers={"content-type": "application/json"})
    assert _error_fields(r, "malformed_json") == [""]

    bad = {**demo, "options": {**demo["options"], "dt": 0.0, "return_candidate": True}}
    fields = _error_fields(client.post("/v1/plan", json=bad), "invalid_request")
    assert set(fields) == {"options.dt", "options.return_candidate"}

    del demo["ego"]
    assert "ego" in _error_fields(client.post("/v1/plan", json=demo), "invalid_request")


def test_unusable_geometry_is_422(client: TestClient, demo: dict[str, Any]) -> None:
    demo["ego"]["heading"] = 3.0  # against the driving direction: a planner domain error
    assert "ego.heading" in _error_fields(client.post("/v1/plan", json=demo), "invalid_input")


def test_planning_failure_is_a_200_fallback(
    client: TestClient, demo: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A fallback answer keeps the contract even for stages that did not run (no timing, no solve)."""

    def failing(problem: Any, config: PlannerConfig = DEFAULT_CONFIG) -> Any:
        result = plan(problem, config)
        timing = {k: v for k, v in result.diagnostics.timing_ms.items() if k not in ("speed", "trajectory")}
        not_run = SolveInfo(SolverStatus.FAILED, 0, 0.0, None, "not run")
        diagnostics = dataclasses.replace(
            result.diagnostics, speed=not_run, timing_ms=timing, speed_profile=ProfileKind.BRAKING
        )
        return dataclasses.replace(
            result, status="fallback", message="speed profile failed", diagnostics=diagnostics
        )

    monkeypatch.setattr(plan_route, "plan", failing)
    out = _plan(client, demo)
    assert (out["status"], out["message"]) == ("fallback", "speed profile failed")
    speed = {"status": "failed", "iterations": 0, "solve_time_ms": 0.0, "profile": "braking"}
    assert out["diagnostics"]["speed"] == speed
    assert out["diagnostics"]["timing_ms"]["speed"] == 0.0
    assert out["trajectory"]


def test_non_finite_plan_is_a_500_not_null(
    client: TestClient, demo: dict[str, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    def broken(problem: Any, config: PlannerConfig = DEFAULT_CONFIG) -> Any:
        result = plan(problem, config)
        x = result.trajectory.x.copy()
        x[3] = np.nan
        return dataclasses.replace(result, trajectory=dataclasses.replace(result.trajectory, x=x))

    monkeypatch.setattr(plan_route, "plan", broken)
    r = client.post("/v1/plan", json=demo)
    assert r.status_code == 500
    assert r.json()["error"]["code"] == "internal_error"


def _check(value: Any, schema: dict[str, Any], components: dict[str, Any], where: str = "") -> None:
    """``value`` against the subset of JSON Schema the document uses ($ref, type, enum, required,
    properties, items, additionalProperties)."""
    if "$ref" in schema:
        schema = components[schema["$ref"].rsplit("/", 1)[1]]
    kinds = {"object": dict, "array": list, "string": str, "boolean": bool, "integer": int}
    kind = schema.get("type")
    if kind == "number":
        assert isinstance(value, int | float) and not isinstance(value, bool), where
    elif kind == "integer":
        assert isinstance(value, int) and not isinstance(value, bool), where
    elif kind is not None:
        assert isinstance(value, kinds[kind]), (where, kind, value)
    if "enum" in schema:
        assert value in schema["enum"], where
    if kind == "object":
        assert set(schema.get("required", ())) <= set(value), where
        properties = schema.get("properties", {})
        if schema.get("additionalProperties") is False:
            assert set(value) <= set(properties), where
        for key, item in value.items():
            if key in properties:
                _check(item, properties[key], components, f"{where}.{key}")
    if kind == "array":
        for i, item in enumerate(value):
            _check(item, schema["items"], components, f"{where}.{i}")


def test_answers_match_the_openapi_schema(client: TestClient, demo: dict[str, Any]) -> None:
    spec = app.openapi()
    components = spec["components"]["schemas"]
    op = spec["paths"]["/v1/plan"]["post"]
    assert (op["operationId"], op["tags"]) == ("plan_trajectory", ["planning"])
    example = op["requestBody"]["content"]["application/json"]["examples"]["demo"]["value"]
    options = {k: v for k, v in demo["options"].items() if v is not None}  # the document leaves out nulls
    assert {k: example[k] for k in ("reference_line", "obstacles", "options")} == {
        "reference_line": demo["reference_line"],
        "obstacles": demo["obstacles"],
        "options": options,
    }
    schema = op["responses"]["200"]["content"]["application/json"]["schema"]
    assert schema == {"$ref": "#/components/schemas/PlanResponse"}
    response = components["PlanResponse"]
    assert set(response["required"]) == {"status", "message", "trajectory", "diagnostics"}
    assert response["properties"]["status"]["enum"] == ["ok", "stopped", "fallback"]
    assert response["properties"]["candidates"]["type"] == "array"  # never null
    assert components["SolverStatus"]["enum"] == [s.value for s in SolverStatus]
    assert set(components["TrajectoryPoint"]["required"]) == TRAJECTORY_KEYS
    assert set(components["PlanTiming"]["required"]) == set(STAGES)

    demo["options"].update(num_candidates=3, return_candidates=True)
    for body in (demo, BLOCKED):
        _check(_plan(client, body), schema, components, "answer")


def test_the_budget_counts_from_the_arrival(demo: dict[str, Any], monkeypatch: pytest.MonkeyPatch) -> None:
    """The planner gets what remains of the request's budget (the request's own, else the server's) once
    the request has waited; a budget spent before the plan starts makes a braking fallback at once."""
    budgets: list[float] = []

    def recording(problem: Any, config: PlannerConfig = DEFAULT_CONFIG) -> Any:
        budgets.append(problem.options.time_budget_ms)
        return plan(problem, config)

    monkeypatch.setattr(plan_route, "plan", recording)
    tight = TestClient(create_app(Settings(plan_processes=0, time_budget_ms=1.0)))
    with tight:
        answer = _plan(tight, demo)  # the server's 1 ms: spent before the plan starts
        assert answer["status"] == "fallback" and "time budget of 1 ms spent" in answer["message"]
        assert answer["trajectory"][-1]["v"] == pytest.approx(0.0, abs=1e-9)
        assert budgets == [1.0]  # the smallest budget
        budgets.clear()
        demo["options"]["time_budget_ms"] = 10_000.0  # the request's own budget wins
        out = _plan(tight, demo)
        assert out["status"] == "ok"
        spent = out["diagnostics"]["request"]
        assert spent["budget_ms"] == 10_000.0 and spent["waited_ms"] > 0.0
        (given,) = budgets
        assert given == pytest.approx(10_000.0 - spent["waited_ms"], abs=0.01)
        assert spent["ran_ms"] >= out["diagnostics"]["timing_ms"]["total"]
        demo["options"]["time_budget_ms"] = 0.0
        r = tight.post("/v1/plan", json=demo)
        assert r.status_code == 422
        assert r.json()["error"]["details"][0]["field"] == "options.time_budget_ms"


class _FullExecutor(PlanExecutor):
    async def run(self, fn: Any, arg: Any, deadline: float | None = None) -> Any:
        raise Overloaded("256 plans are queued or running")


class _LateExecutor(PlanExecutor):
    async def run(self, fn: Any, arg: Any, deadline: float | None = None) -> Any:
        assert deadline is not None and arg.arrived + 9.9 < deadline <= arg.arrived + 10.0
        raise DeadlineExceeded("no plan process became free before the deadline")


def test_overload_is_a_503_to_retry(demo: dict[str, Any]) -> None:
    app = create_app(Settings(plan_processes=0))
    app.dependency_overrides[get_plan_executor] = lambda: _FullExecutor(processes=0, max_pending=1)
    r = TestClient(app).post("/v1/plan", json=demo, headers={"X-Request-ID": "busy"})
    assert r.status_code == 503 and r.headers["Retry-After"] == "1" and r.headers["X-Request-ID"] == "busy"
    assert r.json()["error"]["code"] == "overloaded" and "256 plans" in r.json()["error"]["message"]


def test_a_car_is_planned_with_its_steering_angle(client: TestClient, demo: dict[str, Any]) -> None:
    """With a wheelbase every point has its steering angle, atan(wheelbase · curvature); without, none."""
    car = {**demo, "vehicle": {**demo["vehicle"], "wheelbase": 2.7, "rear_axle_offset": 1.35}}
    out = _plan(client, car)
    assert out["status"] == "ok", out["message"]
    assert all(set(p) == TRAJECTORY_KEYS | {"steering_angle"} for p in out["trajectory"])
    np.testing.assert_allclose(
        _column(out, "steering_angle"), np.arctan(2.7 * _column(out, "curvature")), rtol=1e-12, atol=1e-15
    )
    first = out["trajectory"][0]
    assert (first["x"], first["y"]) == pytest.approx((demo["ego"]["x"], demo["ego"]["y"]), abs=1e-6)
    # the rear axle, 1.35 m behind each point along its heading (the body's yaw), moves along the yaw
    heading = _column(out, "heading")
    rear = np.column_stack((_column(out, "x"), _column(out, "y"))) - 1.35 * np.column_stack(
        (np.cos(heading), np.sin(heading))
    )
    step = np.diff(rear, axis=0)
    off = np.angle(np.exp(1j * (np.arctan2(step[:, 1], step[:, 0]) - 0.5 * (heading[1:] + heading[:-1]))))
    assert np.abs(off).max() < 0.05
    assert all(set(p) == TRAJECTORY_KEYS for p in _plan(client, demo)["trajectory"])


@pytest.mark.parametrize(
    ("vehicle", "field"),
    [
        ({"wheelbase": 2.7}, "vehicle.rear_axle_offset"),
        ({"rear_axle_offset": 1.0}, "vehicle.rear_axle_offset"),
        ({"max_steering_rate": 0.4}, "vehicle.max_steering_rate"),
        ({"wheelbase": 2.7, "rear_axle_offset": 2.5}, "vehicle.rear_axle_offset"),  # beyond length/2
        ({**CAR, "max_steering_angle": 2.0}, "vehicle.max_steering_angle"),
        ({"wheelbase": 0.0, "rear_axle_offset": 1.0}, "vehicle.wheelbase"),
    ],
)
def test_a_car_without_its_geometry_is_a_422_naming_the_field(
    client: TestClient, demo: dict[str, Any], vehicle: dict[str, float], field: str
) -> None:
    r = client.post("/v1/plan", json={**demo, "vehicle": {**demo["vehicle"], **vehicle}})
    assert r.status_code == 422, r.text
    assert field in [d["field"] for d in r.json()["error"]["details"]]


def test_a_plan_that_cannot_start_within_its_budget_is_a_503_to_retry(demo: dict[str, Any]) -> None:
    app = create_app(Settings(plan_processes=0))
    app.dependency_overrides[get_plan_executor] = lambda: _LateExecutor(processes=0, max_pending=1)
    demo["options"]["time_budget_ms"] = 10_000.0  # the wait's deadline: 10 s from the arrival
    r = TestClient(app).post("/v1/plan", json=demo)
    assert r.status_code == 503 and r.headers["Retry-After"] == "1"
    assert r.json()["error"]["code"] == "deadline_exceeded"
    assert "total;dur=" in r.headers["Server-Timing"]


#: the straight road of BLOCKED without its wall
OPEN: dict[str, Any] = {**BLOCKED, "obstacles": [], "options": {"target_speed": 8.0}}


def test_the_answer_says_what_the_trajectory_does_with_the_goal(client: TestClient) -> None:
    assert "goal" not in _plan(client, OPEN)["diagnostics"]  # no goal, no key
    stop = {"position": {"polygon": [[45, -2], [55, -2], [55, 2], [45, 2]]}, "speed": [0, 0.2]}
    out = _plan(client, {**OPEN, "goal": stop})
    goal = out["diagnostics"]["goal"]
    assert set(goal) == {"status", "t", "message"} and goal["status"] == "reached"
    first = next(p for p in out["trajectory"] if 45 <= p["x"] <= 55 and abs(p["y"]) <= 2 and p["v"] <= 0.2)
    assert goal["t"] == pytest.approx(first["t"])
    assert out["trajectory"][-1]["v"] < 0.2 and 45 <= out["trajectory"][-1]["x"] <= 55  # standing inside
    behind = {"position": {"circle": {"center": [-20, 0], "radius": 2}}}
    goal = _plan(client, {**OPEN, "goal": behind})["diagnostics"]["goal"]
    assert set(goal) == {"status", "reason", "message"}
    assert (goal["status"], goal["reason"]) == ("unreachable", "behind")
    later = _plan(client, {**OPEN, "goal": {"time": [30, 40]}})["diagnostics"]["goal"]
    assert set(later) == {"status", "message"} and later["status"] == "on_the_way"


def test_a_goal_answer_matches_the_openapi_schema(client: TestClient) -> None:
    spec = app.openapi()
    components = spec["components"]["schemas"]
    schema = spec["paths"]["/v1/plan"]["post"]["responses"]["200"]["content"]["application/json"]["schema"]
    goal = components["GoalDiagnostics"]
    assert goal["properties"]["status"]["$ref"].endswith("/GoalStatus")
    assert components["GoalStatus"]["enum"] == ["reached", "on_the_way", "unreachable"]
    assert "window_ended" in components["GoalReason"]["enum"]
    assert set(goal["required"]) == {"status", "message"}
    far = {"position": {"circle": {"center": [500, 0], "radius": 1}}}
    for body in ({"time": [0, 2], "speed": [7, 9]}, far):
        _check(_plan(client, {**OPEN, "goal": body}), schema, components, "answer")
    examples = spec["paths"]["/v1/plan"]["post"]["requestBody"]["content"]["application/json"]["examples"]
    assert any("goal" in example["value"] for example in examples.values())


def _car_behind(speed_limit: float) -> dict[str, Any]:
    """A single lane; the ego at 10 m/s (target 10); a car 12 m behind at 16 m/s that does not react."""
    x0 = 30.0 - 4.5 - 12.0
    prediction = [{"t": t, "x": x0 + 16.0 * t, "y": 0.0, "heading": 0.0} for t in np.arange(0.0, 8.01, 0.5)]
    return {
        "reference_line": [[0.0, 0.0], [300.0, 0.0]],
        "lane": {"left_width": 1.75, "right_width": 1.75},
        "obstacles": [{"id": "behind", "length": 4.5, "width": 1.8, "prediction": prediction}],
        "ego": {"x": 30.0, "y": 0.0, "heading": 0.0, "speed": 10.0},
        "options": {"target_speed": 10.0, "speed_limit": speed_limit},
    }


def test_a_car_behind_that_cannot_be_escaped_is_named_in_the_diagnostics(client: TestClient) -> None:
    named = _plan(client, _car_behind(10.0))
    assert named["status"] == "fallback"
    follower = named["diagnostics"]["follower"]
    assert (follower["obstacle_id"], follower["reason"]) == ("behind", "speed_limit") and follower["t"] > 0
    assert named["diagnostics"]["speed"]["profile"] != "braking"  # it does not brake into it
    assert plan_problems(_car_behind(10.0), named, ["fallback"]) == []
    escaped = _plan(client, _car_behind(20.0))  # a speed limit above: it speeds up ahead of it
    assert escaped["status"] == "ok" and "follower" not in escaped["diagnostics"]
    assert plan_problems(_car_behind(20.0), escaped, ["ok"]) == []


def test_the_decision_keeps_the_lane_and_says_why(client: TestClient, demo: dict[str, Any]) -> None:
    out = _plan(client, demo)
    assert out["diagnostics"]["decision"] == {
        "lane": "keep",
        "reason": {"kind": "lane_free", "message": "the lane is free"},
    }
    stopped = _plan(client, BLOCKED)["diagnostics"]["decision"]
    assert stopped["lane"] == "keep"
    reason = stopped["reason"]
    assert (reason["kind"], reason["block"], reason["obstacle_id"]) == ("no_road", "obstacle", "wall")
    assert reason["s"] > 10.0 and "obstacle wall blocks the lane" in reason["message"]


def test_a_wall_across_the_lane_but_not_the_road_is_passed_through_the_road(client: TestClient) -> None:
    body = {
        **BLOCKED,
        "lane": {"left_width": 1.75, "right_width": 1.75},
        "road": {"left_width": 5.25, "right_width": 1.75},
        "obstacles": [{"id": "wall", "polygon": [[60.0, -2.0], [62.0, -2.0], [62.0, 2.0], [60.0, 2.0]]}],
    }
    out = _plan(client, body)
    assert out["status"] == "ok", out["message"]
    decision = out["diagnostics"]["decision"]
    assert decision["lane"] == "borrow_left"
    assert decision["reason"]["kind"] == "passing" and decision["reason"]["side"] == "left"
    assert decision["reason"]["obstacle_id"] == "wall"
    assert "t" not in decision["reason"] and "oncoming_id" not in decision["reason"]
    assert max(_column(out, "d")) > 2.0


def test_a_crawling_car_in_a_wide_lane_is_passed_within_it_and_the_answer_says_so(client: TestClient) -> None:
    crawl = [{"t": t, "x": 45.0 + 0.1 * t, "y": 0.0, "heading": 0.0} for t in np.arange(0.0, 8.01, 0.5)]
    body = {
        "reference_line": [[0.0, 0.0], [300.0, 0.0]],
        "lane": {"left_width": 4.5, "right_width": 4.5},  # three lanes of one direction as one
        "obstacles": [{"id": "crawler", "length": 4.3, "width": 1.8, "prediction": crawl}],
        "ego": {"x": 20.0, "y": 0.0, "heading": 0.0, "speed": 9.0},
        "options": {"target_speed": 9.0},
    }
    out = _plan(client, body)
    assert out["status"] == "ok", out["message"]
    decision = out["diagnostics"]["decision"]
    assert decision["lane"] == "keep"
    reason = decision["reason"]
    assert (reason["kind"], reason["block"], reason["obstacle_id"], reason["side"]) == (
        "passing_in_lane",
        "slow_vehicle",
        "crawler",
        "left",
    )
    assert "within the lane on the left" in reason["message"]
    assert max(_column(out, "d")) > 0.9 + 0.9  # beside it: the two half widths apart
    assert plan_problems(body, out, ["ok"]) == []
