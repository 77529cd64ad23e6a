"""``/viewer`` in headless Chromium: what it draws is what the service answered.

The page exposes what it drew (``document.body.dataset``: ``planStatus``, ``planError``, ``view``,
``folds``, ``runCycles``, ``cycle``; the map's ``dataset``: ``candidates``, ``foldsAlg4``,
``trajectoryPoints``, ``obstacles``, ``points``, ``time``) and its SVG elements carry classes and
data attributes; the tests compare them with the service's own answers and with the planner.
"""

from __future__ import annotations

import copy
import json
import re
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest
import shapely

from planner.candidates import ego_frenet, generate_candidates
from planner.collision import prediction_at
from planner.problem import DynamicObstacle
from planner.reference import build_reference, widths_at
from planner_tools.cli import main as cli_main
from planner_tools.io import problem_from_json
from planner_tools.runfile import SCALE, decode, read_run
from planner_tools.sim import folded_candidates
from tests.browser.conftest import ARTIFACTS, DRAW_TIMEOUT_MS

pytestmark = pytest.mark.browser

REQUESTS = Path(__file__).resolve().parents[1] / "regression" / "requests"


# --------------------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------------------


def body_data(page: Any) -> dict[str, str]:
    return dict(page.evaluate("({...document.body.dataset})"))


def map_data(page: Any) -> dict[str, str]:
    return dict(page.evaluate("({...document.getElementById('map').dataset})"))


def wait_drawn(page: Any) -> dict[str, str]:
    """Wait for the page to set ``planStatus`` (it clears it when it starts loading)."""
    page.locator("body[data-plan-status]").wait_for(state="attached")
    return body_data(page)


def wait_until(page: Any, expression: str, timeout_s: float = DRAW_TIMEOUT_MS / 1000) -> Any:
    """Poll a JavaScript expression until it is truthy (the page's CSP forbids Playwright's own
    wait_for_function, which evaluates strings inside the page)."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = page.evaluate(expression)
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"still false after {timeout_s} s: {expression}")
        time.sleep(0.05)


def plan(api: httpx.Client, request: dict[str, Any]) -> dict[str, Any]:
    asked = copy.deepcopy(request)
    asked.setdefault("options", {})["return_candidates"] = True
    answer = api.post("/v1/plan", json=asked)
    assert answer.status_code == 200, answer.text
    return dict(answer.json())


def alg4_folds(request: dict[str, Any]) -> set[int]:
    """The planner's own verdict: which candidates fold back as Algorithm 4 generates them."""
    problem = problem_from_json(request)
    ref = build_reference(problem.reference_line)
    options = replace(problem.options, generator="naive")
    cands = generate_candidates(
        ref, problem.lane, problem.ego, problem.vehicle, options, start=ego_frenet(ref, problem.ego)
    )
    return set(np.flatnonzero(folded_candidates(ref, cands)).tolist())


def candidate_indices(page: Any, selector: str) -> set[int]:
    return {int(i) for i in page.eval_on_selector_all(selector, "els => els.map(e => e.dataset.index)")}


def svg_points(text: str) -> np.ndarray:
    """World points of an SVG path ``d`` or polygon ``points`` (the map draws y flipped)."""
    numbers = [float(v) for v in re.findall(r"-?\d+(?:\.\d+)?(?:e-?\d+)?", text)]
    xy = np.asarray(numbers).reshape(-1, 2)
    return xy * np.array([1.0, -1.0])


def open_editor_and_plan(page: Any, text: str) -> dict[str, str]:
    if page.locator("#editor").is_hidden():
        page.click("#toggle-editor")
    page.fill("#request-text", text)
    page.click("#plan-text")
    return wait_drawn(page)


@pytest.fixture(scope="module")
def demo(api: httpx.Client) -> dict[str, Any]:
    return dict(api.get("/v1/demo").json())


# --------------------------------------------------------------------------------------------------
# A plan drawn
# --------------------------------------------------------------------------------------------------


def test_the_demo_is_drawn_as_answered(
    page: Any, base_url: str, api: httpx.Client, demo: dict[str, Any]
) -> None:
    page.goto(f"{base_url}/viewer?demo")
    data = wait_drawn(page)
    answer = plan(api, demo)
    assert data["view"] == "plan"
    assert data["planStatus"] == answer["status"] == "ok"
    drawn = map_data(page)
    n_cands, n_points = len(answer["candidates"]), len(answer["trajectory"])
    assert int(drawn["candidates"]) == n_cands == page.locator("#map .candidate").count() == 32
    assert int(drawn["trajectoryPoints"]) == n_points
    assert page.locator("#map .trajectory-segment").count() == n_points - 1
    assert int(drawn["obstacles"]) == len(demo["obstacles"]) == page.locator("#map .obstacle").count()
    repaired = {i for i, c in enumerate(answer["candidates"]) if c["repaired"]}
    assert candidate_indices(page, "#map .candidate[data-repaired='true']") == repaired
    assert page.locator("#plan-message").inner_text() == answer["message"]
    # the trajectory drawn is the answer's: its halo runs through every point
    halo = svg_points(page.get_attribute("#map .trajectory-halo", "d"))
    expected = np.array([[p["x"], p["y"]] for p in answer["trajectory"]])
    np.testing.assert_allclose(halo, expected, atol=1e-3)
    # every key of the diagnostics is shown, nested ones too
    shown = set(page.eval_on_selector_all("#diagnostics-body tr", "rows => rows.map(r => r.dataset.key)"))
    for key, value in answer["diagnostics"].items():
        assert key in shown
        if isinstance(value, dict):
            assert set(value) <= shown
    # the candidates Algorithm 4 folds: the planner's own fold test on the naive candidates
    page.locator("body[data-folds='marked']").wait_for(state="attached")
    folds = alg4_folds(demo)
    assert folds, "the demo's naive candidates fold"
    assert candidate_indices(page, "#map .candidate[data-folds-alg4='true']") == folds
    assert int(map_data(page)["foldsAlg4"]) == len(folds) == page.locator("#map .ghost").count()
    # the four plots hold the trajectory
    for name in ("v", "a", "kappa", "d"):
        assert int(page.get_attribute(f"#plot-{name}", "data-points")) == n_points
    # three seconds in, the vehicle is in the turn (the README's screenshot: docs/viewer.png)
    page.locator("#time").fill("3")
    ego = svg_points(page.get_attribute("#map .ego", "d"))[:4]
    at_3s = next(p for p in answer["trajectory"] if p["t"] == pytest.approx(3.0))
    np.testing.assert_allclose(ego.mean(axis=0), [at_3s["x"], at_3s["y"]], atol=1e-3)
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "viewer_demo.png"))


def test_the_time_slider_moves_the_vehicle_and_the_moving_obstacles(
    page: Any, base_url: str, api: httpx.Client
) -> None:
    request = json.loads((REQUESTS / "pedestrian.json").read_text())
    page.goto(f"{base_url}/viewer")
    data = open_editor_and_plan(page, json.dumps(request))
    answer = plan(api, request)
    assert data["planStatus"] == answer["status"]
    moving = [o for o in problem_from_json(request).obstacles if isinstance(o, DynamicObstacle)]
    assert moving
    traj = answer["trajectory"]
    ts = np.array([p["t"] for p in traj])
    for t in (0.0, 1.7, 4.0):
        page.locator("#time").fill(str(t))
        assert float(map_data(page)["time"]) == pytest.approx(t)
        for ob in moving:
            box = svg_points(page.get_attribute(f"#map .obstacle[data-id='{ob.id}']", "points"))
            np.testing.assert_allclose(box.mean(axis=0), prediction_at(ob, np.array([t]))[0, :2], atol=1e-6)
        ego = svg_points(page.get_attribute("#map .ego", "d"))[:4]
        at = [np.interp(t, ts, [p[k] for p in traj]) for k in ("x", "y")]
        np.testing.assert_allclose(ego.mean(axis=0), at, atol=1e-3)
    # play runs the clock on, pause stops it
    page.locator("#time").fill("0")
    page.click("#play")
    wait_until(page, "Number(document.getElementById('map').dataset.time) > 0.3")
    page.click("#play")
    stopped = float(map_data(page)["time"])
    page.wait_for_timeout(300)
    assert float(map_data(page)["time"]) == stopped


def test_new_diagnostics_fields_and_a_road_show_without_changes(
    page: Any, base_url: str, demo: dict[str, Any]
) -> None:
    """The answer's diagnostics are drawn whatever their keys; the request's road (issue 14) is drawn
    when present (the service here may not take it yet: the page's requests are answered for the
    request without it)."""

    def without_road(route: Any) -> None:
        body = json.loads(route.request.post_data)
        body.pop("road", None)
        response = route.fetch(post_data=json.dumps(body))
        answer = response.json()
        if route.request.url.endswith("/v1/plan"):
            answer["diagnostics"]["decision"] = {"obstacle": "cone", "side": "left"}
            answer["diagnostics"]["timing_ms"]["trajectory"] = 1.25
        route.fulfill(response=response, json=answer)

    page.route(re.compile(r".*/v1/(plan|candidates)$"), without_road)
    page.goto(f"{base_url}/viewer")
    request = {**demo, "road": {"left_width": 14.0, "right_width": 7.0}}
    assert open_editor_and_plan(page, json.dumps(request))["planStatus"] == "ok"
    shown = set(page.eval_on_selector_all("#diagnostics-body tr", "rows => rows.map(r => r.dataset.key)"))
    assert {"decision", "obstacle", "side", "trajectory"} <= shown
    assert page.locator("#map .road-area").count() == 1
    assert page.locator("#map .road-edge").count() >= 2
    # the road's edges are 14 m left of and 7 m right of the reference on its straight start
    edges = [
        svg_points(d)
        for d in page.eval_on_selector_all("#map .road-edge", "e => e.map(x => x.getAttribute('d'))")
    ]
    starts = sorted(float(e[0, 1]) for e in edges)
    assert starts[0] == pytest.approx(-7.0, abs=1e-6) and starts[-1] == pytest.approx(14.0, abs=1e-6)


def test_the_road_drawn_is_the_planners(page: Any, base_url: str) -> None:
    """A coarse polyline: the page draws the planner's spline through it, not the polyline, and the
    lane edges at the widths given per point, interpolated along s as the planner does."""
    points = [[0.0, 0.0], [20.0, 0.0], [35.0, 8.0], [45.0, 22.0], [50.0, 40.0]]
    left = [3.0, 3.5, 4.0, 3.0, 2.5]
    request = {
        "reference_line": points,
        "lane": {"left_width": left, "right_width": 2.0},
        "ego": {"x": 2.0, "y": 0.0, "heading": 0.0, "speed": 3.0},
    }
    page.goto(f"{base_url}/viewer")
    open_editor_and_plan(page, json.dumps(request))
    ref = build_reference(points)
    drawn = shapely.LineString(svg_points(page.get_attribute("#map .reference", "d")))
    assert float(shapely.distance(shapely.points(ref.points), drawn).max()) < 0.01
    assert drawn.length == pytest.approx(ref.length, rel=1e-3)
    edges = shapely.MultiLineString(
        [
            svg_points(d)
            for d in page.eval_on_selector_all("#map .lane-edge", "e => e.map(x => x.getAttribute('d'))")
        ]
    )
    normal = np.column_stack((-np.sin(ref.heading), np.cos(ref.heading)))
    width = widths_at(np.array(left), ref, ref.s, field_name="left")
    for offset in (ref.points + width[:, None] * normal, ref.points - 2.0 * normal):
        assert float(shapely.distance(shapely.points(offset), edges).max()) < 0.02


# --------------------------------------------------------------------------------------------------
# Errors are shown
# --------------------------------------------------------------------------------------------------

HOSTILE = {
    "one_point": {"reference_line": [[0, 0]], "lane": {"left_width": 2, "right_width": 2},
                  "ego": {"x": 0, "y": 0, "heading": 0}},
    "bad_radius": {"reference_line": [[0, 0], [50, 0]], "lane": {"left_width": 2, "right_width": 2},
                   "ego": {"x": 1, "y": 0, "heading": 0, "speed": "fast"},
                   "obstacles": [{"id": "a", "circle": {"center": [10, 0], "radius": -1}}]},
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_a_hostile_request_shows_the_services_error(
    page: Any, base_url: str, api: httpx.Client, name: str
) -> None:
    expected = api.post("/v1/plan", json=HOSTILE[name])
    assert expected.status_code == 422
    error = expected.json()["error"]
    page.goto(f"{base_url}/viewer")
    data = open_editor_and_plan(page, json.dumps(HOSTILE[name]))
    assert data["planStatus"] == "error" and data["planError"] == error["code"]
    box = page.locator("#error")
    assert box.is_visible()
    assert error["message"] in box.inner_text()
    shown = page.eval_on_selector_all(
        "#error .error-detail", "items => items.map(i => [i.dataset.field, i.textContent])"
    )
    assert len(shown) == len(error["details"]) > 0
    for (field, text), detail in zip(shown, error["details"], strict=True):
        assert field == detail["field"] and detail["message"] in text


def test_bad_json_and_network_errors_are_shown(page: Any, base_url: str, demo: dict[str, Any]) -> None:
    page.goto(f"{base_url}/viewer")
    data = open_editor_and_plan(page, '{"reference_line": [[0, 0], [1, 0]],')
    assert data["planError"] == "invalid_json"
    assert "not JSON" in page.locator("#error").inner_text()
    page.route(re.compile(r".*/v1/plan$"), lambda route: route.abort("connectionrefused"))
    data = open_editor_and_plan(page, json.dumps(demo))
    assert data["planStatus"] == "error" and data["planError"] == "network_error"
    assert "Could not reach" in page.locator("#error").inner_text()
    # the request's road and obstacles are still drawn
    assert int(map_data(page)["obstacles"]) == len(demo["obstacles"])


def test_an_api_key_is_sent_and_a_refusal_says_so(page: Any, base_url: str) -> None:
    seen: list[str | None] = []

    def refuse(route: Any) -> None:
        seen.append(route.request.headers.get("authorization"))
        route.fulfill(
            status=401,
            json={
                "error": {"code": "unauthorized", "message": "A valid API key is required.", "details": []}
            },
        )

    page.route(re.compile(r".*/v1/plan$"), refuse)
    page.goto(f"{base_url}/viewer?demo")
    assert wait_drawn(page)["planError"] == "unauthorized"
    assert "API key" in page.locator("#error").inner_text()
    page.fill("#api-key", "s3cret")
    page.click("#load-demo")
    wait_drawn(page)
    assert seen == [None, "Bearer s3cret"]


# --------------------------------------------------------------------------------------------------
# Every request example of the API documentation
# --------------------------------------------------------------------------------------------------


def _examples(api: httpx.Client) -> list[tuple[str, str, dict[str, Any]]]:
    spec = api.get("/openapi.json").json()
    out = []
    for path, ops in spec["paths"].items():
        for method, op in ops.items():
            content = op.get("requestBody", {}).get("content", {}).get("application/json", {})
            for name, example in content.get("examples", {}).items():
                out.append((f"{method.upper()} {path}", name, example["value"]))
    return out


def test_every_request_example_of_the_docs_works(page: Any, base_url: str, api: httpx.Client) -> None:
    examples = _examples(api)
    assert {op for op, _, _ in examples} >= {"POST /v1/plan", "POST /v1/candidates", "POST /v1/frenet"}
    page.goto(f"{base_url}/viewer")
    page.locator("body[data-examples]").wait_for(state="attached")
    assert int(page.get_attribute("#examples", "data-count")) == len(examples)
    for i, (operation, name, value) in enumerate(examples):
        page.select_option("#examples", str(i))
        data = wait_drawn(page)
        label = f"{operation} {name}"
        assert data["planStatus"] != "error", f"{label}: {page.locator('#error').inner_text()}"
        drawn = map_data(page)
        if "lane" in value:  # a planning request, drawn as a plan
            assert data["view"] == "plan", label
            assert data["planStatus"] == plan(api, value)["status"], label
            assert int(drawn["trajectoryPoints"]) > 0, label
        else:  # a coordinate conversion
            assert data["view"] in ("frenet", "cartesian"), label
            assert int(drawn["points"]) == len(value.get("points") or value.get("frenet")), label
        page.screenshot(path=str(ARTIFACTS / f"example_{i}.png"))


# --------------------------------------------------------------------------------------------------
# A simulator run played back
# --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def run_file(tmp_path_factory: pytest.TempPathFactory, api: httpx.Client) -> Path:
    out = tmp_path_factory.mktemp("run")
    (out / "demo.json").write_text(api.get("/v1/demo").text)
    args = ["simulate", str(out / "demo.json"), "--out", str(out), "--duration", "2.5"]
    assert cli_main([*args, "--no-gif", "--frame-every", "100", "--quiet"]) == 0
    return out / "run.json.gz"


def test_a_simulator_run_plays_back_cycle_by_cycle(page: Any, base_url: str, run_file: Path) -> None:
    run = read_run(run_file)
    cycles = run["cycles"]
    page.goto(f"{base_url}/viewer")
    page.set_input_files("#file-input", str(run_file))
    page.locator("body[data-run-cycles]").wait_for(state="attached")
    assert body_data(page)["view"] == "run"
    assert int(body_data(page)["runCycles"]) == len(cycles) == 25
    driven_t = decode(run["driven"]["t"], SCALE["t"])
    driven_xy = decode(run["driven"]["xy"], SCALE["xy"], pairs=True)
    for k in (0, 7, len(cycles) - 1):
        cycle = cycles[k]
        at = round(cycle["t"] + 0.05, 3)  # half a cycle in, on the slider's step
        page.locator("#time").fill(str(at))
        data = body_data(page)
        assert int(data["cycle"]) == k and data["planStatus"] == cycle["status"]
        drawn = map_data(page)
        assert int(drawn["candidates"]) == len(cycle["candidates"]) == page.locator("#map .candidate").count()
        assert candidate_indices(page, "#map .candidate[data-folds-alg4='true']") == set(cycle["alg4_folds"])
        assert int(drawn["trajectoryPoints"]) == len(cycle["trajectory"]["v"])
        # the vehicle is where the run drove it at that time
        i = int(np.searchsorted(driven_t, at, side="right")) - 1
        ego = svg_points(page.get_attribute("#map .ego", "d"))[:4]
        np.testing.assert_allclose(ego.mean(axis=0), driven_xy[i], atol=0.02)
    page.locator("#time").fill(str(cycles[3]["t"]))
    page.click("#next-cycle")
    assert int(body_data(page)["cycle"]) == 4
    page.click("#prev-cycle")
    assert int(body_data(page)["cycle"]) == 3
    page.select_option("#speed", "4")
    page.click("#play")
    wait_until(page, "Number(document.body.dataset.cycle) >= 8")
    page.click("#play")


def test_a_run_loads_from_a_url(page: Any, base_url: str, run_file: Path) -> None:
    served = run_file.read_bytes()
    page.route(
        re.compile(r".*/runs/demo\.json\.gz$"),
        lambda route: route.fulfill(body=served, content_type="application/gzip"),
    )
    page.goto(f"{base_url}/viewer?run=runs/demo.json.gz")
    page.locator("body[data-run-cycles]").wait_for(state="attached")
    assert int(body_data(page)["runCycles"]) == len(read_run(run_file)["cycles"])
    assert body_data(page)["planStatus"] == "ok"


def test_a_request_loads_from_a_url(page: Any, base_url: str, api: httpx.Client) -> None:
    request = json.loads((REQUESTS / "s_curve_parked_cars.json").read_text())
    page.route(re.compile(r".*/requests/cars\.json$"), lambda route: route.fulfill(json=request))
    page.goto(f"{base_url}/viewer?request=requests/cars.json")
    data = wait_drawn(page)
    answer = plan(api, request)
    assert data["planStatus"] == answer["status"]
    assert int(map_data(page)["obstacles"]) == len(request["obstacles"])
    assert int(map_data(page)["trajectoryPoints"]) == len(answer["trajectory"])


def test_the_goal_region_of_a_request_is_drawn(
    page: Any, base_url: str, api: httpx.Client, demo: dict[str, Any]
) -> None:
    page.goto(f"{base_url}/viewer")
    circle = {**demo, "goal": {"position": {"circle": {"center": [30.0, 2.0], "radius": 3.0}}}}
    assert open_editor_and_plan(page, json.dumps(circle))["planStatus"] == plan(api, circle)["status"]
    attributes = "els => els.map(e => ['cx', 'cy', 'r'].map(a => +e.getAttribute(a)))"
    drawn = page.eval_on_selector_all("circle.goal", attributes)
    assert drawn == [[30.0, -2.0, 3.0]]  # the map draws y flipped
    square = [[20.0, -1.0], [24.0, -1.0], [24.0, 3.0], [20.0, 3.0]]
    open_editor_and_plan(page, json.dumps({**demo, "goal": {"position": {"polygon": square}}}))
    outline = page.eval_on_selector_all("path.goal", "els => els.map(e => e.getAttribute('d'))")
    assert len(outline) == 1 and np.allclose(svg_points(outline[0])[:4], square)
    assert page.locator("circle.goal").count() == 0
    open_editor_and_plan(page, json.dumps(demo))  # no goal: none drawn
    assert page.locator(".goal").count() == 0
