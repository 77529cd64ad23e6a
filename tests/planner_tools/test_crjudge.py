"""CommonRoad's judgement of a run (planner_tools.crjudge): the scenario's goal and speed limit in the
request, goal checks, collisions with rear-end ones apart, off-road, on the shared XML scenarios and on
motions made up here."""

from __future__ import annotations

import gzip
import hashlib
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import shapely

from planner_tools.sim import Motion

DATA = Path(__file__).resolve().parents[1] / "data" / "commonroad"


def _scene(name: str):  # type: ignore[no-untyped-def]
    pytest.importorskip("commonroad")
    pytest.importorskip("commonroad_dc")
    from planner_tools.crjudge import CommonRoadScene

    path = DATA / f"{name}.xml"
    return CommonRoadScene.from_file(path if path.exists() else DATA / f"{name}.xml.gz")


def _motion(t_end: float, x, y, yaw, v=0.0) -> Motion:  # type: ignore[no-untyped-def]
    """A motion sampled every 0.01 s; ``x``, ``y``, ``yaw``, ``v`` are functions of t or constants."""
    t = np.round(np.arange(0.0, t_end + 1e-9, 0.01), 10)

    def f(value):  # type: ignore[no-untyped-def]
        return np.asarray(value(t) if callable(value) else np.full_like(t, value), dtype=float)

    zero = np.zeros_like(t)
    return Motion(
        t=t, x=f(x), y=f(y), yaw=f(yaw), course=f(yaw), steering=zero, curvature=zero, v=f(v), a=zero,
        s=zero, d=zero, step=(t / 0.1).astype(np.intp),
    )  # fmt: skip


def test_the_shared_xml_files_are_the_shared_folders_byte_for_byte() -> None:
    sums = dict(line.split()[::-1] for line in (DATA / "SHA256SUMS").read_text().splitlines())
    assert len(sums) == 19
    for name, digest in sums.items():
        plain = DATA / name
        data = plain.read_bytes() if plain.exists() else gzip.decompress((DATA / f"{name}.gz").read_bytes())
        assert hashlib.sha256(data).hexdigest() == digest, name
        assert name in (DATA / "SOURCES.md").read_text()


# --------------------------------------------------------------------------------------------------
# What the request carries
# --------------------------------------------------------------------------------------------------


def test_a_goal_region_becomes_the_requests_goal() -> None:
    scene = _scene("C-DEU_B471-1_3_T-1")  # a rectangle, an orientation range, time steps 0..50
    goal = scene.goal_request()
    assert set(goal) == {"position", "time"} and goal["time"] == [0.0, 5.0]
    polygon = np.array(goal["position"]["polygon"])
    assert polygon.shape == (4, 2)
    (state,) = scene.problem.goal.state_list
    assert state.position.contains_point(shapely.Point(polygon.mean(axis=0)))
    peach = _scene("USA_Peach-3_1_T-1").goal_request()  # a speed range, steps 45..50
    assert peach["time"] == [4.5, 5.0] and peach["speed"] == pytest.approx([8.5611, 14.5611])
    tjunction = _scene("ZAM_Tjunction-1_42_T-1").goal_request()  # a speed range reaching below 0
    assert tjunction["speed"][0] == 0.0 and tjunction["speed"][1] == pytest.approx(10.634771, abs=1e-4)


def test_a_goal_by_time_only_and_no_goal() -> None:
    moabit = _scene("DEU_Moabit-4_1_T-1")
    assert moabit.goal_request() == {"time": [3.3, 3.3]} and moabit.goal_window() == pytest.approx((3.3, 3.3))
    lower = _scene("DEU_LocationALower-28_1_S-1")  # its planning problem has no goal state
    assert not lower.has_goal and lower.goal_request() is None and lower.goal_window() is None


def test_goal_times_count_from_the_initial_time_step() -> None:
    scene = _scene("DEU_A9-3_1_T-1")  # dt 0.2 s: steps 0..30 are 0..6 s
    assert scene.dt == 0.2 and scene.goal_window() == (0.0, 6.0)


def test_the_speed_limit_is_the_routes_lowest_sign() -> None:
    import json

    scene = _scene("ZAM_Over-1_1")
    request = json.loads((DATA / "ZAM_Over-1_1.json").read_text())
    route = scene.route_lanelets(request["reference_line"], [request["ego"]["x"], request["ego"]["y"]])
    assert route
    limit = scene.speed_limit(route)
    assert (limit.value, limit.source) == (23.0, "sign")


def _fake_scene(types: set[str], tags: set[str], signs: list[float]):  # type: ignore[no-untyped-def]
    from planner_tools.crjudge import CommonRoadScene

    elements = [
        SimpleNamespace(traffic_sign_element_id=SimpleNamespace(name="MAX_SPEED"), additional_values=[str(v)])
        for v in signs
    ]
    sign = SimpleNamespace(traffic_sign_elements=elements)
    lanelet = SimpleNamespace(
        traffic_signs={1} if signs else set(), lanelet_type=[SimpleNamespace(value=t) for t in types]
    )
    network = SimpleNamespace(find_lanelet_by_id=lambda i: lanelet, find_traffic_sign_by_id=lambda i: sign)
    scenario = SimpleNamespace(
        lanelet_network=network, tags=[SimpleNamespace(value=t) for t in tags], dt=0.1, scenario_id="fake"
    )
    problem = SimpleNamespace(initial_state=SimpleNamespace(time_step=0))
    return CommonRoadScene(scenario, problem)


@pytest.mark.parametrize(
    ("types", "tags", "signs", "value", "source"),
    [
        ({"urban"}, set(), [8.0, 5.5], 5.5, "sign"),
        ({"country"}, {"urban"}, [], 100 / 3.6, "lanelet type: country"),
        ({"highway", "urban"}, set(), [], 50 / 3.6, "lanelet type: urban"),
        ({"interstate"}, set(), [], 130 / 3.6, "lanelet type: highway"),
        ({"unknown"}, {"rural", "critical"}, [], 100 / 3.6, "scenario tag: country"),
        (set(), {"critical"}, [], 50 / 3.6, "default: urban"),
    ],
)
def test_without_a_sign_the_road_type_sets_the_speed_limit(
    types: set[str], tags: set[str], signs: list[float], value: float, source: str
) -> None:
    limit = _fake_scene(types, tags, signs).speed_limit([7])
    assert limit.value == pytest.approx(value) and limit.source == source


# --------------------------------------------------------------------------------------------------
# Judging a motion
# --------------------------------------------------------------------------------------------------


def test_goal_reached_by_commonroads_check_inside_its_window_and_orientation() -> None:
    scene = _scene("C-DEU_B471-1_3_T-1")
    (state,) = scene.problem.goal.state_list
    centre = state.position.center
    heading = 0.5 * (state.orientation.start + state.orientation.end)
    there = scene.judge(_motion(1.0, centre.x, centre.y, heading), 4.508, 1.61, feasibility=False)
    assert there.goal_reached and there.goal_time == 0.0
    wrong_way = scene.judge(_motion(1.0, centre.x, centre.y, heading + 1.0), 4.508, 1.61, feasibility=False)
    assert not wrong_way.goal_reached
    check = scene.goal_check()
    at = SimpleNamespace(t=0.3, x=centre.x, y=centre.y, yaw=heading, speed=10.0, steering=0.0)
    assert check(at) and not check(SimpleNamespace(**{**vars(at), "t": 0.305}))  # between time steps
    assert not check(SimpleNamespace(**{**vars(at), "t": 5.1}))  # after the window


def test_a_goal_by_time_only_is_reached_by_surviving_until_it() -> None:
    scene = _scene("DEU_Moabit-4_1_T-1")
    ego = scene.problem.initial_state
    x, y = map(float, ego.position)
    short = scene.judge(_motion(3.2, x, y, float(ego.orientation)), 4.508, 1.61, feasibility=False)
    long = scene.judge(_motion(3.3, x, y, float(ego.orientation)), 4.508, 1.61, feasibility=False)
    assert not short.goal_reached and long.goal_reached and long.goal_time == pytest.approx(3.3)
    assert long.states == 34 and long.off_road_steps == 0
    # a window from 0 to 6 s (dt 0.2 s): the initial state is inside it, but only surviving it all counts
    a9 = _scene("DEU_A9-3_1_T-1")
    ego = a9.problem.initial_state
    x, y, yaw = float(ego.position[0]), float(ego.position[1]), float(ego.orientation)
    check = a9.goal_check()
    assert not check(SimpleNamespace(t=0.0, x=x, y=y, yaw=yaw, speed=28.0, steering=0.0))
    assert check(SimpleNamespace(t=6.0, x=x, y=y, yaw=yaw, speed=28.0, steering=0.0))
    move = (lambda t: x + 28.0 * t, y, yaw, 28.0)
    assert not a9.judge(_motion(5.8, *move), 4.508, 1.61, feasibility=False).goal_reached
    survived = a9.judge(_motion(6.0, *move), 4.508, 1.61, feasibility=False)
    assert survived.goal_reached and survived.goal_time == pytest.approx(6.0) and survived.states == 31


def test_a_car_from_behind_that_runs_into_a_standing_ego_is_a_rear_end_collision() -> None:
    scene = _scene("DEU_Test-1_1_T-1")  # one car from x = 17 m at 10 m/s along y = 2; the ego at 35.1 m
    ego = scene.problem.initial_state
    standing = scene.judge(_motion(3.0, float(ego.position[0]), 2.1, 0.0), 4.508, 1.61, feasibility=False)
    (obstacle,) = scene.scenario.dynamic_obstacles
    assert standing.collided == (str(obstacle.obstacle_id),)
    assert standing.rear_end == standing.collided
    # the car is 4.5 m long: contact when its front (x = 17 + 10 t + 2.25) meets the ego's rear (35.1 − 2.254)
    contact = math.ceil((35.1 - 2.254 - 19.25) / 10.0 / 0.1) * 0.1
    assert standing.first_collision_time == pytest.approx(contact)


def test_a_set_based_prediction_from_behind_over_a_standing_ego_is_rear_end() -> None:
    """DEU_LocationALower's traffic has set-based predictions (occupied sets, no states): the heading and
    speed of the set come from its centre's motion."""
    scene = _scene("DEU_LocationALower-28_1_S-1")
    ego = scene.problem.initial_state
    x, y, yaw = float(ego.position[0]), float(ego.position[1]), float(ego.orientation)
    verdict = scene.judge(_motion(3.4, x, y, yaw), 4.508, 1.61, feasibility=False)
    assert verdict.collided == ("17",) and verdict.rear_end == ("17",)
    assert 2.0 < (verdict.first_collision_time or 0.0) < 2.3  # 26 m/s from about 22 m behind


def test_the_collision_check_of_a_state_asks_the_checker_at_its_time_step() -> None:
    scene = _scene("DEU_Test-1_1_T-1")
    check = scene.collision_check(3.0, 4.508, 1.61)
    x = float(scene.problem.initial_state.position[0])

    def at(t: float) -> SimpleNamespace:
        return SimpleNamespace(t=t, x=x, y=2.1, yaw=0.0)

    contact = math.ceil((35.1 - 2.254 - 19.25) / 10.0 / 0.1) * 0.1  # as in the test above
    assert not check(at(0.0)) and not check(at(contact - 0.1))
    assert check(at(contact)) and not check(at(contact + 0.05))  # between time steps: not judged


def test_running_into_the_car_ahead_is_a_collision_but_not_rear_end() -> None:
    scene = _scene("DEU_Test-1_1_T-1")
    # behind the car (x = 17 m at t = 0, 10 m/s), the ego at 15 m/s from x = 8 m catches it with its front
    hit = scene.judge(_motion(4.0, lambda t: 8.0 + 15.0 * t, 2.0, 0.0, 15.0), 4.508, 1.61, feasibility=False)
    assert hit.collision and hit.rear_end == ()
    # the same from the side: the car's front against the ego's side is no rear-end collision either
    side = scene.judge(_motion(3.0, 25.0, 2.0, math.pi / 2), 4.508, 1.61, feasibility=False)
    assert side.collision and side.rear_end == ()


def test_a_static_obstacle_is_a_collision_and_leaving_the_lanelets_is_off_road() -> None:
    scene = _scene("ZAM_Over-1_1")
    (static,) = scene.scenario.static_obstacles
    centre = static.occupancy_at_time(0).center
    verdict = scene.judge(_motion(0.5, centre.x, centre.y, 0.0), 4.508, 1.61)
    assert verdict.collided == (str(static.obstacle_id),) and verdict.rear_end == ()
    assert verdict.first_collision_time == 0.0 and len(verdict.feasible) == 5
    away = scene.judge(_motion(0.5, centre.x + 1e4, centre.y, 0.0), 4.508, 1.61, feasibility=False)
    assert not away.collision and away.off_road_steps == away.states == 6 and away.first_off_road_time == 0.0
