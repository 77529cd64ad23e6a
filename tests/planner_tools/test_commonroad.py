"""CommonRoad conversion: the pure geometry (no commonroad-io), the JSON inputs, and — with the
``commonroad`` extra installed — whole XML scenarios and the ``kappa-planner commonroad`` command."""

from __future__ import annotations

import csv
import importlib.util
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from app.models.planning import PlanningRequest
from planner.pipeline import plan
from planner.problem import Vehicle
from planner.reference import build_reference
from planner_tools import commonroad as cr
from planner_tools.cli import main as cli_main
from planner_tools.evaluate import Settings, prepare
from planner_tools.io import problem_from_json

DATA = Path(__file__).resolve().parents[1] / "data" / "commonroad"


def _arc(radius: float, start: float, stop: float, n: int = 60) -> np.ndarray:
    a = np.linspace(start, stop, n)
    return np.column_stack((radius * np.cos(a), radius * np.sin(a)))


# --------------------------------------------------------------------------------------------------
# Lane widths from edge polylines
# --------------------------------------------------------------------------------------------------


def test_widths_of_a_straight_lane_hold_up_to_both_ends() -> None:
    left = np.array([[0.0, 2.0], [50.0, 2.0]])
    right = np.array([[0.0, -1.5], [50.0, -1.5]])
    # the first and last points sit on the lane's end caps: the reference converter gave them 0
    pts = np.column_stack((np.linspace(0.0, 50.0, 51), np.full(51, 0.25)))
    wl, wr = cr.boundary_widths(pts, left, right)
    np.testing.assert_allclose(wl, 1.75, atol=1e-9)
    np.testing.assert_allclose(wr, 1.75, atol=1e-9)


def test_widths_follow_a_curved_lane_and_are_zero_beyond_an_edge() -> None:
    # a left turn of radius 10 m: left edge (inner) at 8 m, right edge (outer) at 13 m
    left = _arc(8.0, -0.5 * math.pi, 0.0)
    right = _arc(13.0, -0.5 * math.pi, 0.0)
    centre = _arc(10.0, -0.45 * math.pi, -0.05 * math.pi, 20)
    wl, wr = cr.boundary_widths(centre, left, right)
    np.testing.assert_allclose(wl, 2.0, atol=0.02)
    np.testing.assert_allclose(wr, 3.0, atol=0.02)
    beyond_left = _arc(7.0, -0.3 * math.pi, -0.2 * math.pi, 3)
    wl, wr = cr.boundary_widths(beyond_left, left, right)
    np.testing.assert_array_equal(wl, 0.0)
    np.testing.assert_allclose(wr, 6.0, atol=0.02)
    beyond_right = _arc(14.0, -0.3 * math.pi, -0.2 * math.pi, 3)
    wl, wr = cr.boundary_widths(beyond_right, left, right)
    np.testing.assert_allclose(wl, 6.0, atol=0.02)
    np.testing.assert_array_equal(wr, 0.0)


def test_along_the_normal_a_straight_or_round_lane_has_its_widths() -> None:
    """Where the edges run parallel to the line, the width along the normal is the nearest distance."""
    pts = np.column_stack((np.linspace(0.0, 50.0, 51), np.full(51, 0.25)))
    left, right = [[0.0, 2.0], [50.0, 2.0]], [[0.0, -1.5], [50.0, -1.5]]
    straight = cr.boundary_widths(pts, left, right, normals=cr.left_normals(pts))
    np.testing.assert_allclose(straight, [np.full(51, 1.75), np.full(51, 1.75)], atol=1e-9)
    centre = _arc(10.0, -0.45 * math.pi, -0.05 * math.pi, 20)
    inner, outer = _arc(8.0, -0.5 * math.pi, 0.0), _arc(13.0, -0.5 * math.pi, 0.0)
    wl, wr = cr.boundary_widths(centre, inner, outer, normals=cr.left_normals(centre))
    np.testing.assert_allclose(wl, 2.0, atol=0.02)
    np.testing.assert_allclose(wr, 3.0, atol=0.02)


def test_inside_a_sharp_corner_the_width_reaches_the_edge_along_the_normal_not_past_its_vertex() -> None:
    """A right angle (right turn) whose inside edge has a vertex: the nearest distance from the points
    near the apex is the vertex, well short of the edge along the normal. Along the normal the lane is
    wider there, and the widths interpolated between two points never reach beyond the vertex."""
    # centre line: east along y = 0, a quarter circle of radius 3 m, south along x = 3
    east = np.column_stack((np.linspace(-20.0, 0.0, 21), np.zeros(21)))
    turn = _arc(3.0, 0.5 * math.pi, 0.0, 12)[1:-1] + np.array([0.0, -3.0])
    south = np.column_stack((np.full(21, 3.0), np.linspace(-3.0, -23.0, 21)))
    pts = np.vstack((east, turn, south))
    inner = np.array([[-20.0, -1.5], [1.5, -1.5], [1.5, -23.0]])  # the vertex at (1.5, -1.5)
    outer = np.array([[-20.0, 1.5], [4.5, 1.5], [4.5, -23.0]])
    nearest_l, nearest_r = cr.boundary_widths(pts, outer, inner)
    wl, wr = cr.boundary_widths(pts, outer, inner, normals=cr.left_normals(pts))
    assert np.all(wr >= nearest_r - 1e-12) and np.all(wl >= nearest_l - 1e-12)
    assert float(np.max(wr - nearest_r)) > 0.1  # wider on the inside before and after the apex
    # the edge the planner interpolates between two points stays on the lane's side of the vertex
    vertex = np.array([1.5, -1.5])
    for i in range(pts.shape[0] - 1):
        chord = pts[i + 1] - pts[i]
        along = float(np.dot(vertex - pts[i], chord) / np.dot(chord, chord))
        if 0.0 < along < 1.0:
            offset = float(np.dot(vertex - pts[i], -cr.left_normals(pts)[i]))
            interpolated = (1.0 - along) * wr[i] + along * wr[i + 1]
            assert interpolated <= max(offset, (1.0 - along) * nearest_r[i] + along * nearest_r[i + 1]) + 1e-9


def test_a_spike_of_the_map_edge_is_dropped() -> None:
    edge = np.array([[0.0, -1.75], [10.0, -1.75], [10.2, -0.2], [10.4, -1.75], [20.0, -1.75]])
    cleaned = cr.clean_edge(edge)
    np.testing.assert_array_equal(cleaned[:, 1], -1.75)
    wl, wr = cr.boundary_widths([[10.2, 0.0]], [[0.0, 1.75], [20.0, 1.75]], edge)
    assert wr[0] == pytest.approx(1.75)
    assert wl[0] == pytest.approx(1.75)


def test_join_edges_joins_only_continuing_neighbours() -> None:
    a = np.array([[0.0, 1.0], [5.0, 1.0]])
    b = np.array([[5.0, 1.0], [5.5, 1.0]])  # a short lanelet
    c = np.array([[5.5, 1.0], [12.0, 1.0]])
    d = np.array([[13.0, 4.0], [20.0, 4.0]])  # a lane added: the edge jumps
    np.testing.assert_array_equal(
        cr.join_edges([a, b, c, d], 1), [[0.0, 1.0], [5.0, 1.0], [5.5, 1.0], [12.0, 1.0]]
    )
    np.testing.assert_array_equal(cr.join_edges([a, b, c, d], 3), [[13.0, 4.0], [20.0, 4.0]])


def test_points_of_a_hairpin_are_given_to_their_own_leg() -> None:
    # out along y = 0, back along y = 3 (a U-turn of radius 1.5 m): both legs are 3 m apart
    out = np.column_stack((np.linspace(0.0, 30.0, 31), np.zeros(31)))
    turn = 30.0 + _arc(1.5, -0.5 * math.pi, 0.5 * math.pi, 20) + [0.0, 1.5]
    back = np.column_stack((np.linspace(30.0, 0.0, 31), np.full(31, 3.0)))
    line = np.vstack((out, turn[1:], back[1:]))
    owner = cr.assign_pieces(line, [out, turn, back], window=5.0)
    assert np.all(owner[:25] == 0)
    assert np.all(owner[-25:] == 2)
    assert set(np.unique(owner)) == {0, 1, 2}


# --------------------------------------------------------------------------------------------------
# Resampling, smoothing, predictions, target speed
# --------------------------------------------------------------------------------------------------


def test_resample_is_uniform_and_keeps_the_ends() -> None:
    pts, s = cr.resample([[0.0, 0.0], [3.0, 0.0], [3.0, 4.5]], 1.0)
    assert pts[0].tolist() == [0.0, 0.0] and pts[-1].tolist() == [3.0, 4.5]
    np.testing.assert_allclose(np.diff(s), 7.5 / 8)


def test_smooth_keeps_a_straight_line_and_rounds_a_corner() -> None:
    line = np.column_stack((np.arange(30.0), 0.5 * np.arange(30.0)))
    np.testing.assert_allclose(cr.smooth(line, 1.5, 1.0), line, atol=1e-9)
    corner = np.vstack((np.column_stack((np.arange(15.0), np.zeros(15))), [[14.0, k] for k in range(1, 15)]))
    smoothed = cr.smooth(corner, 1.5, 1.0)
    assert smoothed[0].tolist() == corner[0].tolist() and smoothed[-1].tolist() == corner[-1].tolist()
    assert 0.1 < np.hypot(*(smoothed[14] - corner[14])) < 1.5  # the corner is cut, a little


def test_prediction_rows_shift_time_and_move_to_the_box_centre() -> None:
    steps = [3, 4, 5, 6]
    xy = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]]
    heading = [0.5 * math.pi, 0.5 * math.pi, -1.5 * math.pi + 0.1, 0.5 * math.pi + 0.2]
    rows = cr.prediction_rows(steps, xy, heading, dt=0.1, t0_step=4, offset=(-1.0, 0.0))
    np.testing.assert_allclose(rows[:, 0], [0.0, 0.1, 0.2])  # the state before the ego's time dropped
    # a rear-axle origin 1 m behind the centre: the centre is 1 m "behind" along heading π/2 … i.e. at y = −1
    np.testing.assert_allclose(rows[0, 1:3], [1.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(rows[:, 3], [0.5 * math.pi, 0.5 * math.pi + 0.1, 0.5 * math.pi + 0.2])


def test_constant_velocity_rows() -> None:
    rows = cr.constant_velocity_rows(1.0, 2.0, [5.0, 5.0], 0.0, 10.0, 0.25)
    np.testing.assert_allclose(rows[:, 0], [1.0, 1.25, 1.5, 1.75, 2.0])
    np.testing.assert_allclose(rows[:, 1], [5.0, 7.5, 10.0, 12.5, 15.0])
    np.testing.assert_allclose(rows[:, 2], 5.0)


def _moving(oid: str, end: float, speed: float = 10.0, step: float = 0.1) -> dict[str, object]:
    """A recorded vehicle driving along +x at ``speed`` [m/s] from x = 0 until ``end`` [s]."""
    t = np.arange(0.0, end + 1e-9, step)
    rows = [{"t": round(float(ti), 4), "x": speed * float(ti), "y": 0.0, "heading": 0.0} for ti in t]
    return {"id": oid, "length": 4.0, "width": 1.8, "prediction": rows}


def test_a_vehicle_whose_recording_ends_early_drives_on_and_leaves_the_scene() -> None:
    """One that left the recorded area (its recording ends before the latest moving one's) drives on at its
    last velocity for the horizon and leaves the scene when its recording ends; a standing one, one
    recorded to the end and a static outline are as they were, and the input is not modified."""
    left = _moving("left", 2.0, speed=15.0)
    last = _moving("last", 8.0)
    parked = {**_moving("parked", 1.0, speed=0.0), "id": "parked"}
    cone = {"id": "cone", "circle": {"center": [5.0, 5.0], "radius": 0.5}}
    obstacles = [left, last, parked, cone]
    out, leaves = cr.continued_predictions(obstacles, 8.0)
    assert leaves == {"left": pytest.approx(2.0)}
    assert out[1] is last and out[2] is parked and out[3] is cone
    pred = out[0]["prediction"]
    assert pred[:-1] == left["prediction"] and len(left["prediction"]) == 21  # the input as it was
    assert pred[-1]["t"] == pytest.approx(10.0)
    assert pred[-1]["x"] == pytest.approx(30.0 + 15.0 * 8.0) and pred[-1]["y"] == 0.0
    # the request stays valid, and the planner sees it moving on, not stopped at x = 30 m
    problem = problem_from_json({
        "reference_line": [[0.0, 0.0], [200.0, 0.0]], "lane": {"left_width": 2.0, "right_width": 2.0},
        "obstacles": out, "ego": {"x": -40.0, "y": 0.0, "heading": 0.0, "speed": 10.0}, "vehicle": {},
        "options": {"target_speed": 10.0},
    })  # fmt: skip
    from planner.collision import prediction_at

    x_at_4 = prediction_at(problem.obstacles[0], np.array([4.0]))[0, 0]
    assert x_at_4 == pytest.approx(60.0)


def test_no_moving_vehicle_no_change() -> None:
    obstacles = [{**_moving("parked", 3.0, speed=0.0)}]
    out, leaves = cr.continued_predictions(obstacles, 8.0)
    assert out == obstacles and leaves == {}


@pytest.mark.parametrize(
    ("ego", "goal", "expected"),
    [
        (6.37, None, 6.37),
        (2.876, None, 5.0),
        (0.0, (8.5611, 14.5611), 11.56),
        (5.635, (-2.37, 10.63), 5.63),
        (1.5, (0.0, 0.0), 5.0),
    ],
)
def test_target_speed_matches_the_shared_requests(
    ego: float, goal: tuple[float, float] | None, expected: float
) -> None:
    assert cr.target_speed(ego, goal) == expected


# --------------------------------------------------------------------------------------------------
# JSON inputs
# --------------------------------------------------------------------------------------------------


def test_a_reduced_scenario_becomes_a_valid_request_with_real_end_widths() -> None:
    reduced = {
        "name": "tiny",
        "reference_line": [[float(x), 0.0] for x in range(21)],
        "left_width": [0.0] + [1.75] * 19 + [0.0],
        "right_width": [1.75] * 21,
        "obstacles": [
            {"id": 7, "kind": "dynamic", "type": "car", "length": 4.0, "width": 1.8,
             "polygon": [[0, 0], [1, 0], [1, 1]],
             "trajectory": [{"t": 0.0, "x": 15.0, "y": 0.0, "heading": 3.1, "speed": 2.0},
                            {"t": 0.1, "x": 14.8, "y": 0.0, "heading": 3.1, "speed": 2.0}]},
            {"id": 8, "kind": "static", "type": "parkedVehicle", "length": None, "width": None,
             "polygon": [[8.0, 1.0], [10.0, 1.0], [10.0, 1.7], [8.0, 1.7]], "trajectory": None},
        ],
        "ego": {"x": 2.0, "y": 0.0, "heading": -2 * math.pi, "speed": 3.0, "time_step": 0},
        "goal": {"states": [{"velocity": [4.0, 8.0]}], "s_goal": 17.5},
    }  # fmt: skip
    conv = cr.request_from_reduced(reduced)
    req = PlanningRequest.model_validate(conv.request)
    assert req.lane.left_width[0] == 1.75 and req.lane.left_width[-1] == 1.75
    assert req.ego.heading == pytest.approx(0.0, abs=1e-12)
    assert req.options.target_speed == 6.0
    assert [o.id for o in req.obstacles] == ["7", "8"]
    assert conv.goal["s_min"] == 17.5
    # the converted request plans: the parked car narrows the short lane and the other car comes towards
    # the ego in it, so the plan stops before them
    assert plan(problem_from_json(conv.request)).status == "stopped"


def test_a_request_json_takes_its_goal_from_the_index() -> None:
    conv = cr.load(DATA / "ZAM_Over-1_1.json")
    index = {e["name"]: e for e in json.loads((DATA / "index.json").read_text())}
    assert conv.goal["s_min"] == index["ZAM_Over-1_1"]["goal"]["s_goal"]
    assert conv.request == json.loads((DATA / "ZAM_Over-1_1.json").read_text())
    assert conv.sim_goal().s_min == conv.goal["s_min"]


def test_unknown_json_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "x.json"
    path.write_text('{"hello": 1}')
    with pytest.raises(cr.CommonRoadError):
        cr.load(path)
    with pytest.raises(cr.CommonRoadError, match="no such file"):
        cr.load(tmp_path / "missing.xml")


def test_the_command_runs_a_request_json(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = cli_main(["commonroad", str(DATA / "ZAM_Over-1_1.json"), "--duration", "0.5", "--quiet",
                     "--no-gif", "--out", str(tmp_path)])  # fmt: skip
    assert code == 0
    assert "ZAM_Over-1_1" in capsys.readouterr().out
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["metrics"]["steps"] == 5
    if importlib.util.find_spec("commonroad") is None:  # judged by the simulator: the goal's arc length
        assert metrics["goal"]["s_min"] == pytest.approx(67.77)
        return
    # judged against ZAM_Over-1_1.xml.gz beside it: the scenario's goal and speed limit in the request
    request = json.loads((tmp_path / "request.json").read_text())
    assert request["goal"]["time"] == [0.0, 3.0] and len(request["goal"]["position"]["polygon"]) == 4
    assert request["options"]["speed_limit"] == 23.0  # the scenario's sign, above the 20 m/s target
    assert metrics["goal"]["s_min"] is None
    row = next(csv.DictReader((tmp_path / "results.csv").open()))
    judged = (row["judge"], row["goal"], row["collision"], row["transitions"])
    assert judged == ("commonroad", "no", "no", "5")


def test_the_command_reports_a_missing_file(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli_main(["commonroad", "no/such/file.xml", "--quiet"]) == 2
    assert "no such file" in capsys.readouterr().err


# --------------------------------------------------------------------------------------------------
# CommonRoad XML (the optional extra `commonroad`)
# --------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["C-DEU_B471-1_3_T-1", "DEU_Moabit-4_1_T-1"])
def test_xml_conversion_is_a_valid_request_close_to_the_shared_one(name: str) -> None:
    pytest.importorskip("commonroad")
    conv = cr.load(DATA / f"{name}.xml")
    req = PlanningRequest.model_validate(conv.request)
    shared = json.loads((DATA / f"{name}.json").read_text())
    # same obstacles, the same recorded motion
    assert sorted(o["id"] for o in conv.request["obstacles"]) == sorted(o["id"] for o in shared["obstacles"])
    ours = {o["id"]: o for o in conv.request["obstacles"]}
    for o in shared["obstacles"]:
        if "prediction" in o:
            assert ours[o["id"]]["prediction"] == o["prediction"]
            assert (ours[o["id"]]["length"], ours[o["id"]]["width"]) == (o["length"], o["width"])
    assert (
        conv.request["ego"]["x"] == shared["ego"]["x"]
        and conv.request["ego"]["speed"] == shared["ego"]["speed"]
    )
    assert conv.request["options"] == shared["options"]
    # a lane everywhere, the ends included (the shared conversion has 0 at an end)
    widths = np.array([req.lane.left_width, req.lane.right_width])
    assert widths.min() > 1.0
    # the route starts BEHIND_EGO behind the ego, or where the map does (Moabit: 7 m)
    assert 5.0 < conv.info["s_ego"] < cr.BEHIND_EGO + 0.5
    result = plan(problem_from_json(conv.request))
    assert result.status in ("ok", "stopped")


def test_an_ego_driving_against_its_lanelet_is_refused_by_name(monkeypatch: pytest.MonkeyPatch) -> None:
    """A route along the only lanelets there would run against the ego (the planner refuses such a
    request): the conversion says so instead of writing it."""
    pytest.importorskip("commonroad")
    read = cr.read_scenario

    def turned(path: object, planning_problem_id: int | None = None) -> tuple[object, object]:
        scenario, problem = read(path, planning_problem_id)  # type: ignore[arg-type]
        problem.initial_state.orientation += math.pi
        return scenario, problem

    monkeypatch.setattr(cr, "read_scenario", turned)
    with pytest.raises(cr.CommonRoadError, match=r"drives against every lanelet there \(\d+.*\): no route"):
        cr.load(DATA / "C-DEU_B471-1_3_T-1.xml")


def test_a_recorded_car_becomes_the_ego_of_a_new_scene(tmp_path: Path) -> None:
    """bench/swap_ego.py's scenes: the recorded car leaves the traffic and starts as the ego, its goal
    where its recording ends, within the slack around that end; the scene converts and plans."""
    pytest.importorskip("commonroad")
    scenario, _ = cr.read_scenario(DATA / "ZAM_Tjunction-1_42_T-1.xml.gz")
    cars = cr.recorded_cars(scenario, 60, 30.0)
    assert cars and all(len(c.prediction.trajectory.state_list) >= 60 for c in cars)
    car = cars[0]
    new, problems = cr.recorded_as_ego(scenario, car.obstacle_id, (2.0, 4.0))
    assert car.obstacle_id not in {o.obstacle_id for o in new.obstacles}
    assert scenario.obstacle_by_id(car.obstacle_id) is car  # the source scenario is left as it was
    conv = cr.load(cr.write_scenario(tmp_path / "swapped.xml", new, problems))
    req = PlanningRequest.model_validate(conv.request)
    x0, y0 = np.asarray(car.initial_state.position, dtype=float)
    # the converter reports the ego's centre (the recorded one), rounded to mm
    assert (req.ego.x, req.ego.y) == pytest.approx((x0, y0), abs=1e-3)
    assert req.ego.speed == pytest.approx(car.initial_state.velocity, abs=1e-3)
    assert str(car.obstacle_id) not in {o["id"] for o in conv.request["obstacles"]}
    end = (car.prediction.trajectory.state_list[-1].time_step - car.initial_state.time_step) * scenario.dt
    assert conv.goal["time"] == pytest.approx([end - 2.0, end + 4.0], abs=1e-6)
    assert plan(problem_from_json(conv.request)).status in ("ok", "stopped", "fallback")
    with pytest.raises(cr.CommonRoadError, match="no recorded vehicle"):
        cr.recorded_as_ego(scenario, -1)


def test_a_recorded_car_in_a_turn_starts_steering_into_it(tmp_path: Path) -> None:
    """DEU_Lohmar-55's car 310 is recorded turning right at 5.6 m/s, about 1 rad/s. As the ego of a
    swapped scene it starts with that yaw rate, and the request's curvature is ``ψ̇ / v`` held to 0.9 of
    the car's 4 m/s² lateral limit (the recorded driver turns at about 5.6 m/s²). Started straight (yaw
    rate 0), the car had to steer at 0.62 rad/s to stay in its lane (limit 0.4): a braking fallback."""
    pytest.importorskip("commonroad")
    scenario, _ = cr.read_scenario(DATA / "DEU_Lohmar-55_1_T-1.xml.gz")
    new, problems = cr.recorded_as_ego(scenario, 310, (2.0, 4.0))
    car = scenario.obstacle_by_id(310)
    first = car.prediction.trajectory.state_list[0]
    yaw_rate = problems.planning_problem_dict[310].initial_state.yaw_rate
    assert yaw_rate == pytest.approx((first.orientation - car.initial_state.orientation) / scenario.dt)
    assert yaw_rate < -0.9
    path = cr.write_scenario(tmp_path / "swapped.xml", new, problems)
    request = cr.load(path).request
    ego, vehicle = request["ego"], Vehicle(**request["vehicle"])
    body = abs(ego["curvature"]) * math.hypot(1.0, vehicle.rear_offset * ego["curvature"]) * ego["speed"] ** 2
    assert ego["curvature"] < 0.0
    assert body == pytest.approx(cr.START_LATERAL_SHARE * vehicle.max_lateral_acceleration, rel=1e-3)
    result = plan(prepare(path, Settings(vehicle="car")).problem)
    assert result.status == "ok", result.message
    assert result.trajectory.curvature[0] == pytest.approx(ego["curvature"], abs=1e-3)


def test_a_start_curvature_is_the_yaw_rate_over_the_speed_within_the_vehicles_limits() -> None:
    vehicle = {**cr.VEHICLE, "wheelbase": 2.5, "rear_axle_offset": 1.2, "max_curvature": 0.4}
    assert cr.initial_curvature(0.05, 10.0, vehicle) == pytest.approx(0.005)
    assert cr.initial_curvature(-0.05, 10.0, vehicle) == pytest.approx(-0.005)
    assert cr.initial_curvature(None, 10.0, vehicle) is None
    assert cr.initial_curvature(0.3, cr.YAW_RATE_MIN_SPEED / 2, vehicle) is None  # too slow to say
    assert cr.initial_curvature(2.0, 1.0, vehicle) == pytest.approx(0.4)  # the curvature limit
    fast = cr.initial_curvature(1.0, 8.0, vehicle)  # 8 m/s² for a 4 m/s² car
    assert fast is not None
    body = fast * math.hypot(1.0, 1.2 * fast) * 8.0**2
    assert body == pytest.approx(cr.START_LATERAL_SHARE * vehicle["max_lateral_acceleration"])


def test_a_line_continued_straight_keeps_its_direction_spacing_and_end_widths() -> None:
    line = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 1.0], [3.0, 2.0]])
    widths = (np.array([1.0, 2.0, 3.0, 4.0]), np.array([0.5, 0.5, 0.5, 1.5]))
    out, (left, right) = cr.continued_straight(line, widths, 10.0, 1.0)
    assert out.shape == (14, 2) and np.array_equal(out[:4], line)
    steps = np.diff(out[3:], axis=0)
    assert np.allclose(np.hypot(*steps.T), 1.0)
    assert np.allclose(steps / np.hypot(*steps.T)[:, None], [math.sqrt(0.5), math.sqrt(0.5)])
    assert np.array_equal(left, [1.0, 2.0, 3.0] + [4.0] * 11) and np.array_equal(right[3:], [1.5] * 11)


def test_a_route_to_the_maps_edge_goes_on_straight_one_inside_the_map_does_not() -> None:
    """US101's route ends where its map does, and recorded cars drive off it there: the reference goes on
    MAP_EDGE_EXTENSION straight past the last lanelet's end, with the end's widths; Lohmar-26's route
    ends inside the map: no extension."""
    pytest.importorskip("commonroad")
    conv = cr.load(DATA / "USA_US101-6_1_T-1.xml.gz")
    scenario, _ = cr.read_scenario(DATA / "USA_US101-6_1_T-1.xml.gz")
    network = scenario.lanelet_network
    assert not network.find_lanelet_by_id(conv.info["route_lanelet_ids"][-1]).successor
    assert conv.info["map_edge_extension_m"] == cr.MAP_EDGE_EXTENSION
    req = PlanningRequest.model_validate(conv.request)
    points = np.asarray(conv.request["reference_line"], dtype=float)
    extended = round(cr.MAP_EDGE_EXTENSION / cr.SPACING)
    beyond = points[-extended:]
    assert not any(network.find_lanelet_by_position(list(beyond[5:])))  # off the map
    heading = np.arctan2(*np.diff(points[-extended - 1 :], axis=0).T[::-1])
    assert np.ptp(heading) < 5e-3  # straight (the points are rounded to mm)
    for widths in (req.lane.left_width, req.lane.right_width, req.road.left_width, req.road.right_width):
        assert isinstance(widths, list) and len(set(widths[-extended - 1 :])) == 1
    inside = cr.load(DATA / "DEU_Lohmar-26_1_T-1.xml.gz")
    assert inside.info["map_edge_extension_m"] == 0.0


@pytest.mark.parametrize(
    ("name", "why"),
    [
        ("ZAM_Loading_Bay-1_1_T", "no traffic drives off the map there"),
        ("DEU_Lohmar-55_1_T-1", "its continuation meets other lanelets"),
    ],
)
def test_a_route_to_the_maps_edge_ends_there_where_the_road_need_not_go_on(name: str, why: str) -> None:
    """The loading bay's route ends at the map's edge, but no recorded vehicle leaves there (a dead end,
    as far as the recording says); Lohmar-55's straight continuation would run into other lanelets."""
    pytest.importorskip("commonroad")
    scenario, _ = cr.read_scenario(DATA / f"{name}.xml.gz")
    conv = cr.load(DATA / f"{name}.xml.gz")
    assert not scenario.lanelet_network.find_lanelet_by_id(conv.info["route_lanelet_ids"][-1]).successor
    assert conv.info["map_edge_extension_m"] == 0.0, why


def test_a_recorded_car_driving_off_the_map_is_not_braked_for_the_maps_edge(tmp_path: Path) -> None:
    """A swapped-ego scene (bench/swap_ego.py) whose recorded car drives at 18 m/s to the map's edge, a
    faster car behind it: its goal lies 14 m before the edge. Planned as if the road ended there, the
    first plan braked for the edge into the car behind (a fallback); the road goes on: it drives on."""
    pytest.importorskip("commonroad")
    scenario, _ = cr.read_scenario(DATA / "USA_US101-6_1_T-1.xml.gz")
    new, problems = cr.recorded_as_ego(scenario, 376, (2.0, 4.0))
    path = cr.write_scenario(tmp_path / "swapped.xml", new, problems)
    assert cr.load(path).info["map_edge_extension_m"] > 0.0
    # as `kappa-planner commonroad` plans it (the traffic driving on past the edge, the goal, the limit)
    result = plan(prepare(path, Settings(vehicle="car")).problem)
    assert result.status == "ok", result.message
    assert min(result.trajectory.a) > -0.5  # no braking


def test_the_road_reaches_as_far_as_the_surface_goes_without_a_gap() -> None:
    shapely = pytest.importorskip("shapely")
    points = np.column_stack((np.linspace(0.0, 50.0, 11), np.zeros(11)))
    lane = np.full(11, 1.75)
    # drivable from y = -1.75 to 5.25, a 0.5 m gap (a median), more surface beyond it
    surface = shapely.union(shapely.box(-5.0, -1.75, 55.0, 5.25), shapely.box(-5.0, 5.75, 55.0, 12.0))
    left, right = cr.surface_widths(points, lane, lane, surface)
    np.testing.assert_allclose(left, 5.25, atol=cr.ROAD_STEP + 1e-9)
    assert np.all(left <= 5.25)
    np.testing.assert_allclose(right, 1.75)  # no surface beyond the lane on the right
    wide = shapely.box(-5.0, -30.0, 55.0, 30.0)
    left, right = cr.surface_widths(points, lane, lane, wide)
    np.testing.assert_allclose(left, 1.75 + cr.ROAD_BEYOND, atol=1e-9)  # at most ROAD_BEYOND beyond it
    np.testing.assert_allclose(right, 1.75 + cr.ROAD_BEYOND, atol=1e-9)


def test_xml_conversion_emits_the_road_of_the_opposite_lane() -> None:
    pytest.importorskip("commonroad")
    conv = cr.load(DATA / "C-DEU_B471-1_3_T-1.xml")
    req = PlanningRequest.model_validate(conv.request)
    assert req.road is not None
    lane_left, road_left = np.array(req.lane.left_width), np.array(req.road.left_width)
    np.testing.assert_array_equal(req.road.right_width, req.lane.right_width)  # the verge: nothing
    beyond = road_left - lane_left
    assert np.all(beyond >= 0.0) and 3.0 < float(np.median(beyond)) < 4.5  # the opposite lane
    shared = json.loads((DATA.parent / "commonroad-road" / "C-DEU_B471-1_3_T-1.json").read_text())
    shared_beyond = np.array(shared["road"]["left_width"]) - np.array(shared["lane"]["left_width"])
    assert float(np.median(beyond)) == pytest.approx(float(np.median(shared_beyond)), abs=0.3)


def test_xml_conversion_opens_the_junction_beyond_aarschots_hairpin() -> None:
    """The U-turn crosses a junction: no lanelet is adjacent to the turning one, but the crossing road's
    lanelets lie beyond its outside (the right of a left turn)."""
    pytest.importorskip("commonroad")
    conv = cr.load(DATA / "BEL_Aarschot-3_1_T-1.xml.gz")
    problem = problem_from_json(conv.request)
    assert problem.road is not None
    ref = build_reference(problem.reference_line)
    tightest = float(ref.s[np.argmax(ref.kappa)])
    s = np.linspace(tightest - 3.0, tightest + 3.0, 7)
    _, lane_right = problem.lane.widths(ref, s)
    _, road_right = problem.road.widths(ref, s)
    assert np.all(road_right - lane_right > 1.0)


def test_xml_goal_region_becomes_an_arc_length() -> None:
    pytest.importorskip("commonroad")
    conv = cr.load(DATA / "C-DEU_B471-1_3_T-1.xml")
    index = {e["name"]: e for e in json.loads((DATA / "index.json").read_text())}
    # the shared converter's s_goal, measured on a reference starting at another point
    shared_s = index["C-DEU_B471-1_3_T-1"]["goal"]["s_goal"] - 10.45 + conv.info["s_ego"]
    assert conv.goal["s_min"] == pytest.approx(shared_s, abs=5.0)
    assert conv.goal["time"] == [0.0, 5.0]
    survival = cr.load(DATA / "DEU_Moabit-4_1_T-1.xml")
    assert survival.goal["s_min"] is None and survival.goal["time"] == [3.3, 3.3]


def test_the_command_converts_and_drives_an_xml(tmp_path: Path) -> None:
    pytest.importorskip("commonroad")
    code = cli_main(["commonroad", str(DATA / "C-DEU_B471-1_3_T-1.xml"), "--duration", "0.3", "--quiet",
                     "--no-gif", "--out", str(tmp_path)])  # fmt: skip
    assert code == 0
    request = json.loads((tmp_path / "request.json").read_text())
    PlanningRequest.model_validate(request)
    info = json.loads((tmp_path / "conversion.json").read_text())
    assert info["info"]["route_lanelet_ids"] == [38807]


def test_xml_without_the_extra_says_how_to_install_it(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "commonroad", None)  # as if commonroad-io were not installed
    with pytest.raises(cr.CommonRoadError, match=r"kappa-planner\[commonroad\]"):
        cr.load(DATA / "C-DEU_B471-1_3_T-1.xml")
    assert cli_main(["commonroad", str(DATA / "C-DEU_B471-1_3_T-1.xml"), "--quiet"]) == 2
    assert "commonroad-io" in capsys.readouterr().err


def test_a_written_solution_of_the_car_is_feasible_for_commonroads_checker(tmp_path: Path) -> None:
    """``kappa-planner commonroad X.xml --solution`` writes the driven motion of CommonRoad's car (vehicle
    type 2) as a kinematic single-track solution; commonroad-drivability-checker finds every
    transition feasible (its position and orientation tolerances, its steering limits). Driven as the
    point model, the same solution is not: the checker places the rear axle behind the centre along a
    yaw the point model does not have."""
    pytest.importorskip("commonroad")
    pytest.importorskip("commonroad_dc")
    from commonroad.common.solution import CommonRoadSolutionReader, VehicleModel, VehicleType

    scenario = DATA / "DEU_Moabit-4_1_T-1.xml"  # an urban start: it turns while it brakes behind traffic
    verdicts = {}
    for vehicle in ("request", "point"):
        out = tmp_path / f"{vehicle}.xml"
        code = cli_main(["commonroad", str(scenario), "--duration", "3", "--quiet", "--vehicle", vehicle,
                         "--solution", str(out)])  # fmt: skip
        assert code == 0 and out.exists()
        solution = CommonRoadSolutionReader.open(str(out))
        (pp,) = solution.planning_problem_solutions
        assert (pp.vehicle_model, pp.vehicle_type) == (VehicleModel.KS, VehicleType.BMW_320i)
        states = pp.trajectory.state_list
        assert len(states) == 31 and states[0].time_step == 0
        verdicts[vehicle] = cr.feasible_transitions(states, 0.1)
    assert all(verdicts["request"]), verdicts["request"]
    assert not all(verdicts["point"])


def test_the_xml_conversion_is_commonroads_car() -> None:
    pytest.importorskip("commonroad")
    conv = cr.load(DATA / "C-DEU_B471-1_3_T-1.xml")
    vehicle = conv.request["vehicle"]
    assert vehicle["wheelbase"] == pytest.approx(2.578, abs=1e-3)
    assert vehicle["rear_axle_offset"] == pytest.approx(1.422, abs=1e-3)
    assert (vehicle["length"], vehicle["width"]) == (4.508, 1.61)
    assert (vehicle["max_steering_angle"], vehicle["max_steering_rate"]) == (1.066, 0.4)
    # the car turns as its steering allows (tan δ / W), not as the point model's 0.3 1/m
    assert vehicle["max_curvature"] == pytest.approx(np.tan(1.066) / vehicle["wheelbase"])
    assert problem_from_json(conv.request).vehicle.curvature_limit == pytest.approx(0.702, abs=1e-3)
    assert cr.point_vehicle(vehicle) == cr.VEHICLE
    assert cr.car_vehicle(cr.VEHICLE) == vehicle
    assert (conv.info["dt"], conv.info["initial_time_step"]) == (0.1, 0)
    problem = problem_from_json(conv.request)
    assert problem.vehicle.is_car
    result = plan(problem)
    assert result.trajectory.steering_angle is not None


def test_a_solution_needs_the_xml(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = cli_main(["commonroad", str(DATA / "DEU_Moabit-4_1_T-1.json"), "--duration", "0.2", "--quiet",
                     "--solution", str(tmp_path / "s.xml")])  # fmt: skip
    assert code == 2 and "needs a CommonRoad XML" in capsys.readouterr().err
