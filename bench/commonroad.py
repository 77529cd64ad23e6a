"""Closed loop on real roads: ``python bench/commonroad.py`` drives every CommonRoad scene in one process
and prints a markdown table (asserts nothing; also written to ``bench/results/commonroad.md``).

Scenes: the planning requests ``tests/data/commonroad/*.json`` (converted from the CommonRoad benchmark by
the shared reference converter), each judged against the scenario's XML beside it (``X.xml`` or
``X.xml.gz``); with ``--xml DIR`` the CommonRoad XML files of ``DIR`` (``*.xml``, ``*.xml.gz``) converted
by :mod:`planner_tools.commonroad`. Each scene is prepared, driven and judged by
:func:`planner_tools.evaluate.run_scene` — the same code as ``kappa-planner commonroad`` and
``kappa-planner evaluate`` (on Ray): the request carries the scenario's goal and speed limit; the run
(a replan every 0.1 s) ends at CommonRoad's goal, a collision, the goal's time window's end or
``--duration`` simulated seconds (default 35 s); CommonRoad's goal check, the drivability checker's
collision checker (rear-end collisions by traffic from behind apart) and its kinematic single-track
feasibility check judge it; success = goal ∧ no collision ∧ feasible. See :mod:`planner_tools.evaluate`
and :mod:`planner_tools.crjudge` for the details, ``planner_tools.evaluate.COLUMNS`` for the columns.

``--road``: the same requests with the whole road beyond the lane (``tests/data/commonroad-road``, from
the shared scenarios' ``requests-road``), so that plans may borrow it (issue 14); XML conversions carry
the road of their lanelet network always.

Vehicle (``--vehicle``): ``car`` (default), the scenario's vehicle, CommonRoad's vehicle type 2 (BMW 320i:
wheelbase, rear axle, steering limits) planned as a car; ``point``, the same footprint as the point model;
``request``, the request's own (the point model for the shared requests).

:func:`scene_paths` and :func:`load_scene` are what other benches reuse to load the same scenes.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

# bench/ itself must not be on the path: this file would shadow the commonroad package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner_tools.evaluate import (  # noqa: E402 (after the path fix)
    DURATION,
    VEHICLES,
    Outcome,
    Prepared,
    Settings,
    find_scenes,
    prepare,
    run_scene,
    table,
    write_csv,
)
from planner_tools.sim import SimResult  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
REQUESTS = ROOT / "tests" / "data" / "commonroad"
#: the same requests with the whole road beyond the lane (``road``); their XML links to REQUESTS' own
ROAD_REQUESTS = ROOT / "tests" / "data" / "commonroad-road"
RESULTS = ROOT / "bench" / "results"


@dataclass(frozen=True)
class Row:
    """One scene: its name, the run, its row (:class:`planner_tools.evaluate.Outcome`), the goal's arc
    length [m] (None: none), the scene's wall time [s]."""

    name: str
    result: SimResult | None
    outcome: Outcome
    goal_s: float | None
    wall_s: float


def scene_paths(xml: Path | None = None, only: list[str] | None = None, road: bool = False) -> list[Path]:
    """The scenes: the request JSONs of ``tests/data/commonroad`` (with ``road``, those of
    ``tests/data/commonroad-road``, which carry the whole road) or the XML files of ``xml``, those named
    in ``only`` (file stems) if given."""
    if xml is None:
        folder = ROAD_REQUESTS if road else REQUESTS
        paths = sorted(p for p in folder.glob("*.json") if p.name != "index.json")
    else:
        paths = [p for p in find_scenes([xml]) if not p.name.endswith(".json")]
    if only:
        paths = [p for p in paths if p.name.split(".")[0] in set(only)]
    return paths


def load_scene(path: Path, vehicle: str = "car", duration: float = DURATION) -> Prepared:
    """A scene ready to run (:func:`planner_tools.evaluate.prepare`): its problem (with the scenario's goal
    and speed limit), the simulator's goal, the duration."""
    return prepare(path, Settings(vehicle=vehicle, duration=duration))


def run_one(path: Path, duration: float = DURATION, vehicle: str = "car") -> Row:
    """Drive and judge one scene in this process."""
    run = run_scene(path, Settings(vehicle=vehicle, duration=duration), keep=True)
    goal_s = None if run.prepared is None else run.prepared.goal_s
    return Row(path.name, run.result, run.outcome, goal_s, run.outcome.wall_s or 0.0)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=DURATION, help="simulated seconds per scene, most")
    parser.add_argument(
        "--xml", type=Path, default=None, help="the CommonRoad XML files in DIR instead of the requests"
    )
    parser.add_argument("--only", nargs="*", default=None, help="scenario names (file stems) to run")
    parser.add_argument("--out", type=Path, default=None, help="markdown file (default bench/results/…)")
    parser.add_argument("--csv", type=Path, default=None, help="also write the rows as results.csv here")
    parser.add_argument("--vehicle", choices=VEHICLES, default="car", help="see the module docstring")
    parser.add_argument(
        "--road", action="store_true", help="the requests with the whole road (tests/data/commonroad-road)"
    )
    args = parser.parse_args(argv)

    paths = scene_paths(args.xml, args.only, args.road)
    if args.xml is None:
        folder = ROAD_REQUESTS if args.road else REQUESTS
        source = f"requests in {folder.relative_to(ROOT)}, judged against the XML beside each"
        name = "commonroad" if args.vehicle == "point" else "commonroad_car"
        default_out = RESULTS / f"{name}{'_road' if args.road else ''}.md"
    else:
        source = f"CommonRoad XML in {args.xml}, converted by planner_tools.commonroad"
        default_out = RESULTS / "commonroad_xml.md"
    out = args.out or default_out
    rows: list[Row] = []
    t0 = time.perf_counter()
    for path in paths:
        row = run_one(path, args.duration, args.vehicle)
        o = row.outcome
        print(
            f"{row.name}: {o.status} {o.error} {o.termination} after {o.sim_time_s or 0:.1f} s sim, "
            f"{o.cycles or 0} steps, {row.wall_s:.1f} s wall",
            file=sys.stderr,
        )
        rows.append(row)
    total = time.perf_counter() - t0
    outcomes = [r.outcome for r in rows]
    text = table(outcomes)
    try:
        load = " / ".join(f"{v:.2f}" for v in os.getloadavg())
    except OSError:
        load = "—"
    header = (
        f"# Closed loop on CommonRoad scenarios\n\n"
        f"`python bench/commonroad.py{' '.join(['', *(argv if argv is not None else sys.argv[1:])])}`: "
        f"{source}; vehicle: {args.vehicle}; replan every 0.1 s, at most {args.duration:g} s simulated per "
        f"scene; {total:.0f} s wall on {os.cpu_count()} cores, load average {load} at the end.\n\n"
    )
    print(text)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(header + text + "\n")
    if args.csv is not None:
        write_csv(outcomes, args.csv)
    print(f"\nwrote {out} ({total:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
