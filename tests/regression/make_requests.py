"""Write the golden planning requests of the regression suite to ``tests/regression/requests/``.

Each golden request ``NAME.json`` is a body for ``POST /v1/plan``; its sidecar ``NAME.expect.json`` says
which answers are acceptable (``statuses``), what the request is about and, where a fallback is
tolerated for now, the known issue behind it. The requests are

* the demo road (``app.conversions.demo_request``, what ``GET /v1/demo`` serves) and a coarser variant of it;
* synthetic scenarios built on exactly known roads (``planner.roads``, ``tests/planner/scenario_roads.py``),
  the same situations as ``tests/planner/test_scenarios.py``;
* copies of some recorded CommonRoad requests from ``tests/data/commonroad/``.

Run from the repository root::

    python tests/regression/make_requests.py          # (re)write the requests and sidecars
    python tests/regression/make_requests.py --check  # exit 1 if the files differ from what it builds

Units: metres, seconds, radians.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # run as a script
    sys.path.insert(0, str(ROOT))

from app.conversions import demo_request, from_problem  # noqa: E402
from planner.goal import Goal, GoalCircle, GoalPolygon  # noqa: E402
from planner.problem import (  # noqa: E402
    CircleObstacle,
    DynamicObstacle,
    Ego,
    Lane,
    Options,
    PlanningProblem,
    PolygonObstacle,
    Vehicle,
)
from planner.roads import box, driving, straight, two_lane_problem, u_turn  # noqa: E402
from tests.planner.scenario_roads import (  # noqa: E402
    Road,
    arc_piece,
    box_on_road,
    follow_prediction,
    straight_piece,
)

REQUESTS = Path(__file__).resolve().parent / "requests"
COMMONROAD = ROOT / "tests" / "data" / "commonroad"
COMMONROAD_ROAD = ROOT / "tests" / "data" / "commonroad-road"

Json = dict[str, Any]
OK, STOPPED, FALLBACK = "ok", "stopped", "fallback"


def _request(problem: PlanningProblem) -> Json:
    return from_problem(problem).model_dump(mode="json", exclude_none=True)


# --------------------------------------------------------------------------------------------------
# Synthetic scenarios
# --------------------------------------------------------------------------------------------------


def demo() -> Json:
    """What ``GET /v1/demo`` serves."""
    return demo_request().model_dump(mode="json", exclude_none=True)


def demo_coarse() -> Json:
    """The demo with a coarser time step, a shorter horizon, fewer candidates, the candidates returned."""
    data = demo()
    data["options"].update(
        dt=0.25, horizon_time=6.0, num_candidates=12, num_points=40, return_candidates=True
    )
    return data


def u_turn_cone() -> Json:
    """The paper's U-turn (radius 8 m, inner side 11 m wide) with a cone on the outer half at the apex."""
    radius = 8.0
    cone = CircleObstacle("cone", center=np.array([radius + 1.2, radius]), radius=1.0)
    return _request(
        PlanningProblem(
            reference_line=u_turn(radius=radius, leg=40.0, step=1.0),
            lane=Lane(left_width=radius + 3.0, right_width=3.5),
            ego=Ego(x=-12.0, y=0.0, heading=0.0, speed=5.0),
            obstacles=(cone,),
            vehicle=Vehicle(),
            options=Options(horizon_time=8.0, dt=0.1, target_speed=7.0),
        )
    )


def hairpin_turning_limit() -> Json:
    """A 5 m hairpin with max_curvature 0.2 1/m: the centre line itself is at the turning limit."""
    return _request(
        PlanningProblem(
            reference_line=u_turn(radius=5.0, leg=30.0, step=0.5),
            lane=Lane(left_width=3.5, right_width=4.0),
            ego=Ego(x=-10.0, y=0.0, heading=0.0, speed=3.0),
            vehicle=Vehicle(max_curvature=0.2),
            options=Options(horizon_time=8.0, dt=0.1, target_speed=4.0),
        )
    )


def s_curve_parked_cars() -> Json:
    """An S-curve with cars parked 1 m into the lane on alternating sides."""
    road = Road(
        [
            straight_piece(20.0),
            arc_piece(30.0, np.radians(50.0)),
            arc_piece(30.0, -np.radians(100.0)),
            arc_piece(30.0, np.radians(50.0)),
            straight_piece(60.0),
        ]
    )
    parked = [(32.0, -1.9), (58.0, 1.9), (84.0, -1.9)]
    obstacles = tuple(
        PolygonObstacle(f"car{k}", box_on_road(road, s, d, 4.5, 1.8)) for k, (s, d) in enumerate(parked)
    )
    x0, y0, h0 = road.pose(10.0)
    return _request(
        PlanningProblem(
            reference_line=road.polyline(1.0),
            lane=Lane(left_width=3.5, right_width=3.5),
            ego=Ego(x=x0, y=y0, heading=h0, speed=8.0),
            obstacles=obstacles,
            vehicle=Vehicle(),
            options=Options(horizon_time=10.0, dt=0.1, target_speed=9.0),
        )
    )


def right_angle_corner() -> Json:
    """A 90° left corner on a 3 m radius, tighter than the vehicle's 5 m: driven wide in a wide lane."""
    road = Road([straight_piece(30.0), arc_piece(3.0, np.pi / 2), straight_piece(30.0)])
    x0, y0, h0 = road.pose(14.0)
    return _request(
        PlanningProblem(
            reference_line=road.polyline(0.5),
            lane=Lane(left_width=2.5, right_width=5.0),
            ego=Ego(x=x0, y=y0, heading=h0, speed=3.0),
            vehicle=Vehicle(max_curvature=0.2),
            options=Options(horizon_time=8.0, dt=0.1, target_speed=4.0),
        )
    )


def blocked_road() -> Json:
    """A wall across the whole lane 35 m ahead: the answer must stop before it."""
    road = Road([straight_piece(20.0), arc_piece(80.0, np.radians(60.0))])
    x0, y0, h0 = road.pose(10.0)
    wall = PolygonObstacle("wall", box_on_road(road, 45.5, 0.0, 1.0, 9.0))
    return _request(
        PlanningProblem(
            reference_line=road.polyline(2.0),
            lane=Lane(left_width=3.5, right_width=3.5),
            ego=Ego(x=x0, y=y0, heading=h0, speed=8.0),
            obstacles=(wall,),
            vehicle=Vehicle(),
            options=Options(horizon_time=8.0, dt=0.1, target_speed=10.0),
        )
    )


def slow_leader() -> Json:
    """A 3 m/s leader in a 3.6 m lane with no room to pass: followed."""
    road = Road([straight_piece(30.0), arc_piece(120.0, np.radians(40.0)), straight_piece(80.0)])
    lead = DynamicObstacle("lead", 4.5, 1.8, follow_prediction(road, 32.0, 3.0, 8.0))
    x0, y0, h0 = road.pose(10.0)
    return _request(
        PlanningProblem(
            reference_line=road.polyline(1.0),
            lane=Lane(left_width=1.8, right_width=1.8),
            ego=Ego(x=x0, y=y0, heading=h0, speed=8.0),
            obstacles=(lead,),
            vehicle=Vehicle(),
            options=Options(horizon_time=8.0, dt=0.1, target_speed=10.0),
        )
    )


def pedestrian() -> Json:
    """A pedestrian crossing at 1.5 m/s 25 m ahead, too soon to pass first: yielded to."""
    t = np.arange(0.0, 8.01, 0.1)
    walk = np.column_stack((t, np.full_like(t, 35.0), 4.5 - 1.5 * t, np.full_like(t, -np.pi / 2)))
    return _request(
        PlanningProblem(
            reference_line=Road([straight_piece(150.0)]).polyline(5.0),
            lane=Lane(left_width=3.5, right_width=3.5),
            ego=Ego(x=10.0, y=0.0, heading=0.0, speed=8.0),
            obstacles=(DynamicObstacle("pedestrian", 0.6, 0.6, walk),),
            vehicle=Vehicle(),
            options=Options(horizon_time=8.0, dt=0.1, target_speed=10.0),
        )
    )


def goal_past_parked_car() -> Json:
    """A car parked 1.2 m into the lane in a 40 m left curve, and a goal beyond it: stop in a 3 m disc."""
    road = Road([straight_piece(20.0), arc_piece(40.0, np.radians(90.0)), straight_piece(60.0)])
    parked = PolygonObstacle("parked", box_on_road(road, 40.0, -1.4, 4.5, 1.8))
    x0, y0, h0 = road.pose(10.0)
    goal = Goal(GoalCircle(road.point(67.0, 0.0), 3.0), speed=(0.0, 0.5))
    return _request(
        PlanningProblem(
            reference_line=road.polyline(1.0),
            lane=Lane(left_width=3.5, right_width=3.5),
            ego=Ego(x=x0, y=y0, heading=h0, speed=8.0),
            obstacles=(parked,),
            vehicle=Vehicle(),
            options=Options(horizon_time=10.0, dt=0.1, target_speed=8.0),
            goal=goal,
        )
    )


def goal_window() -> Json:
    """A goal region 95–115 m ahead between 6 and 8 s from now: late at the target (10 m/s), in time up
    to the speed limit (16 m/s)."""
    road = Road([straight_piece(300.0)])
    region = GoalPolygon(np.array([[105.0, -1.75], [125.0, -1.75], [125.0, 1.75], [105.0, 1.75]]))
    return _request(
        PlanningProblem(
            reference_line=road.polyline(5.0),
            lane=Lane(left_width=3.5, right_width=3.5),
            ego=Ego(x=10.0, y=0.0, heading=0.0, speed=10.0),
            vehicle=Vehicle(),
            options=Options(horizon_time=8.0, dt=0.1, target_speed=10.0, speed_limit=16.0),
            goal=Goal(region, time=(6.0, 8.0)),
        )
    )


HIGHWAY = Road(
    [
        straight_piece(300.0),
        arc_piece(1000.0, np.radians(15.0)),
        straight_piece(250.0),
        arc_piece(800.0, -np.radians(25.0)),
        straight_piece(200.0),
        arc_piece(1200.0, np.radians(12.0)),
        straight_piece(400.0),
    ]
)


def highway(s_ego: float) -> Callable[[], Json]:
    """A 2.3 km highway given as a polyline every 5 m, the ego at ``s_ego`` [m] at 25 m/s."""

    def build() -> Json:
        x0, y0, h0 = HIGHWAY.pose(s_ego)
        return _request(
            PlanningProblem(
                reference_line=HIGHWAY.polyline(5.0),
                lane=Lane(left_width=3.75, right_width=3.75),
                ego=Ego(x=x0, y=y0, heading=h0, speed=25.0),
                vehicle=Vehicle(max_speed=36.0),
                options=Options(horizon_time=8.0, dt=0.1, target_speed=25.0),
            )
        )

    build.__doc__ = highway.__doc__
    return build


def commonroad(name: str, *, road: bool = False) -> Callable[[], Json]:
    """A recorded CommonRoad request as it is in ``tests/data/commonroad/`` (with ``road``:
    ``tests/data/commonroad-road/``; the file is copied as is)."""
    return _CopiedFile((COMMONROAD_ROAD if road else COMMONROAD) / f"{name}.json")


def parked_truck(*, oncoming: bool = False) -> Callable[[], Json]:
    """A lane-wide truck parked 44–56 m ahead on a two-lane road whose opposite lane is the road beyond
    the lane (`road`); with an oncoming car in it."""

    def build() -> Json:
        extra = (driving("car", 160.0, 3.5, -10.0),) if oncoming else ()
        truck = box("truck", 60.0, 0.0, 12.0, 3.2)
        return _request(two_lane_problem(straight(160.0), obstacles=(truck, *extra)))

    return build


class _CopiedFile:
    """A request read from a file, and copied byte for byte when the requests are written."""

    def __init__(self, source: Path) -> None:
        self.source = source

    def __call__(self) -> Json:
        data: Json = json.loads(self.source.read_text())
        return data


# --------------------------------------------------------------------------------------------------
# The golden set
# --------------------------------------------------------------------------------------------------


def _expect(statuses: list[str], about: str, goal: list[str] | None = None) -> Json:
    """The sidecar: acceptable statuses, what the request is about and, for a request with a goal, the
    acceptable ``diagnostics.goal.status``."""
    return {"statuses": statuses, "about": about, **({} if goal is None else {"goal": goal})}


#: name → (request builder, expectation)
GOLDEN: dict[str, tuple[Callable[[], Json], Json]] = {
    "demo": (demo, _expect([OK], "GET /v1/demo: the paper's U-turn with a cone at the corner")),
    "demo_coarse": (demo_coarse, _expect([OK], "the demo at dt 0.25 s over 6 s, candidates returned")),
    "u_turn_cone": (u_turn_cone, _expect([OK], "U-turn, inner side wider than the radius, cone at the apex")),
    "hairpin_turning_limit": (hairpin_turning_limit, _expect([OK], "5 m hairpin at max_curvature 0.2 1/m")),
    "s_curve_parked_cars": (s_curve_parked_cars, _expect([OK], "S-curve, parked cars on alternating sides")),
    "right_angle_corner": (right_angle_corner, _expect([OK], "90° corner on 3 m, tighter than the vehicle")),
    "blocked_road": (blocked_road, _expect([STOPPED], "a wall across the lane 35 m ahead")),
    "slow_leader": (slow_leader, _expect([OK], "a 3 m/s leader in a lane too narrow to pass")),
    "pedestrian": (pedestrian, _expect([OK, STOPPED], "a pedestrian crossing 25 m ahead")),
    "goal_past_parked_car": (
        goal_past_parked_car,
        _expect([OK], "stop in a goal past a car parked in a curve", goal=["reached"]),
    ),
    "goal_window": (
        goal_window,
        _expect(
            [OK], "in a goal region between 6 and 8 s: above the target, within the limit", goal=["reached"]
        ),
    ),
    "highway_420": (highway(420.0), _expect([OK], "coarse 2.3 km highway polyline, in a 1 km curve")),
    "highway_1300": (highway(1300.0), _expect([OK], "coarse 2.3 km highway polyline, in an 800 m curve")),
    **{
        f"cr_{name}": (commonroad(name), _expect([OK], "recorded CommonRoad request"))
        for name in (
            "BEL_Zaventem-1_2_T-1",
            "DEU_A9-3_1_T-1",
            "DEU_Moabit-4_1_T-1",
            "DEU_Test-1_1_T-1",
            "ITA_CarpiCentro-9_6_T-1",
            "PRI_Barceloneta-4_3_T-1",
            "USA_Peach-3_1_T-1",
            "ZAM_Tjunction-1_42_T-1",
        )
    },
    "cr_BEL_Aarschot-3_1_T-1": (
        commonroad("BEL_Aarschot-3_1_T-1"),
        _expect([STOPPED], "recorded CommonRoad request: the road is blocked a few metres ahead"),
    ),
    "cr_C-DEU_B471-1_3_T-1": (
        commonroad("C-DEU_B471-1_3_T-1"),
        _expect([STOPPED], "recorded CommonRoad request: a lane-wide obstacle 20 m ahead"),
    ),
    # Obstacle 17 comes from 64 m behind at 26 m/s against the ego's 14.7 m/s: with the target speed a
    # hard cap it cannot be escaped within the horizon; the answer keeps the speed (a typed fallback).
    "cr_DEU_LocationALower-28_1_S-1": (
        commonroad("DEU_LocationALower-28_1_S-1"),
        _expect([FALLBACK], "recorded CommonRoad request: a faster car from behind, not escapable"),
    ),
    # The two recorded scenes whose initial state cannot keep the limits (tests/planner/test_scenarios.py,
    # UNREACHABLE): claiming `ok` or `stopped` there would be wrong.
    "cr_HRV_Pula-27_3_T-1": (
        commonroad("HRV_Pula-27_3_T-1"),
        _expect([FALLBACK], "unreachable: 14.2 m/s into a bend that needs ~10 m/s² even braking at once"),
    ),
    "cr_ZAM_Over-1_1": (
        commonroad("ZAM_Over-1_1"),
        _expect([FALLBACK], "unreachable: 20 m/s with a lane-wide obstacle 20 m ahead"),
    ),
    # With the whole road (issue 14): the plan may borrow it; its footprint stays in the road
    "parked_truck_road": (parked_truck(), _expect([OK], "a lane-wide parked truck, passed through the road")),
    "parked_truck_oncoming": (
        parked_truck(oncoming=True),
        _expect([STOPPED], "a lane-wide parked truck and a car coming in the opposite lane: waits"),
    ),
    "cr_road_ZAM_Over-1_1": (
        commonroad("ZAM_Over-1_1", road=True),
        _expect([OK], "with the road: swerves round a lane-wide obstacle it cannot stop for from 20 m/s"),
    ),
    "cr_road_C-DEU_B471-1_3_T-1": (
        commonroad("C-DEU_B471-1_3_T-1", road=True),
        _expect([STOPPED], "with the road: waits for a car overtaking in the opposite lane"),
    ),
}


def build_all() -> dict[str, tuple[Json, Json]]:
    """Every golden request and its expectation, built now."""
    return {name: (build(), dict(expect)) for name, (build, expect) in GOLDEN.items()}


def dumps(data: Json) -> str:
    """The file text of a request or sidecar."""
    return json.dumps(data, indent=1, ensure_ascii=False) + "\n"


def same(a: Any, b: Any, *, rel: float = 1e-9, abs_: float = 1e-9) -> bool:
    """Whether two JSON values are equal, numbers up to rounding (last-bit differences of libm)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k], rel=rel, abs_=abs_) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same(x, y, rel=rel, abs_=abs_) for x, y in zip(a, b, strict=True))
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return math.isclose(a, b, rel_tol=rel, abs_tol=abs_)
    return bool(a == b)


def stale(built: dict[str, tuple[Json, Json]]) -> list[str]:
    """Names of files in ``requests/`` that differ from ``built``, are missing, or are left over."""
    out: list[str] = []
    wanted: set[str] = set()
    for name, (request, expect) in built.items():
        for path, data in ((REQUESTS / f"{name}.json", request), (REQUESTS / f"{name}.expect.json", expect)):
            wanted.add(path.name)
            if not path.exists() or not same(json.loads(path.read_text()), data):
                out.append(path.name)
    out += sorted(p.name for p in REQUESTS.glob("*.json") if p.name not in wanted)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only compare; exit 1 if a file differs")
    args = parser.parse_args(argv)
    built = build_all()
    if args.check:
        differ = stale(built)
        for name in differ:
            print(f"differs: {REQUESTS.name}/{name}")
        return 1 if differ else 0
    REQUESTS.mkdir(exist_ok=True)
    for leftover in (p for p in REQUESTS.glob("*.json") if p.stem.removesuffix(".expect") not in built):
        leftover.unlink()
    for name, (request, expect) in built.items():
        build = GOLDEN[name][0]
        if isinstance(build, _CopiedFile):
            shutil.copyfile(build.source, REQUESTS / f"{name}.json")
        else:
            (REQUESTS / f"{name}.json").write_text(dumps(request))
        (REQUESTS / f"{name}.expect.json").write_text(dumps(expect))
    print(f"wrote {len(built)} requests to {REQUESTS.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
