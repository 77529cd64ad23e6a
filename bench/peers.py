"""Side by side with CommonRoad's own tools: ``python bench/peers.py`` (asserts nothing; prints markdown
tables, also written to ``bench/results/peers.md``).

On the CommonRoad scenarios (the requests in ``tests/data/commonroad`` and, for the peers, the XML
files they were converted from, ``--xml-dir``, default ``../shared/scenarios/commonroad``):

* **planners** — our planner in closed loop (:func:`planner_tools.sim.simulate`, a plan every 0.1 s) and
  commonroad-reactive-planner (sampling Frenet planner, Werling et al.) in its own closed loop as its
  example ``run_planner.py`` does it (its route planner's reference path and its default configuration,
  re-planning every 0.1 s — ``replanning_frequency = 1`` — without multiprocessing), both for
  ``--cycles`` cycles or until the goal. A run succeeds when every cycle gave a trajectory: ours with
  status ``ok`` or ``stopped`` and no collision, the reactive planner a feasible one without raising.
* **projection** — ``--points`` points drawn uniformly in the road area of each request (between its
  lane edges) mapped to the Frenet frame of its reference line by our ``planner.frenet.to_frenet``
  (TransF-κ, defined on the whole plane) and by commonroad-clcs's ``CurvilinearCoordinateSystem``
  (default parameters: the reference resampled, projection domain at most 40 m), points per second and
  the points each refuses (CLCS: outside its unique projection domain; ours: a non-finite result).

The peers need commonroad-io < 2025 and commonroad-clcs, which pins osqp ~= 0.6 while this planner
needs osqp ≥ 1, so they live in their own virtual environment (``--peers-python``, default
``/work/peers-venv/bin/python``; make it with ``python -m venv /work/peers-venv &&
/work/peers-venv/bin/pip install commonroad-reactive-planner==2025.1 commonroad-clcs==2025.1.1``).
This script runs itself there as a worker (``--worker``) for the peers' half and says so when that
environment is missing, printing our half alone.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REQUESTS = ROOT / "tests" / "data" / "commonroad"
RESULTS = ROOT / "bench" / "results"
DEFAULT_XML = ROOT.parent / "shared" / "scenarios" / "commonroad"
DEFAULT_PEERS = Path("/work/peers-venv/bin/python")
REPLAN = 0.1

# bench/ itself must not be on the path: bench/commonroad.py would shadow the commonroad package
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]


# --------------------------------------------------------------------------------------------------
# The peers (run in their own environment; imports nothing from this repository)
# --------------------------------------------------------------------------------------------------


def _reactive(xml: str, cycles: int) -> dict[str, Any]:
    """commonroad-reactive-planner's closed loop on one scenario for at most ``cycles`` cycles."""
    from commonroad.common.file_reader import CommonRoadFileReader
    from commonroad_route_planner.reference_path_planner import ReferencePathPlanner
    from commonroad_route_planner.route_planner import RoutePlanner
    from commonroad_rp.reactive_planner import ReactivePlanner
    from commonroad_rp.utility.config import ReactivePlannerConfiguration
    from commonroad_rp.utility.utils_coordinate_system import create_coordinate_system

    times: list[float] = []
    done, error, goal = 0, "", False
    try:
        scenario, problems = CommonRoadFileReader(xml).open()
        problem = problems.planning_problem_dict[min(problems.planning_problem_dict)]
        config = ReactivePlannerConfiguration()
        config.debug.multiproc = False
        config.debug.logging_level = "ERROR"
        config.planning.replanning_frequency = 1
        config.update(scenario=scenario, planning_problem=problem)
        routes = RoutePlanner(scenario.lanelet_network, problem).plan_routes()
        path = ReferencePathPlanner(scenario.lanelet_network, problem, routes).plan_shortest_reference_path()
        planner = ReactivePlanner(config)
        planner.set_reference_path(coordinate_system=create_coordinate_system(path.reference_path))
        planner.record_state_and_input(planner.x_0)
        for _ in range(cycles):
            if planner.goal_reached():
                goal = True
                break
            planner.set_desired_velocity(current_speed=planner.x_0.velocity)
            t0 = time.perf_counter()
            optimal = planner.plan()
            times.append(time.perf_counter() - t0)
            if not optimal:
                error = "no feasible trajectory"
                break
            planner.record_state_and_input(optimal[0].state_list[1])
            planner.reset(
                initial_state_cart=planner.record_state_list[-1],
                initial_state_curv=(optimal[1][1], optimal[2][1]),
                collision_checker=planner.collision_checker,
                coordinate_system=planner.coordinate_system,
            )
            done += 1
    except Exception as exc:  # the peer's own failure is a result
        error = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"[:120]
    return {
        "cycles": done,
        "success": not error and (goal or done == cycles),
        "goal": goal,
        "error": error,
        "median_ms": 1e3 * statistics.median(times) if times else None,
    }


def _clcs(reference: list[list[float]], points_file: str) -> dict[str, Any]:
    """commonroad-clcs on a reference polyline: build time and the projection of the given points."""
    from commonroad_clcs.clcs import CurvilinearCoordinateSystem
    from commonroad_clcs.config import CLCSParams

    pts = np.load(points_file)
    try:
        t0 = time.perf_counter()
        cosy = CurvilinearCoordinateSystem(
            np.asarray(reference, dtype=float), CLCSParams(), preprocess_path=True
        )
        build = time.perf_counter() - t0
        t0 = time.perf_counter()
        out = cosy.convert_list_of_points_to_curvilinear_coords(list(pts), 1)
        elapsed = time.perf_counter() - t0
    except Exception as exc:
        return {"error": f"{type(exc).__name__}: {exc}"[:120]}
    return {
        "build_ms": 1e3 * build,
        "points_per_s": pts.shape[0] / elapsed,
        "refused": int(pts.shape[0] - len(out)),
        "points": int(pts.shape[0]),
    }


def worker(job_file: Path, out_file: Path) -> int:
    """The peers' half: every job of ``job_file``, answers to ``out_file`` (JSON)."""
    warnings.filterwarnings("ignore")
    jobs = json.loads(job_file.read_text())
    answers: dict[str, Any] = {}
    for job in jobs:
        ans: dict[str, Any] = {"clcs": _clcs(job["reference_line"], job["points_file"])}
        if job.get("xml"):
            ans["reactive"] = _reactive(job["xml"], job["cycles"])
        answers[job["name"]] = ans
        print(f"peers: {job['name']} done", file=sys.stderr, flush=True)
    out_file.write_text(json.dumps(answers))
    return 0


# --------------------------------------------------------------------------------------------------
# Our side
# --------------------------------------------------------------------------------------------------


def road_points(request: dict[str, Any], count: int, seed: int = 0) -> np.ndarray:
    """``count`` points drawn uniformly in the road area between the request's lane edges."""
    import shapely

    from planner.frenet import to_cartesian
    from planner.reference import build_reference, widths_at
    from planner_tools.io import problem_from_json

    problem = problem_from_json(request)
    ref = build_reference(problem.reference_line)
    left = widths_at(problem.lane.left_width, ref, ref.s, field_name="lane.left_width")
    right = widths_at(problem.lane.right_width, ref, ref.s, field_name="lane.right_width")
    # one quadrilateral per reference segment, so that edges folding back on a hairpin's inside stay valid
    le, re = to_cartesian(ref, ref.s, left), to_cartesian(ref, ref.s, -right)
    quads = np.stack((re[:-1], re[1:], le[1:], le[:-1]), axis=1)
    road = shapely.union_all(shapely.make_valid(shapely.polygons(quads)))
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(road.bounds[:2]), np.asarray(road.bounds[2:])
    out: list[np.ndarray] = []
    have = 0
    while have < count:
        cand = rng.uniform(lo, hi, size=(4 * count, 2))
        cand = cand[shapely.contains_xy(road, cand[:, 0], cand[:, 1])]
        out.append(cand)
        have += cand.shape[0]
    return np.vstack(out)[:count]


def ours(path: Path, cycles: int, points: np.ndarray) -> dict[str, Any]:
    from planner.frenet import to_frenet
    from planner.reference import build_reference
    from planner_tools.commonroad import load
    from planner_tools.io import problem_from_json
    from planner_tools.sim import Goal, simulate

    conv = load(path)
    problem = problem_from_json(conv.request)
    s_min = conv.goal.get("s_min")
    result = simulate(
        problem, duration=cycles * REPLAN, goal=None if s_min is None else Goal(s_min=float(s_min))
    )
    m = result.metrics
    ok = m.status_counts["ok"] + m.status_counts["stopped"]
    ref = build_reference(problem.reference_line)
    to_frenet(ref, points[:1000])  # warm-up
    t0 = time.perf_counter()
    fr = to_frenet(ref, points)
    elapsed = time.perf_counter() - t0
    refused = int(np.count_nonzero(~(np.isfinite(fr.s) & np.isfinite(fr.d))))
    return {
        "cycles": m.steps,
        "success": m.collisions == 0 and ok == m.steps,
        "goal": m.goal_reached,
        "status": m.status_counts,
        "collisions": m.collisions,
        "median_ms": m.planning_ms["median"],
        "points_per_s": points.shape[0] / elapsed,
        "refused": refused,
    }


def _fmt(v: float | None, spec: str) -> str:
    return "—" if v is None else format(v, spec)


def tables(names: list[str], our: dict[str, Any], peer: dict[str, Any] | None, note: str) -> str:
    lines = ["## Planners (closed loop, bounded cycles)", ""]
    lines.append(
        "| scenario | ours: success | ours: cycles (ok / stopped / fallback / error) | ours: median [ms] "
        "| reactive: success | reactive: cycles | reactive: median [ms] | reactive: failure |"
    )
    lines.append("|" + "---|" * 8)
    for n in names:
        o = our[n]
        st = o["status"]
        r = (peer or {}).get(n, {}).get("reactive")
        lines.append(
            f"| {n} | {'yes' if o['success'] else 'no'} | {o['cycles']} ({st['ok']} / {st['stopped']} / "
            f"{st['fallback']} / {st['error']}) | {o['median_ms']:.0f} | "
            + (
                "— | — | — | " + note
                if r is None
                else f"{'yes' if r['success'] else 'no'} | {r['cycles']} | {_fmt(r['median_ms'], '.0f')} "
                f"| {r['error'] or ('goal' if r['goal'] else '')}"
            )
            + " |"
        )
    so = sum(our[n]["success"] for n in names)
    med_o = statistics.median(our[n]["median_ms"] for n in names)
    summary = f"\nOurs: {so}/{len(names)} succeeded, median of medians {med_o:.0f} ms per cycle."
    if peer:
        rs = [peer[n]["reactive"] for n in names if "reactive" in peer.get(n, {})]
        meds = [r["median_ms"] for r in rs if r["median_ms"] is not None]
        summary += (
            f" Reactive planner: {sum(r['success'] for r in rs)}/{len(rs)} succeeded, median of medians "
            f"{statistics.median(meds):.0f} ms per cycle."
            if meds
            else ""
        )
    lines.append(summary)
    lines += ["", "## Projection (points drawn uniformly in the road area)", ""]
    lines.append("| scenario | points | ours [points/s] | ours refused | CLCS [points/s] | CLCS refused |")
    lines.append("|" + "---|" * 6)
    for n in names:
        o = our[n]
        c = (peer or {}).get(n, {}).get("clcs")
        if c is None or "error" in c:
            cl = f"— | {note if c is None else c['error']}"
        else:
            cl = f"{c['points_per_s']:,.0f} | {c['refused']} ({100 * c['refused'] / c['points']:.1f} %)"
        lines.append(f"| {n} | {o['points']} | {o['points_per_s']:,.0f} | {o['refused']} | {cl} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--cycles", type=int, default=20, help="planning cycles per scenario and planner")
    parser.add_argument("--points", type=int, default=100_000, help="points projected per scenario")
    parser.add_argument(
        "--xml-dir", type=Path, default=DEFAULT_XML, help="the scenarios' CommonRoad XML files"
    )
    parser.add_argument("--peers-python", type=Path, default=DEFAULT_PEERS, help="the peers' interpreter")
    parser.add_argument("--only", nargs="*", default=None, help="scenario names to run")
    parser.add_argument("--out", type=Path, default=RESULTS / "peers.md", help="markdown output")
    parser.add_argument("--worker", nargs=2, type=Path, metavar=("JOBS", "OUT"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.worker:
        return worker(*args.worker)

    sys.path.insert(0, str(ROOT))
    paths = sorted(p for p in REQUESTS.glob("*.json") if p.name != "index.json")
    if args.only:
        paths = [p for p in paths if p.stem in set(args.only)]
    names = [p.stem for p in paths]
    t_start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        jobs, our = [], {}
        for p in paths:
            request = json.loads(p.read_text())
            pts = road_points(request, args.points)
            np.save(Path(tmp) / f"{p.stem}.npy", pts)
            xml = args.xml_dir / f"{p.stem}.xml"
            jobs.append(
                {
                    "name": p.stem,
                    "reference_line": request["reference_line"],
                    "points_file": str(Path(tmp) / f"{p.stem}.npy"),
                    "xml": str(xml) if xml.exists() else None,
                    "cycles": args.cycles,
                }
            )
            our[p.stem] = {**ours(p, args.cycles, pts), "points": int(pts.shape[0])}
            print(f"ours: {p.stem} done", file=sys.stderr, flush=True)
        peer: dict[str, Any] | None = None
        note = ""
        if not args.peers_python.exists():
            note = f"peers not run: no interpreter at {args.peers_python}"
        else:
            (Path(tmp) / "jobs.json").write_text(json.dumps(jobs))
            proc = subprocess.run(
                [
                    str(args.peers_python),
                    __file__,
                    "--worker",
                    str(Path(tmp) / "jobs.json"),
                    str(Path(tmp) / "peers.json"),
                ],
                stdout=subprocess.DEVNULL,
                stderr=None,
                check=False,
                env={**os.environ, "PYTHONWARNINGS": "ignore"},
            )
            if (Path(tmp) / "peers.json").exists():
                peer = json.loads((Path(tmp) / "peers.json").read_text())
            else:
                note = (
                    f"peers failed (exit {proc.returncode}); is commonroad-reactive-planner installed there?"
                )
    total = time.perf_counter() - t_start
    if note:
        print(note, file=sys.stderr)
    text = tables(names, our, peer, note or "not run")
    header = (
        f"# Side by side: commonroad-reactive-planner and commonroad-clcs\n\n"
        f"`python bench/peers.py --cycles {args.cycles} --points {args.points}`: {len(names)} scenarios, "
        f"{total:.0f} s wall on {os.cpu_count()} cores (load from other processes inflates times).\n\n"
    )
    print(text)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(header + text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
