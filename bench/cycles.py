"""Every cycle on time: ``python bench/cycles.py`` drives the closed loops of the CommonRoad scenes in this
process and prints the distribution of the per-cycle plan wall times, the worst cycles and what happened
in them (asserts nothing).

The loops are :mod:`bench.commonroad`'s (its loading, goals and vehicles: ``run_one``), a replan every
0.1 s, after the warm-up of a plan process of the service (:func:`app.jobs.plan_demos`: the first plans
of a process build the speed problems, with and without a goal's and a follower's bounds, 25–50 ms
each; a checkout without it plans the first scene's first request once instead). When a scene's loop
starts, what is alive leaves the cyclic garbage collector's care (``gc.freeze()``), as a plan process's
heap does after its warm-up: its full collections would otherwise walk the loop's own objects inside a
plan (``--no-freeze``: they do).
Every ``plan`` call the loop makes is recorded — its wall time in this process, its answer's status
and ``diagnostics`` (stage times, the lateral QP's and the speed SQP's infos), the obstacles it was
given — and so is every solver call inside it
(``LateralQPSolver.solve``: calls, OSQP iterations, what the second backend did; ``SpeedSolver.solve``:
calls, QPs, HPIPM iterations). The counts do not depend on the machine's load: the same request gets
the same answer and the same counts. Beside the wall time, each plan's CPU time (of the thread that
planned) is printed: on a machine shared with other jobs it is much closer to the wall time an idle
machine would measure. With ``PlannerConfig.speculate`` a plan also works on its spare thread
(:mod:`planner.thread_solvers`): the loop waits for it to be idle after each plan (outside the timed
plan; a 10 Hz loop leaves it the time), so that what it solved is counted in its cycle
(``spare_speed_solves``), and the process's CPU time, the spare thread's included, is printed too.
They work on any checkout of the planner (the recorder wraps the loop's ``plan`` and the two solver
classes), so that a run against the previous commit can be interleaved with this one::

    python bench/cycles.py                      # all scenes, the requests' own vehicle (point model)
    python bench/cycles.py --vehicle car --only USA_Peach-3_1_T-1 --worst 20
    python bench/cycles.py --xml DIR --vehicle car  # CommonRoad XML scenes (bench/swap_ego.py's, say)
    python bench/cycles.py --json cycles.json   # every cycle as JSON, e.g. to compare two checkouts
    python bench/cycles.py --compare before.json after.json
    python bench/cycles.py --dump DIR           # the worst cycles' requests, to replay one of them:
    valgrind --tool=callgrind python bench/cycles.py --replay DIR/worst_1.json --times 2

``--replay FILE --times N`` plans the request once to warm up (the first plan builds the speed problem)
and then N times, printing each answer's status and counts; the instructions of one plan are the
difference of two callgrind runs with different N, divided by the difference of N.
"""

from __future__ import annotations

import argparse
import gc
import importlib.util
import json
import math
import os
import statistics
import sys
import threading
import time
from collections.abc import Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
# bench/ itself must not be on the path (bench/commonroad.py would shadow the commonroad package)
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(ROOT))

import planner_tools.sim as sim  # noqa: E402 (after the path fix)
from planner.pipeline import plan  # noqa: E402
from planner.problem import PlanningProblem  # noqa: E402
from planner.st_bounds import moving_obstacles  # noqa: E402
from planner.thread_solvers import thread_solvers  # noqa: E402
from planner_tools.io import problem_from_json, problem_to_json  # noqa: E402
from solvers.lateral_qp import LateralQPSolver  # noqa: E402
from solvers.speed_sqp import SpeedSolver  # noqa: E402


def _commonroad_bench() -> Any:
    """bench/commonroad.py as a module (its loading code, goals and vehicles)."""
    spec = importlib.util.spec_from_file_location("bench_commonroad", ROOT / "bench" / "commonroad.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


#: cycles over this wall time [ms] miss a 10 Hz loop's deadline
DEADLINE_MS = 100.0


@dataclass
class Counts:
    """Solver calls inside one plan (machine-independent)."""

    lateral_solves: int = 0
    osqp_iterations: int = 0
    #: lateral QP solves that did not converge (after the second backend, where there is one)
    lateral_unconverged: int = 0
    #: lateral QP solves handed to the second backend, and those it solved
    second_backend: int = 0
    second_solved: int = 0
    speed_solves: int = 0
    sqp_qps: int = 0
    hpipm_iterations: int = 0
    #: speed profiles the spare thread solved beside the plan's (``PlannerConfig.speculate``), used or not
    #: (their QPs and iterations are in the two above)
    spare_speed_solves: int = 0


@dataclass
class Cycle:
    """One plan call of a closed loop."""

    scene: str
    cycle: int
    wall_ms: float
    cpu_ms: float
    status: str
    message: str
    timing_ms: dict[str, float]
    lateral_status: str
    lateral_iterations: int
    lateral_backend: str
    speed_status: str
    speed_profile: str
    restarts: int
    obstacles: int
    moving: int
    counts: Counts = field(default_factory=Counts)
    #: CPU time of the whole process from the plan's start until its spare thread is idle [ms]
    process_cpu_ms: float = float("nan")


@dataclass
class Recorder:
    """What the wrapped ``plan`` and solvers saw, cycle by cycle."""

    scene: str = ""
    cycle: int = 0
    cycles: list[Cycle] = field(default_factory=list)
    problems: list[PlanningProblem] = field(default_factory=list)
    counts: Counts = field(default_factory=Counts)
    keep_problems: bool = False
    #: freeze the heap out of the cyclic GC when a scene's loop starts (``--no-freeze``: not)
    freeze: bool = True

    def plan(self, problem: PlanningProblem, *args: Any, **kwargs: Any) -> Any:
        if self.cycle == 0 and self.freeze:
            # A scene's loop starts: what is alive (the loaded scene, the loop's state) leaves the cyclic
            # GC, as a plan process's heap does after its warm-up (app.jobs.warm_up); the loop's objects
            # would not be in a plan process's heap at all.
            gc.collect()
            gc.freeze()
        self.counts = Counts()
        t0, c0, p0 = time.perf_counter(), time.thread_time(), time.process_time()
        try:
            result = plan(problem, *args, **kwargs)
        except Exception as exc:  # a domain error is the loop's to handle; record it first
            self._add(problem, 1e3 * (time.perf_counter() - t0), 1e3 * (time.thread_time() - c0), None, exc)
            raise
        wall, cpu = 1e3 * (time.perf_counter() - t0), 1e3 * (time.thread_time() - c0)
        # what the spare thread started in this plan is this cycle's (a 10 Hz loop leaves it the time)
        spare = getattr(thread_solvers(), "spare", None)
        if spare is not None:
            spare.wait()
        self._add(problem, wall, cpu, result, None, 1e3 * (time.process_time() - p0))
        return result

    def _add(
        self,
        problem: PlanningProblem,
        wall: float,
        cpu: float,
        result: Any,
        exc: Exception | None,
        process_cpu: float = float("nan"),
    ) -> None:
        moving = len(moving_obstacles(problem))
        if result is None:
            cycle = Cycle(
                self.scene, self.cycle, wall, cpu, "error", str(exc), {}, "", 0, "", "", "", 0,
                len(problem.obstacles), moving, self.counts,
            )  # fmt: skip
        else:
            diag = result.diagnostics
            lat, spd = diag.lateral_qp, diag.speed
            cycle = Cycle(
                scene=self.scene,
                cycle=self.cycle,
                wall_ms=wall,
                cpu_ms=cpu,
                status=result.status,
                message=result.message,
                timing_ms={k: float(v) for k, v in diag.timing_ms.items()},
                lateral_status=str(lat.status),
                lateral_iterations=int(lat.iterations),
                lateral_backend=str(lat.extras.get("backend", "osqp")),
                speed_status=str(spd.status),
                speed_profile=str(diag.speed_profile),
                restarts=int(spd.extras.get("restarts", 0)),
                obstacles=len(problem.obstacles),
                moving=moving,
                counts=self.counts,
                process_cpu_ms=process_cpu,
            )
        self.cycles.append(cycle)
        if self.keep_problems:
            self.problems.append(problem)
        self.cycle += 1


def _warm_up(otherwise: Any) -> None:
    """What a plan process builds at its start (:func:`app.jobs.plan_demos`), without its freeze of the
    heap (the recorder's to decide); on a checkout without it, ``otherwise()``."""
    try:
        from app.jobs import plan_demos
    except ImportError:
        otherwise()
    else:
        plan_demos()


@contextmanager
def recording(recorder: Recorder) -> Iterator[Recorder]:
    """Route the loop's ``plan`` and every solver call through ``recorder`` while the block runs."""
    lateral_solve, speed_solve = LateralQPSolver.solve, SpeedSolver.solve

    def counted_lateral(self: LateralQPSolver, *args: Any, **kwargs: Any) -> Any:
        out = lateral_solve(self, *args, **kwargs)
        counts, extras = recorder.counts, out.info.extras
        counts.lateral_solves += 1
        counts.osqp_iterations += int(out.info.iterations)
        counts.lateral_unconverged += not out.info.converged
        handed = bool(extras.get("second_status", ""))  # (not an elastic path after OSQP's own proof)
        counts.second_backend += handed
        counts.second_solved += handed and extras.get("backend", "osqp") != "osqp"
        return out

    plan_thread = threading.current_thread()
    counting = threading.Lock()  # the spare thread counts beside the plan's

    def counted_speed(self: SpeedSolver, *args: Any, **kwargs: Any) -> Any:
        out = speed_solve(self, *args, **kwargs)
        with counting:
            if threading.current_thread() is plan_thread:
                recorder.counts.speed_solves += 1
            else:
                recorder.counts.spare_speed_solves += 1
            recorder.counts.sqp_qps += int(out.info.extras.get("qp_solves", 0))
            recorder.counts.hpipm_iterations += int(out.info.iterations)
        return out

    loop_plan = sim.plan
    sim.plan = recorder.plan  # type: ignore[assignment]
    LateralQPSolver.solve = counted_lateral  # type: ignore[method-assign]
    SpeedSolver.solve = counted_speed  # type: ignore[method-assign]
    try:
        yield recorder
    finally:
        sim.plan = loop_plan  # type: ignore[assignment]
        LateralQPSolver.solve = lateral_solve  # type: ignore[method-assign]
        SpeedSolver.solve = speed_solve  # type: ignore[method-assign]


def run(
    names: list[str] | None,
    vehicle: str,
    duration: float,
    keep_problems: bool = False,
    freeze: bool = True,
    xml: Path | None = None,
) -> tuple[Recorder, dict[str, Any]]:
    """Every scene's closed loop (``names``: file stems; None: all; ``xml``: the CommonRoad XML files of
    that directory instead of the shared requests); the recorder and per-scene results."""
    cr = _commonroad_bench()
    paths = cr.scene_paths(xml=xml, only=names)
    recorder = Recorder(keep_problems=keep_problems, freeze=freeze)
    scenes: dict[str, Any] = {}
    if paths:  # warm up as a plan process does at start: the first plans build the speed problems
        _warm_up(lambda: plan(cr.prepare(paths[0], cr.Settings(vehicle=vehicle, duration=duration)).problem))
    with recording(recorder):
        for path in paths:
            recorder.scene, recorder.cycle = path.stem, 0
            row = cr.run_one(path, duration, vehicle)
            if row.result is None:  # a scene the converter refuses (its cycles are none of ours)
                print(f"{path.stem}: not driven: {row.outcome.error}", file=sys.stderr)
                continue
            m = row.result.metrics
            scenes[path.stem] = {
                "termination": m.termination,
                "goal_reached": bool(m.goal_reached),
                "collisions": int(m.collisions),
                "steps": int(m.steps),
                "status_counts": dict(m.status_counts),
            }
            print(f"{path.stem}: {m.termination}, {m.steps} cycles, {row.wall_s:.1f} s", file=sys.stderr)
    return recorder, scenes


# --------------------------------------------------------------------------------------------------
# Printing


def _pct(values: list[float] | np.ndarray, q: float) -> float:
    return float(np.percentile(np.asarray(values, dtype=float), q)) if len(values) else float("nan")


def distribution(name: str, values: list[float], unit: str = "ms", over: float | None = None) -> str:
    """One line: count, median, p90, p99, max (and how many above ``over``)."""
    if not values:
        return f"{name:28s} (none)"
    line = (
        f"{name:28s} n {len(values):5d}  median {_pct(values, 50):7.1f}  p90 {_pct(values, 90):7.1f}  "
        f"p99 {_pct(values, 99):7.1f}  max {max(values):7.1f} {unit}"
    )
    if over is not None:
        line += f"  over {over:g}: {sum(v > over for v in values)}"
    return line


def _mean(values: Iterable[float]) -> float:
    items = list(values)
    return statistics.mean(items) if items else float("nan")


def _counts(c: Cycle) -> Mapping[str, int]:
    return asdict(c.counts) if isinstance(c.counts, Counts) else dict(c.counts)


def describe(c: Cycle) -> str:
    """A cycle in one line: where, how long, each stage, what the solvers did."""
    n = _counts(c)
    stages = " ".join(f"{k[:4]} {v:.0f}" for k, v in c.timing_ms.items() if k != "total")
    return (
        f"{c.wall_ms:6.1f} ms (CPU {c.cpu_ms:5.1f})  {c.scene} #{c.cycle} {c.status:8s} [{stages}]  "
        f"lateral {c.lateral_status}"
        f"/{c.lateral_backend} {n['lateral_solves']} solves {n['osqp_iterations']} it "
        f"{n.get('second_backend', 0)} to clarabel; speed "
        f"{n['speed_solves']} solves (+{n.get('spare_speed_solves', 0)} spare) {n['sqp_qps']} QPs "
        f"{n['hpipm_iterations']} it {c.restarts} restarts, "
        f"{c.speed_profile}; obstacles {c.obstacles} ({c.moving} moving)"
    )


def report(cycles: list[Cycle], scenes: Mapping[str, Any], worst: int) -> str:
    """Everything the bench prints about one run."""
    lines: list[str] = []
    walls = [c.wall_ms for c in cycles]
    lines.append(distribution("plan wall time", walls, over=DEADLINE_MS))
    lines.append(
        f"{'':28s} over 40 ms: {sum(w > 40 for w in walls)}, over 80 ms: {sum(w > 80 for w in walls)}"
    )
    cpu = [c.cpu_ms for c in cycles]
    lines.append(distribution("plan CPU time (this thread)", cpu, over=DEADLINE_MS))
    lines.append(f"{'':28s} over 40 ms: {sum(w > 40 for w in cpu)}, over 80 ms: {sum(w > 80 for w in cpu)}")
    whole = [c.process_cpu_ms for c in cycles if math.isfinite(c.process_cpu_ms)]
    if whole:  # with the spare thread's work (PlannerConfig.speculate), used or not
        lines.append(distribution("plan CPU time (process)", whole) + f"  total {sum(whole) / 1e3:.1f} s")
    stages = sorted({k for c in cycles for k in c.timing_ms})
    for stage in stages:
        lines.append(
            distribution(f"  stage {stage}", [c.timing_ms[stage] for c in cycles if stage in c.timing_ms])
        )
    lines.append("")
    lines.append("machine-independent, per cycle:")
    for key in asdict(Counts()):
        values = [float(_counts(c)[key]) for c in cycles]
        lines.append(distribution(f"  {key}", values, unit="") + f"  total {sum(values):.0f}")
    statuses: dict[str, int] = {}
    for c in cycles:
        statuses[c.status] = statuses.get(c.status, 0) + 1
    lateral = {
        s: sum(c.lateral_status == s for c in cycles) for s in sorted({c.lateral_status for c in cycles})
    }
    backends = {
        b: sum(c.lateral_backend == b for c in cycles) for b in sorted({c.lateral_backend for c in cycles})
    }
    lines.append(f"statuses {statuses}; lateral QP {lateral}; backend {backends}")
    if cycles:
        slow = _pct(walls, 90)
        tail = [c for c in cycles if c.wall_ms >= slow]
        rest = [c for c in cycles if c.wall_ms < slow]
        lines.append("")
        lines.append(f"the slowest 10 % (≥ {slow:.1f} ms) against the rest, means per cycle:")
        for key in asdict(Counts()):
            lines.append(
                f"  {key:18s} {statistics.mean(_counts(c)[key] for c in tail):8.1f}  vs "
                f"{statistics.mean(_counts(c)[key] for c in rest) if rest else float('nan'):8.1f}"
            )
        for key in ("obstacles", "moving"):
            lines.append(
                f"  {key:18s} {statistics.mean(getattr(c, key) for c in tail):8.1f}  vs "
                f"{statistics.mean(getattr(c, key) for c in rest) if rest else float('nan'):8.1f}"
            )
        for stage in stages:
            lines.append(
                f"  stage {stage:12s} {_mean(c.timing_ms.get(stage, 0.0) for c in tail):8.1f}  vs "
                f"{_mean(c.timing_ms.get(stage, 0.0) for c in rest):8.1f} ms"
            )
    lines.append("")
    lines.append("per scene: cycles, wall median / p99 / max [ms], fallbacks, end")
    for name in sorted({c.scene for c in cycles}):
        own = [c for c in cycles if c.scene == name]
        w = [c.wall_ms for c in own]
        end = scenes.get(name, {}).get("termination", "")
        fallbacks = sum(c.status == "fallback" for c in own)
        lines.append(
            f"  {name:32s} {len(own):4d}  {_pct(w, 50):6.1f} / {_pct(w, 99):6.1f} / {max(w):6.1f}  "
            f"{fallbacks:3d}  {end}"
        )
    lines.append("")
    lines.append(f"the {worst} slowest cycles:")
    for c in sorted(cycles, key=lambda c: -c.wall_ms)[:worst]:
        lines.append("  " + describe(c))
        if c.status != "ok":
            lines.append(f"      {c.message[:160]}")
    unconverged = sum(c.lateral_status not in ("solved", "solved_inaccurate") for c in cycles)
    lines.append("")
    lines.append(
        f"{len(cycles)} cycles: {sum(c.status == 'fallback' for c in cycles)} fallbacks, {unconverged} whose "
        f"lateral QP did not converge; lateral QP solves not converged "
        f"{sum(_counts(c).get('lateral_unconverged', 0) for c in cycles)}, handed to the second backend "
        f"{sum(_counts(c).get('second_backend', 0) for c in cycles)} (solved there "
        f"{sum(_counts(c).get('second_solved', 0) for c in cycles)})"
    )
    if scenes:
        goals = sum(s["goal_reached"] for s in scenes.values())
        hits = sum(s["collisions"] > 0 for s in scenes.values())
        fallbacks = sum(s["status_counts"].get("fallback", 0) for s in scenes.values())
        lines.append("")
        lines.append(
            f"{len(scenes)} scenes: {goals} goals reached, {hits} runs with a collision, "
            f"{fallbacks} fallbacks"
        )
    return "\n".join(lines)


def compare(before: list[Cycle], after: list[Cycle]) -> str:
    """Two runs of the same loops side by side: the distributions, and the cycles whose counts changed."""
    lines = ["before:", report(before, {}, 5), "", "after:", report(after, {}, 5), ""]
    keyed = {(c.scene, c.cycle): c for c in before}
    changed = moved = 0
    for c in after:
        b = keyed.get((c.scene, c.cycle))
        if b is None:
            continue
        if b.status != c.status or b.message != c.message or _lateral(b) != _lateral(c):
            changed += 1
        elif _counts(b) != _counts(c):
            # the same answer and lateral work: the speed solves differ only where one run solved some on
            # its spare thread (PlannerConfig.speculate: started beside the first, used or not)
            spared = _counts(b)["spare_speed_solves"] or _counts(c)["spare_speed_solves"]
            changed += not spared
            moved += bool(spared)
    lines.append(
        f"{changed} of {len(after)} cycles changed status, message or solver counts "
        "(a changed cycle changes the loop after it)"
    )
    if moved:
        lines.append(f"{moved} more with the same answers and lateral work, speed solves on a spare thread")
    return "\n".join(lines)


#: the lateral QP's counts among :class:`Counts`
_LATERAL = ("lateral_solves", "osqp_iterations", "lateral_unconverged", "second_backend", "second_solved")


def _lateral(c: Cycle) -> list[int]:
    """The lateral QP's counts of a cycle."""
    counts = _counts(c)
    return [counts[k] for k in _LATERAL]


def _load(path: Path) -> list[Cycle]:
    out = []
    for item in json.loads(path.read_text())["cycles"]:
        item["counts"] = Counts(**item["counts"])
        item.setdefault("cpu_ms", float("nan"))
        out.append(Cycle(**item))
    return out


def replay(path: Path, times: int) -> None:
    """Plan the request in ``path`` once to warm up, then ``times`` times, printing what each did."""
    problem = problem_from_json(json.loads(path.read_text()))
    recorder = Recorder()
    with recording(recorder):
        recorder.plan(problem)
        for _ in range(times):
            recorder.plan(problem)
    for c in recorder.cycles:
        print(describe(c))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="*", default=None, help="scene names (file stems) to run")
    parser.add_argument("--vehicle", choices=("request", "car", "point"), default="request")
    parser.add_argument(
        "--xml", type=Path, default=None, help="the CommonRoad XML files in DIR instead of the requests"
    )
    parser.add_argument("--duration", type=float, default=35.0, help="simulated seconds per scene at most")
    parser.add_argument("--worst", type=int, default=15, help="how many of the slowest cycles to show")
    parser.add_argument("--json", type=Path, default=None, help="write every cycle to this JSON file")
    parser.add_argument("--dump", type=Path, default=None, help="write the worst cycles' requests here")
    parser.add_argument("--compare", nargs=2, type=Path, default=None, help="two --json files")
    parser.add_argument("--replay", type=Path, default=None, help="a request to plan (see --times)")
    parser.add_argument("--times", type=int, default=1, help="plans of --replay after the warm-up")
    parser.add_argument(
        "--no-freeze", action="store_true", help="leave the heap in the cyclic GC's care (see Recorder)"
    )
    args = parser.parse_args(argv)

    if args.compare is not None:
        print(compare(_load(args.compare[0]), _load(args.compare[1])))
        return 0
    if args.replay is not None:
        replay(args.replay, args.times)
        return 0
    load0 = os.getloadavg()
    t0 = time.perf_counter()
    recorder, scenes = run(
        args.only,
        args.vehicle,
        args.duration,
        keep_problems=args.dump is not None,
        freeze=not args.no_freeze,
        xml=args.xml,
    )
    total = time.perf_counter() - t0
    load1 = os.getloadavg()
    print(
        f"python bench/cycles.py {' '.join(argv if argv is not None else sys.argv[1:])}\n"
        f"{os.cpu_count()} cores, load average {load0[0]:.1f} at the start, {load1[0]:.1f} at the end; "
        f"{total:.0f} s wall; every time is in-process wall time\n"
    )
    print(report(recorder.cycles, scenes, args.worst))
    if args.json is not None:
        data = {"vehicle": args.vehicle, "scenes": scenes, "cycles": [asdict(c) for c in recorder.cycles]}
        args.json.write_text(json.dumps(data))
        print(f"\nwrote {args.json}", file=sys.stderr)
    if args.dump is not None:
        args.dump.mkdir(parents=True, exist_ok=True)
        order = sorted(range(len(recorder.cycles)), key=lambda i: -recorder.cycles[i].wall_ms)
        for rank, i in enumerate(order[: args.worst], start=1):
            c = recorder.cycles[i]
            out = args.dump / f"worst_{rank}.json"
            out.write_text(json.dumps(problem_to_json(recorder.problems[i])))
            print(f"{out}: {c.scene} #{c.cycle}, {c.wall_ms:.1f} ms", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
