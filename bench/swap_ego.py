"""More recorded scenes from the same recordings: ``python bench/swap_ego.py OUT_DIR`` writes, for each
shared CommonRoad scenario, new scenarios in which one of its recorded cars becomes the ego (removed from
the traffic; the planning problem starts from its first recorded state and asks for the place it reached
within a time window around when it reached it). Then ``python bench/commonroad.py --xml OUT_DIR`` drives
them: scenes no test here was tuned on, with traffic that reacted to the recorded car, not to us (a
follower that was behind it keeps coming).

Picked: cars (and trucks, buses) recorded at least ``--min-seconds`` (default 8 s), moving at least
``--min-distance`` (default 30 m), at most ``--per-scene`` (default 3) per scenario, the longest first.
Goal: a rectangle 10 m long and 4 m wide along the car's last heading, centred on its last recorded centre,
time window from 2 s before to 4 s after its last recorded step (``--slack``).

Asserts nothing; prints what it wrote.
"""

from __future__ import annotations

import argparse
import copy
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner_tools.commonroad import read_scenario, scenario_name  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ROOT / "tests" / "data" / "commonroad"
VEHICLES = {"car", "truck", "bus", "priorityVehicle"}


def _point(position: object) -> np.ndarray | None:
    """A recorded position as ``[x, y]``; None for an uncertain one (a shape)."""
    try:
        xy = np.asarray(position, dtype=float)
    except (TypeError, ValueError):
        return None
    return xy if xy.shape == (2,) else None


def _candidates(scenario: Any, min_steps: int, min_distance: float) -> list[tuple[int, Any]]:
    """``(steps recorded, obstacle)`` for the dynamic obstacles worth driving, the longest first."""
    out = []
    for ob in scenario.dynamic_obstacles:
        if ob.obstacle_type.value not in VEHICLES:
            continue
        states = ob.prediction.trajectory.state_list if hasattr(ob.prediction, "trajectory") else []
        if len(states) < min_steps:
            continue
        first, last = _point(ob.initial_state.position), _point(states[-1].position)
        if first is None or last is None or float(np.hypot(*(last - first))) < min_distance:
            continue
        out.append((len(states), ob))
    return sorted(out, key=lambda item: -item[0])


def swapped(scenario: Any, obstacle: Any, slack: tuple[float, float]) -> tuple[Any, Any]:
    """``(scenario, planning problem set)``: ``scenario`` without ``obstacle``, which becomes the ego."""
    import shapely
    from commonroad.common.util import Interval
    from commonroad.geometry.occupancy.rect_occupancy import RectOccupancy
    from commonroad.planning.goal import GoalRegion
    from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
    from commonroad.scenario.state import CustomState, InitialState

    new = copy.deepcopy(scenario)
    new.remove_obstacle(new.obstacle_by_id(obstacle.obstacle_id))
    dt = float(new.dt)
    init = obstacle.initial_state
    last = obstacle.prediction.trajectory.state_list[-1]
    start = InitialState(
        time_step=int(init.time_step),
        position=np.asarray(init.position, dtype=float),
        orientation=float(init.orientation),
        velocity=float(getattr(init, "velocity", 0.0) or 0.0),
        acceleration=0.0,
        yaw_rate=0.0,
        slip_angle=0.0,
    )
    target = CustomState(
        position=RectOccupancy(
            rect_center=shapely.Point(*np.asarray(last.position, dtype=float)),
            width=4.0,
            length=10.0,
            orientation=float(last.orientation),
        ),
        time_step=Interval(
            max(int(init.time_step) + 1, int(last.time_step) - round(slack[0] / dt)),
            int(last.time_step) + round(slack[1] / dt),
        ),
    )
    problem = PlanningProblem(int(obstacle.obstacle_id), start, GoalRegion([target]))
    return new, PlanningProblemSet([problem])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path, help="folder for the new scenarios (created)")
    parser.add_argument("sources", nargs="*", type=Path, help=f"scenarios (default: {SOURCES})")
    parser.add_argument("--min-seconds", type=float, default=8.0)
    parser.add_argument("--min-distance", type=float, default=30.0)
    parser.add_argument("--per-scene", type=int, default=3)
    parser.add_argument("--slack", type=float, nargs=2, default=(2.0, 4.0), metavar=("BEFORE", "AFTER"))
    args = parser.parse_args(argv)
    from commonroad.common.file_writer import CommonRoadFileWriter, OverwriteExistingFile
    from commonroad.common.util import FileFormat

    sources = args.sources or sorted(p for p in SOURCES.iterdir() if p.name.endswith((".xml", ".xml.gz")))
    args.out.mkdir(parents=True, exist_ok=True)
    written = 0
    for path in sources:
        scenario, _ = read_scenario(path)
        dt = float(scenario.dt)
        picked = _candidates(scenario, round(args.min_seconds / dt), args.min_distance)[: args.per_scene]
        for _, obstacle in picked:
            new, problems = swapped(scenario, obstacle, tuple(args.slack))
            out = args.out / f"{scenario_name(path)}-ego{obstacle.obstacle_id}.xml"
            CommonRoadFileWriter(
                new,
                problems,
                "kappa-planner bench/swap_ego.py",
                "",
                "recorded car as ego",
                set(),
                file_format=FileFormat.XML,
            ).write_to_file(str(out), OverwriteExistingFile.ALWAYS)
            written += 1
            print(out.name)
    print(f"{written} scenarios in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
