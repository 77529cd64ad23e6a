"""More recorded scenes from the same recordings: ``python bench/swap_ego.py OUT_DIR`` writes, for each
shared CommonRoad scenario, new scenarios in which one of its recorded cars becomes the ego
(:func:`planner_tools.commonroad.recorded_as_ego`: removed from the traffic; the planning problem starts
from its first recorded state and asks for the place its recording ends, 10 m × 4 m, from ``--slack``
seconds before to after that end). Then ``python bench/commonroad.py --xml OUT_DIR`` drives them: scenes
no test here was tuned on, with traffic that reacted to the recorded car, not to us (a follower that was
behind it keeps coming).

Picked (:func:`planner_tools.commonroad.recorded_cars`): cars, trucks and buses recorded at least
``--min-seconds`` (default 8 s) whose recording ends at least ``--min-distance`` (default 30 m) from where
it starts, at most ``--per-scene`` (default 3) per scenario, the longest recorded first.

Asserts nothing; prints what it wrote.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

# bench/ itself must not be on the path: bench/commonroad.py would shadow the commonroad package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner_tools.commonroad import (  # noqa: E402 (after the path fix)
    read_scenario,
    recorded_as_ego,
    recorded_cars,
    scenario_name,
    write_scenario,
)

ROOT = Path(__file__).resolve().parents[1]
SOURCES = ROOT / "tests" / "data" / "commonroad"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path, help="folder for the new scenarios (created)")
    parser.add_argument("sources", nargs="*", type=Path, help=f"scenarios (default: {SOURCES})")
    parser.add_argument("--min-seconds", type=float, default=8.0)
    parser.add_argument("--min-distance", type=float, default=30.0)
    parser.add_argument("--per-scene", type=int, default=3)
    parser.add_argument("--slack", type=float, nargs=2, default=(2.0, 4.0), metavar=("BEFORE", "AFTER"))
    args = parser.parse_args(argv)
    sources = args.sources or sorted(p for p in SOURCES.iterdir() if p.name.endswith((".xml", ".xml.gz")))
    written = 0
    for path in sources:
        scenario, _ = read_scenario(path)
        steps = round(args.min_seconds / float(scenario.dt))
        for car in recorded_cars(scenario, steps, args.min_distance)[: args.per_scene]:
            new, problems = recorded_as_ego(scenario, car.obstacle_id, tuple(args.slack))
            out = args.out / f"{scenario_name(path)}-ego{car.obstacle_id}.xml"
            write_scenario(out, new, problems, "kappa-planner bench/swap_ego.py")
            written += 1
            print(out.name)
    print(f"{written} scenarios in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
