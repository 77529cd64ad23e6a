"""How early could the vehicle be in each CommonRoad goal region at all? ``python bench/goal_reach.py``
prints, per scene with a goal region and a time window, the earliest time the footprint's centre can
reach the region along the reference within the vehicle's limits and the request's speed limit
(:func:`planner_tools.reach.reach`: no jerk limit, no margin; *lateral only* without the steering rate's
limit), next to the window; ``late`` where even that arrives after the window closes: no speed profile
along the reference gets there in time (asserts nothing).

Scenes as ``bench/commonroad.py`` loads them (``--only``, ``--vehicle``, ``--road`` alike).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# bench/ itself must not be on the path: commonroad.py here would shadow the commonroad package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner_tools.evaluate import VEHICLES, Settings, prepare  # noqa: E402 (after the path fix)
from planner_tools.reach import reach  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
REQUESTS = ROOT / "tests" / "data" / "commonroad"
ROAD_REQUESTS = ROOT / "tests" / "data" / "commonroad-road"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="*", default=None, help="scenario names (file stems) to run")
    parser.add_argument("--vehicle", choices=VEHICLES, default="car", help="as bench/commonroad.py's")
    parser.add_argument("--road", action="store_true", help="the requests with the whole road")
    args = parser.parse_args(argv)
    folder = ROAD_REQUESTS if args.road else REQUESTS
    paths = sorted(p for p in folder.glob("*.json") if p.name != "index.json")
    if args.only:
        paths = [p for p in paths if p.stem in set(args.only)]
    print(
        "| scenario | region ahead [m] | window [s] | speed limit [m/s] | earliest arrival [s] "
        "| lateral only [s] | verdict |\n|---|---|---|---|---|---|---|"
    )
    for path in paths:
        prepared = prepare(path, Settings(vehicle=args.vehicle))
        bound = reach(prepared.problem)
        if bound is None:
            continue
        verdict = "late" if bound.earliest > bound.t_max else "in time"
        print(
            f"| {path.stem} | {bound.ahead:.1f} | {bound.t_min:.1f}–{bound.t_max:.1f} "
            f"| {prepared.problem.options.speed_limit} | {bound.earliest:.2f} | {bound.lateral_only:.2f} "
            f"| {verdict} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
