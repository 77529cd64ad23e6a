"""Command line: ``kappa-planner simulate | compare | demo | commonroad`` — closed-loop runs, drawn.

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
* ``kappa-planner commonroad SCENARIO [--out DIR]`` converts a CommonRoad scenario
  (:mod:`planner_tools.commonroad`: XML, a request JSON or a reduced scenario JSON) and drives it to the
  goal of its planning problem; ``--out`` adds ``request.json``, ``conversion.json`` and the files of
  ``simulate``; ``--solution OUT.xml`` writes the driven trajectory as a CommonRoad solution (XML
  scenarios); ``--vehicle car|point`` drives CommonRoad's vehicle type 2 car (an XML's own) or the
  same footprint as the point model.

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
from dataclasses import replace
from pathlib import Path
from typing import Any

from planner.errors import PlannerError
from planner.problem import CAR_FIELDS, Generator, PlanningProblem
from planner.roads import demo_problem
from planner_tools.commonroad import CommonRoadError, car_vehicle, load, point_vehicle, write_solution
from planner_tools.extras import COMMONROAD, TOOLS, MissingExtraError
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


def _run(problem: PlanningProblem, generator: Generator, args: argparse.Namespace) -> SimResult:
    from tqdm import tqdm

    problem = _car(problem, args)
    problem = replace(problem, options=replace(problem.options, generator=generator))
    model = BicycleModel.for_vehicle(problem.vehicle, centre_midway=args.centre_midway)
    goal = None if args.goal_s is None else Goal(s_min=args.goal_s)
    with tqdm(total=1, desc=generator, unit="cycle", disable=_quiet(args)) as bar:

        def progress(done: int, total: int) -> None:
            bar.total = total
            bar.n = done
            bar.refresh()

        return simulate(
            problem,
            duration=args.duration,
            replan_period=args.replan_period,
            goal=goal,
            progress=progress,
            model=model,
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
    try:
        conv = load(args.scenario, planning_problem_id=args.planning_problem)
        if args.vehicle != "request":
            vehicle = conv.request["vehicle"]
            vehicle = car_vehicle(vehicle) if args.vehicle == "car" else point_vehicle(vehicle)
            conv = replace(conv, request={**conv.request, "vehicle": vehicle})
        if args.solution is not None and "scenario_id" not in conv.info:
            raise CommonRoadError(f"--solution needs a CommonRoad XML scenario, not {args.scenario}")
    except (CommonRoadError, OSError, ValueError) as exc:
        raise PlannerError(str(exc)) from exc
    problem = problem_from_json(conv.request)
    if args.goal_s is None and conv.goal.get("s_min") is not None:
        args.goal_s = float(conv.goal["s_min"])
    result = _run(problem, args.generator or problem.options.generator, args)
    print(f"{conv.name}: {len(conv.request['obstacles'])} obstacles, goal s ≥ {args.goal_s}")
    print(summary([result]))
    out: Path | None = args.out
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "request.json").write_text(json.dumps(conv.request) + "\n")
        (out / "conversion.json").write_text(
            json.dumps({"name": conv.name, "goal": conv.goal, "info": conv.info}, indent=1) + "\n"
        )
        _write_run(result, out, args, {"scenario": str(args.scenario)})
        print(
            f"wrote request.json, conversion.json, key frames, {'' if args.no_gif else 'sim.gif, '}"
            f"steps.csv, metrics.json, run.json.gz to {out}"
        )
    if args.solution is not None:
        try:
            written = write_solution(args.solution, conv, result.motion)
        except CommonRoadError as exc:
            raise PlannerError(str(exc)) from exc
        print(f"wrote the driven trajectory as a CommonRoad solution (KS, vehicle type 2) to {written}")
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


def _add_commonroad(sub: Any) -> None:
    p: argparse.ArgumentParser = sub.add_parser(
        "commonroad",
        help="convert a CommonRoad scenario and drive it in closed loop to its goal",
        description="Convert a CommonRoad scenario (XML; or a request JSON from tests/data/commonroad, or a "
        "reduced scenario JSON) to a planning request and drive it in closed loop to the goal of its "
        f"planning problem. Reading XML needs commonroad-io ({COMMONROAD.hint}).",
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
    p.add_argument(
        "--vehicle",
        choices=("request", "car", "point"),
        default="request",
        help="the request's vehicle (XML: CommonRoad's vehicle type 2 car, BMW 320i), that car, or the "
        "same footprint as the point model (no wheelbase)",
    )
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
