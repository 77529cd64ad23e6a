"""Regression suite: golden planning requests against a service, answers held to property checks.

Every ``requests/NAME.json`` is posted to ``/v1/plan``; its sidecar ``NAME.expect.json`` lists the
acceptable statuses, and the answer must pass :func:`tests.regression.checks.plan_problems` (shape,
time grid, start, and the trajectory checks of the status). Run against the app in-process
(``pytest tests/regression``) or any server (``pytest tests/regression --base-url http://host:port``).
The requests are rebuilt by ``python tests/regression/make_requests.py``.
"""

from __future__ import annotations

import json
from typing import Any

import httpx
import pytest

from tests.regression.checks import STATUSES, error_problems, goal_problems, plan_problems
from tests.regression.make_requests import REQUESTS, build_all, stale


def _names() -> list[str]:
    return sorted(p.name.removesuffix(".json") for p in REQUESTS.glob("*.json") if ".expect." not in p.name)


def _load(name: str) -> tuple[dict[str, Any], dict[str, Any]]:
    request = json.loads((REQUESTS / f"{name}.json").read_text())
    expect = json.loads((REQUESTS / f"{name}.expect.json").read_text())
    return request, expect


def _post_plan(service: httpx.Client, request: dict[str, Any]) -> Any:
    response = service.post("/v1/plan", json=request)
    assert response.status_code == 200, f"{response.status_code}: {response.text[:500]}"
    assert response.headers["content-type"].startswith("application/json")
    return response.json()


def test_the_golden_set_is_there() -> None:
    names = _names()
    assert len(names) >= 10
    for name in names:
        _, expect = _load(name)
        assert expect["statuses"] and set(expect["statuses"]) <= set(STATUSES), name


@pytest.mark.parametrize("name", _names())
def test_golden_request(service: httpx.Client, name: str) -> None:
    request, expect = _load(name)
    answer = _post_plan(service, request)
    problems = plan_problems(request, answer, expect["statuses"])
    if not problems and ("goal" in request or "goal" in expect):
        problems = goal_problems(request, answer, expect.get("goal", []))
    status = answer.get("status") if isinstance(answer, dict) else None
    message = answer.get("message") if isinstance(answer, dict) else None
    assert problems == [], f"{name}: status {status!r} ({message}):\n  " + "\n  ".join(problems)


def test_healthz(service: httpx.Client) -> None:
    response = service.get("/healthz")
    assert response.status_code == 200
    assert response.json() == {"status": "ok"}


def test_served_demo_plans(service: httpx.Client) -> None:
    response = service.get("/v1/demo")
    assert response.status_code == 200
    demo = response.json()
    answer = _post_plan(service, demo)
    problems = plan_problems(demo, answer, ["ok"])
    assert problems == [], "\n".join(problems)


def test_a_bad_request_is_a_4xx_in_the_error_shape(service: httpx.Client) -> None:
    request, _ = _load("demo")
    request["reference_line"] = request["reference_line"][:1]
    request["options"]["dt"] = "0.1"
    response = service.post("/v1/plan", json=request)
    assert 400 <= response.status_code < 500, response.text[:500]
    answer = response.json()
    assert error_problems(answer) == []
    fields = {d["field"] for d in answer["error"]["details"]}
    assert {"reference_line", "options.dt"} <= fields, fields


def test_the_golden_requests_are_what_make_requests_builds() -> None:
    differ = stale(build_all())
    assert differ == [], f"run `python tests/regression/make_requests.py`; these differ: {differ}"


# --------------------------------------------------------------------------------------------------
# The checks themselves: a good answer passes, each kind of breakage is caught
# --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def demo_answer(service: httpx.Client) -> tuple[dict[str, Any], dict[str, Any]]:
    request, _ = _load("demo")
    return request, _post_plan(service, request)


def _column(answer: dict[str, Any], field: str, f: Any) -> None:
    for i, p in enumerate(answer["trajectory"]):
        p[field] = f(i, p[field])


def _box(x: float, y: float, half: float) -> list[list[float]]:
    return [[x - half, y - half], [x + half, y - half], [x + half, y + half], [x - half, y + half]]


def _broken(request: dict[str, Any], answer: dict[str, Any]) -> list[tuple[str, Any, Any, str]]:
    """(name, request, answer, text expected in a problem) for each breakage of a good answer."""
    mid = answer["trajectory"][40]
    cases: list[tuple[str, Any, Any, str]] = []

    def case(name: str, expected: str, *, req: Any = None, ans: Any = None) -> None:
        r, a = json.loads(json.dumps(request)), json.loads(json.dumps(answer))
        if req:
            req(r)
        if ans:
            ans(a)
        cases.append((name, r, a, expected))

    case("status", "expected one of", ans=lambda a: a.update(status="stopped"))
    case("extra key", "top-level keys", ans=lambda a: a.update(extra=1))
    case("missing field", "has keys", ans=lambda a: a["trajectory"][3].pop("d"))
    case("string number", "non-numbers", ans=lambda a: a["trajectory"][3].update(v="5"))
    case("no message", "no message", ans=lambda a: a.update(message=" "))
    case("t0", "t[0]", ans=lambda a: _column(a, "t", lambda i, v: v + 0.05))
    case("dt", "time step", ans=lambda a: a["trajectory"].pop(10))
    case("horizon", "ends at", ans=lambda a: a.update(trajectory=a["trajectory"][:-5]))
    case("start", "from the ego", req=lambda r: r["ego"].update(x=r["ego"]["x"] - 0.5))
    case("v·dt", "mean speed × dt", ans=lambda a: _column(a, "v", lambda i, v: 1.3 * v))
    case("curvature", "above max_curvature", ans=lambda a: _column(a, "curvature", lambda i, v: 0.3))
    case("lateral", "lateral acceleration", req=lambda r: r["vehicle"].update(max_lateral_acceleration=0.5))
    case("acceleration", "acceleration outside", req=lambda r: r["vehicle"].update(max_acceleration=0.01))
    case("heading", "off the direction of motion", ans=lambda a: _column(a, "heading", lambda i, v: v + 0.2))
    case("s", "s does not increase", ans=lambda a: _column(a, "s", lambda i, v: 100.0 - i))
    case("d", "reported d", ans=lambda a: _column(a, "d", lambda i, v: v + 0.5))
    case("lane", "leaves the lane", req=lambda r: r["lane"].update(left_width=0.5, right_width=0.5))
    case(
        "circle",
        "hits obstacle rock",
        req=lambda r: r["obstacles"].append(
            {"id": "rock", "circle": {"center": [mid["x"], mid["y"]], "radius": 0.3}}
        ),
    )
    case(
        "polygon",
        "hits obstacle crate",
        req=lambda r: r["obstacles"].append({"id": "crate", "polygon": _box(mid["x"], mid["y"], 0.3)}),
    )
    walker = [{"t": mid["t"] + k, "x": mid["x"], "y": mid["y"], "heading": 0.0} for k in (-0.2, 0.2)]
    case(
        "moving",
        "hits moving obstacle walker",
        req=lambda r: r["obstacles"].append(
            {"id": "walker", "length": 0.5, "width": 0.5, "prediction": walker}
        ),
    )

    def speeding_fallback(a: dict[str, Any]) -> None:
        a["status"] = "fallback"
        a["diagnostics"]["speed"]["profile"] = "braking"
        _column(a, "v", lambda i, v: v + 0.01 * i)

    case("fallback speeds up", "speeds up", ans=speeding_fallback)
    return cases


def test_the_checks_pass_a_good_answer(demo_answer: tuple[dict[str, Any], dict[str, Any]]) -> None:
    request, answer = demo_answer
    assert answer["status"] == "ok"
    assert plan_problems(request, answer, ["ok"]) == []


def test_the_checks_catch_each_breakage(demo_answer: tuple[dict[str, Any], dict[str, Any]]) -> None:
    request, answer = demo_answer
    missed = []
    for name, req, ans, expected in _broken(request, answer):
        problems = plan_problems(req, ans, ["ok", "fallback"] if name != "status" else ["ok"])
        if not any(expected in p for p in problems):
            missed.append(f"{name}: expected {expected!r} in {problems}")
    assert missed == [], "\n".join(missed)


def test_the_goal_checks_catch_a_wrong_claim(service: httpx.Client) -> None:
    request, expect = _load("goal_window")
    answer = _post_plan(service, request)
    assert goal_problems(request, answer, expect["goal"]) == []
    report = answer["diagnostics"]["goal"]
    assert report["status"] == "reached"

    def claims(**change: Any) -> list[str]:
        wrong = json.loads(json.dumps(answer))
        wrong["diagnostics"]["goal"] = {k: v for k, v in {**report, **change}.items() if v is not None}
        return goal_problems(request, wrong, ["reached", "on_the_way", "unreachable"])

    assert any("already" in p for p in claims(t=report["t"] + 0.2))  # met before the t claimed
    assert any("does not meet it" in p for p in claims(t=report["t"] - 0.1))  # not met then
    assert any("meets it" in p for p in claims(status="on_the_way", t=None))  # met, but not said
    assert any("expected one of" in p for p in goal_problems(request, answer, ["unreachable"]))
    assert any("no diagnostics.goal" in p for p in goal_problems(request, {"diagnostics": {}}, ["reached"]))
    plain = {k: v for k, v in request.items() if k != "goal"}
    assert goal_problems(plain, answer, []) == ["diagnostics.goal without a goal in the request"]
