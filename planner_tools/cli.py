"""Command line: ``kappa-planner simulate | compare | demo | commonroad | evaluate`` — closed-loop runs,
drawn and judged.

* ``kappa-planner simulate ROAD.json --out DIR [--generator naive|transf_kappa]`` drives the planning
  request in ``ROAD.json`` (the body of ``POST /v1/plan``, e.g. from ``GET /v1/demo`` or
  ``tests/data/commonroad/*.json``) in closed loop (:func:`planner_tools.sim.simulate`) and writes a PNG
  per key frame (every ``--frame-every`` seconds and the last), ``sim.gif``, ``steps.csv``,
  ``metrics.json`` and ``run.json.gz``, the run file ``/viewer`` plays back (:mod:`planner_tools.runfile`).
* ``kappa-planner compare ROAD.json --out DIR`` runs both generators and draws them side by side like
  Fig. 4 of the paper (``compare.png``: road, obstacles, driven paths, candidate fans at four points
  along the road, a metrics table; ``compare.gif``), with ``metrics.json`` for both and a run file
  per generator (``run_naive.json.gz``, ``run_transf_kappa.json.gz``).
* ``kappa-planner demo --out DIR`` is ``compare`` on the built-in demo U-turn.
* ``--wheelbase W --rear-axle-offset L_R`` (and ``--max-steering-angle``, ``--max-steering-rate``) make
  the vehicle of ``simulate``, ``compare`` and ``demo`` a car: planned and driven at its rear axle.
* ``kappa-planner commonroad SCENARIO [--out DIR]`` prepares a scene (:func:`planner_tools.evaluate.prepare`:
  a CommonRoad XML converted by :mod:`planner_tools.commonroad`, or a request JSON, judged against the
  XML beside it; the scenario's goal and speed limit in the request), drives it and judges it as
  ``bench/commonroad.py`` does; ``--out`` adds ``request.json``, ``conversion.json``, ``results.csv`` and
  the files of ``simulate``; ``--solution OUT.xml`` writes the driven trajectory as a CommonRoad solution
  (XML scenarios); ``--vehicle car|point|request``: CommonRoad's vehicle type 2 car (default), the same
  footprint as the point model, or the request's own.
* ``kappa-planner evaluate SCENARIO... --out DIR`` runs many scenes on Ray (:mod:`planner_tools.scale`):
  ``DIR/results.csv``, ``DIR/summary.md``.

The request is read by :func:`planner_tools.io.problem_from_json` (no pydantic, no ``app`` import: the
command line is a client of the planner like the HTTP layer). Drawing (:mod:`planner_tools.render`) and
progress bars need the optional extra ``tools``; without it every command says how to install it.
Exit status: 0 on success (whatever the run's outcome), 2 for an unreadable or invalid request or a
missing extra.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from planner.errors import PlannerError
from planner.problem import CAR_FIELDS, Generator, PlanningProblem
from planner.roads import demo_problem
from planner_tools.commonroad import CommonRoadError, write_solution
from planner_tools.evaluate import DURATION, VEHICLES, Settings, judge_run, prepare, table, totals, write_csv
from planner_tools.extras import COMMONROAD, SCALE, TOOLS, MissingExtraError
from planner_tools.io import problem_from_json
from planner_tools.records import run_record, summary, write_json, write_steps_csv
from planner_tools.runfile import write_run
from planner_tools.sim import BicycleModel, Goal, SimResult, simulate

GENERATORS: tuple[Generator, ...] = ("naive", "transf_kappa")


# --------------------------------------------------------------------------------------------------
# Commands (render and tqdm come from the extra `tools`, which main checks before any command runs)
# --------------------------------------------------------------------------------------------------


def _load(path: Path) -> PlanningProblem:
    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise PlannerError(f"cannot read {path}: {exc.strerror or exc}") from exc
    except json.JSONDecodeError as exc:
        raise PlannerError(f"{path} is not JSON: {exc}") from exc
    return problem_from_json(data)


def _quiet(args: argparse.Namespace) -> bool:
    """No progress bars: asked for, or nobody watches stderr."""
    return bool(args.quiet) or not sys.stderr.isatty()


def _car(problem: PlanningProblem, args: argparse.Namespace) -> PlanningProblem:
    """``problem`` with the car of ``--wheelbase``, ``--rear-axle-offset``, … (the vehicle as is
    without ``--wheelbase``)."""
    fields: dict[str, Any] = {name: getattr(args, name, None) for name in CAR_FIELDS}
    if fields["wheelbase"] is None:
        given = [name for name, value in fields.items() if value is not None]
        if given:
            raise PlannerError(f"--{given[0].replace('_', '-')} needs --wheelbase")
        return problem
    return replace(problem, vehicle=replace(problem.vehicle, **fields))


def _run(
    problem: PlanningProblem,
    generator: Generator,
    args: argparse.Namespace,
    *,
    goal: Goal | None = None,
    duration: float | None = None,
    leaves: dict[str, float] | None = None,
) -> SimResult:
    """A closed loop of ``problem`` (the car of ``--wheelbase``, … when given) with ``generator``, to
    ``goal`` (default: ``--goal-s``, else the simulator's) for ``duration`` (default ``--duration``)."""
    from tqdm import tqdm

    problem = _car(problem, args)
    problem = replace(problem, options=replace(problem.options, generator=generator))
    model = BicycleModel.for_vehicle(problem.vehicle, centre_midway=args.centre_midway)
    if goal is None and args.goal_s is not None:
        goal = Goal(s_min=args.goal_s)
    with tqdm(total=1, desc=generator, unit="cycle", disable=_quiet(args)) as bar:

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        return simulate(
            problem,
            duration=args.duration if duration is None else duration,
            replan_period=args.replan_period,
            goal=goal,
            progress=progress,
            model=model,
            leaves=leaves,
        )


def _write_run(result: SimResult, out: Path, args: argparse.Namespace, source: dict[str, Any]) -> list[Path]:
    """Key frames, ``sim.gif`` (unless ``--no-gif``), ``steps.csv``, ``metrics.json`` (``source``
    first) and the run file ``run.json.gz`` of one run in ``out``; returns the key frames."""
    from planner_tools import render

    frames = render.write_key_frames(result, out, every=args.frame_every)
    if not args.no_gif:
        render.write_gif(
            [result], out / "sim.gif", stride=args.gif_stride, dpi=args.gif_dpi, quiet=_quiet(args)
        )
    write_steps_csv(result, out / "steps.csv")
    write_json({**source, **run_record(result)}, out / "metrics.json")
    write_run(result, out / "run.json.gz", source)
    return frames


def _cmd_simulate(args: argparse.Namespace) -> int:
    problem = _load(args.road)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    result = _run(problem, args.generator or problem.options.generator, args)
    frames = _write_run(result, out, args, {"road": str(args.road)})
    print(summary([result]))
    print(
        f"wrote {len(frames)} frames, {'' if args.no_gif else 'sim.gif, '}steps.csv, metrics.json, "
        f"run.json.gz (open /viewer and drop it) to {out}"
    )
    return 0


def _compare(problem: PlanningProblem, road: str, args: argparse.Namespace) -> int:
    from planner_tools import render

    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    results = [_run(problem, g, args) for g in GENERATORS]
    render.write_compare(results, out / "compare.png")
    if not args.no_gif:
        render.write_gif(
            results, out / "compare.gif", stride=args.gif_stride, dpi=args.gif_dpi, quiet=_quiet(args)
        )
    for r in results:
        write_steps_csv(r, out / f"steps_{r.problem.options.generator}.csv")
        write_run(r, out / f"run_{r.problem.options.generator}.json.gz", {"road": road})
    write_json(
        {"road": road, "runs": {r.problem.options.generator: run_record(r) for r in results}},
        out / "metrics.json",
    )
    print(summary(results))
    print(
        f"wrote compare.png, {'' if args.no_gif else 'compare.gif, '}steps_*.csv, metrics.json, "
        f"run_*.json.gz (open /viewer and drop one) to {out}"
    )
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    return _compare(_load(args.road), str(args.road), args)


def _cmd_demo(args: argparse.Namespace) -> int:
    return _compare(demo_problem(), "built-in demo U-turn (planner.roads.demo_problem)", args)


def _cmd_commonroad(args: argparse.Namespace) -> int:
    settings = Settings(
        vehicle=args.vehicle, duration=args.duration or DURATION, replan_period=args.replan_period
    )
    try:
        prepared = prepare(args.scenario, settings, planning_problem_id=args.planning_problem)
        conv = prepared.conversion
        if args.solution is not None and "scenario_id" not in conv.info:
            raise CommonRoadError(f"--solution needs a CommonRoad XML scenario, not {args.scenario}")
    except (CommonRoadError, OSError, ValueError) as exc:
        raise PlannerError(str(exc)) from exc
    goal = None if args.goal_s is not None else prepared.goal
    t0 = time.perf_counter()
    result = _run(
        prepared.problem, args.generator or prepared.problem.options.generator, args, goal=goal,
        duration=prepared.duration, leaves=prepared.leaves,
    )  # fmt: skip
    try:
        outcome = judge_run(prepared, result, settings, time.perf_counter() - t0)
    except CommonRoadError as exc:
        raise PlannerError(str(exc)) from exc
    judged = "CommonRoad's checkers" if prepared.judge is not None else "the simulator (no XML beside it)"
    print(f"{conv.name}: {len(conv.request['obstacles'])} obstacles, judged by {judged}")
    print(summary([result]))
    print(table([outcome]))
    out: Path | None = args.out
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "request.json").write_text(json.dumps(prepared.request) + "\n")
        (out / "conversion.json").write_text(
            json.dumps({"name": conv.name, "goal": conv.goal, "info": conv.info}, indent=1) + "\n"
        )
        write_csv([outcome], out / "results.csv")
        _write_run(result, out, args, {"scenario": str(args.scenario)})
        print(
            f"wrote request.json, conversion.json, results.csv, key frames, "
            f"{'' if args.no_gif else 'sim.gif, '}steps.csv, metrics.json, run.json.gz to {out}"
        )
    if args.solution is not None:
        try:
            written = write_solution(args.solution, conv, result.motion)
        except CommonRoadError as exc:
            raise PlannerError(str(exc)) from exc
        print(f"wrote the driven trajectory as a CommonRoad solution (KS, vehicle type 2) to {written}")
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from planner_tools.scale import evaluate

    settings = Settings(vehicle=args.vehicle, duration=args.duration, gif=args.gifs)
    try:
        report = evaluate(
            args.scenarios, args.out, settings, workers=args.workers, address=args.address,
            timeout=args.timeout, force=args.force, quiet=args.quiet,
        )  # fmt: skip
    except CommonRoadError as exc:
        raise PlannerError(str(exc)) from exc
    failed = sum(o.status != "done" for o in report.ran)
    print(totals(report.outcomes))
    print(
        f"ran {len(report.ran)} scenes ({failed} failed), kept {report.skipped}; Ray start-up "
        f"{report.startup_s:.1f} s, scenes {report.wall_s:.1f} s on {report.workers} worker(s); "
        f"wrote results.csv, summary.md{', gifs/' if args.gifs else ''} to {args.out}"
    )
    return 0


# --------------------------------------------------------------------------------------------------
# Parser
# --------------------------------------------------------------------------------------------------


def _positive(text: str) -> float:
    value = float(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"must be positive: {text}")
    return value


def _add_timing(p: argparse.ArgumentParser) -> None:
    p.add_argument("--duration", type=_positive, default=None, help="longest simulated time [s]")
    p.add_argument("--replan-period", type=_positive, default=0.1, help="time between plans [s]")


def _add_gif(p: argparse.ArgumentParser) -> None:
    p.add_argument("--no-gif", action="store_true", help="skip the animation")
    p.add_argument("--gif-stride", type=int, default=2, help="a GIF frame every N cycles")
    p.add_argument("--gif-dpi", type=int, default=100, help="GIF resolution [px/inch]")


def _add_vehicle(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--vehicle",
        choices=VEHICLES,
        default="car",
        help="the scenario's vehicle, CommonRoad's vehicle type 2 (BMW 320i) as a car (default); the "
        "same footprint as the point model (point, no wheelbase); or the request's own (request)",
    )


def _add_evaluate(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "evaluate",
        help="drive and judge many scenes in parallel on Ray (here or on a cluster)",
        description="Drive every scene in closed loop, one Ray task each, and judge it as "
        "bench/commonroad.py does (CommonRoad's goal check, collision checker and feasibility against "
        "the scenario's XML). "
        "Writes DIR/results.csv (a row per scene) and DIR/summary.md (totals and the table); rerun with "
        f"the same DIR to skip the scenes done. Needs Ray ({SCALE.hint}) and, for XML, commonroad-io "
        f"({COMMONROAD.hint}).",
    )
    p.add_argument(
        "scenarios",
        nargs="+",
        type=Path,
        help="CommonRoad XML (.xml, .xml.gz) or planning request JSON files, or folders of them",
    )
    p.add_argument("--out", type=Path, required=True, help="output folder DIR (created)")
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="local Ray: worker processes (default: the CPUs available); with --address: at most this "
        "many scenes at once (default: the cluster's CPUs)",
    )
    p.add_argument(
        "--address",
        default=None,
        help="a running Ray cluster (ray start --head; default: $RAY_ADDRESS, else a local Ray)",
    )
    p.add_argument(
        "--timeout", type=_positive, default=900.0, help="seconds a scene may run before it is cancelled"
    )
    p.add_argument("--force", action="store_true", help="run every scene again, even those done in DIR")
    p.add_argument("--gifs", action="store_true", help="an animation per scene in DIR/gifs/")
    p.add_argument(
        "--duration", type=_positive, default=DURATION, help="longest simulated time per scene [s]"
    )
    _add_vehicle(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_evaluate)


def _add_commonroad(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "commonroad",
        help="drive a CommonRoad scenario in closed loop and judge it by CommonRoad's checkers",
        description="Convert a CommonRoad scenario (XML, .xml.gz; or a request JSON from "
        "tests/data/commonroad, judged against the XML beside it; or a reduced scenario JSON) to a planning "
        "request with the scenario's goal and speed limit, drive it in closed loop and judge it as "
        "bench/commonroad.py does (CommonRoad's goal check, the drivability checker's collision and "
        f"feasibility checks). Reading XML needs commonroad-io ({COMMONROAD.hint}).",
    )
    p.add_argument(
        "scenario", type=Path, help="CommonRoad XML, planning request JSON or reduced scenario JSON"
    )
    p.add_argument("--out", type=Path, default=None, help="write request.json, metrics.json, … here")
    p.add_argument(
        "--planning-problem", type=int, default=None, help="planning problem id (default: smallest)"
    )
    p.add_argument("--generator", choices=GENERATORS, default=None, help="default: transf_kappa")
    _add_timing(p)
    p.add_argument("--goal-s", type=float, default=None, help="goal: arc length reached [m] (overrides)")
    p.add_argument("--frame-every", type=_positive, default=2.0, help="key frame period [s]")
    _add_gif(p)
    _add_vehicle(p)
    p.add_argument(
        "--solution",
        type=Path,
        default=None,
        help="write the driven trajectory as a CommonRoad solution file (XML scenarios: kinematic "
        "single-track model, vehicle type 2)",
    )
    p.add_argument(
        "--centre-midway",
        action="store_true",
        help="the point model driven by a car referenced midway between its axles (its body yaws by the "
        "slip angle in turns)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_commonroad)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="kappa-planner",
        description="Closed-loop simulation of the TransF-κ planner: key frames, animation and metrics.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--out", type=Path, required=True, help="output directory (created)")
    _add_timing(common)
    common.add_argument("--goal-s", type=float, default=None, help="goal: arc length reached [m]")
    _add_gif(common)
    common.add_argument(
        "--centre-midway",
        action="store_true",
        help="the point model driven by a car referenced midway between its axles: its body yaws against "
        "the path by the slip angle, which the point model's footprint does not model (default: no slip "
        "at the centre, the vehicle the point model describes; plan a car with --wheelbase instead)",
    )
    car = common.add_argument_group("a car (kinematic single-track: planned and driven at its rear axle)")
    car.add_argument("--wheelbase", type=_positive, default=None, help="the car's wheelbase [m]")
    car.add_argument(
        "--rear-axle-offset",
        type=float,
        default=None,
        help="how far its rear axle lies behind the footprint's centre [m] (with --wheelbase)",
    )
    car.add_argument("--max-steering-angle", type=_positive, default=None, help="[rad] (with --wheelbase)")
    car.add_argument("--max-steering-rate", type=_positive, default=None, help="[rad/s] (with --wheelbase)")
    common.add_argument("--quiet", action="store_true", help="no progress bar")

    sim = sub.add_parser("simulate", parents=[common], help="simulate one run of a planning request")
    sim.add_argument("road", type=Path, help="planning request JSON (the body of POST /v1/plan)")
    sim.add_argument("--generator", choices=GENERATORS, default=None, help="default: the request's")
    sim.add_argument("--frame-every", type=_positive, default=2.0, help="key frame period [s]")
    sim.set_defaults(func=_cmd_simulate)

    cmp_ = sub.add_parser("compare", parents=[common], help="naive vs transf_kappa side by side")
    cmp_.add_argument("road", type=Path, help="planning request JSON (the body of POST /v1/plan)")
    cmp_.set_defaults(func=_cmd_compare)

    demo = sub.add_parser("demo", parents=[common], help="compare on the built-in demo U-turn")
    demo.set_defaults(func=_cmd_demo)

    _add_commonroad(sub)
    _add_evaluate(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``kappa-planner``; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        TOOLS.require("the command line")
        code: int = args.func(args)
    except (PlannerError, MissingExtraError) as exc:
        print(f"kappa-planner: error: {exc}", file=sys.stderr)
        return 2
    return code


if __name__ == "__main__":
    sys.exit(main())
