"""How often the speed SQP's budget keeps a worse profile: ``python bench/sqp_restarts.py`` drives the
CommonRoad closed loops (:mod:`bench.commonroad`'s ``run_one``) and solves every speed problem the plans
pose once more, beside the plan's own solve, with ``--iterations`` (default 8) SQP iterations; it prints,
per scene, the solves whose kept profile comes from a restart (``restarted``) and those the longer SQP
beats: a profile that travels farther over the horizon by more than ``--loss`` [m] with no larger
violation of the limit, ``v ≥ 0`` and ``s_bound`` (asserts nothing; the loops drive the plan's own
profiles, so they are the same as without this bench).

    python bench/sqp_restarts.py                       # car, the lane's requests
    python bench/sqp_restarts.py --road --vehicle point --only USA_US101-6_1_T-1
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import pickle
import sys
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
# bench/ itself must not be on the path (bench/commonroad.py would shadow the commonroad package)
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(ROOT))

import planner_tools.sim as sim  # noqa: E402 (after the path fix)
from solvers.speed_problem import SpeedProblem, SpeedResult  # noqa: E402
from solvers.speed_sqp import SpeedSolver  # noqa: E402

#: the slack of a violation that still counts as no larger [m/s or m]
_SLACK = 0.05


def _commonroad_bench() -> Any:
    spec = importlib.util.spec_from_file_location("bench_commonroad", ROOT / "bench" / "commonroad.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@dataclass(frozen=True)
class Solve:
    """One speed solve of a plan and the longer SQP's on the same problem."""

    scene: str
    cycle: int
    status: str
    restarts: int
    restarted: bool
    qps: int
    distance: float  # s_N − s0 of the plan's profile [m]
    min_speed: float  # its lowest speed after the first second [m/s]
    violation: float  # its largest violation of v_lim, v ≥ 0 and s_bound
    long_status: str
    long_distance: float
    long_min_speed: float
    long_violation: float


def _summary(result: SpeedResult, problem: SpeedProblem) -> tuple[float, float, float]:
    later = result.t >= 1.0
    return (
        float(result.s[-1] - problem.s0),
        float(result.v[later].min()),
        max(result.speed_violation, result.position_violation),
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="*", default=None)
    parser.add_argument("--vehicle", default="car")
    parser.add_argument("--road", action="store_true")
    parser.add_argument("--duration", type=float, default=None)
    parser.add_argument("--iterations", type=int, default=8)
    parser.add_argument("--loss", type=float, default=1.0, help="distance [m] a worse profile lacks")
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--dump", type=Path, default=None, help="pickle the worse solves' problems here")
    args = parser.parse_args(argv)

    cr = _commonroad_bench()
    paths = cr.scene_paths(only=args.only, road=args.road)
    solve = SpeedSolver.solve
    shadows: dict[tuple[int, float, float, float], SpeedSolver] = {}
    state = {"scene": "", "cycle": -1}
    rows: list[Solve] = []
    problems: list[SpeedProblem] = []
    loop_plan = sim.plan

    def counted_plan(*a: Any, **k: Any) -> Any:
        state["cycle"] += 1
        return loop_plan(*a, **k)

    def shadowed(self: SpeedSolver, problem: SpeedProblem, **kwargs: Any) -> SpeedResult:
        out = solve(self, problem, **kwargs)
        if self in shadows.values():
            return out
        key = (self._max_iterations, self._tolerance, self._restore_violation, self._hpipm.residual)
        shadow = shadows.get(key)
        if shadow is None:
            shadow = shadows[key] = SpeedSolver(
                max_iterations=args.iterations, tolerance=key[1], restore_violation=key[2], qp_residual=key[3]
            )
        long = solve(shadow, problem, **kwargs)
        problems.append(problem)
        extras = out.info.extras
        rows.append(
            Solve(
                str(state["scene"]),
                int(state["cycle"]),
                str(out.info.status),
                int(extras.get("restarts", 0)),
                bool(extras.get("restarted", False)),
                out.qp_solves,
                *_summary(out, problem),
                str(long.info.status),
                *_summary(long, problem),
            )
        )
        return out

    sim.plan = counted_plan  # type: ignore[assignment]
    SpeedSolver.solve = shadowed  # type: ignore[method-assign,assignment]
    try:
        for path in paths:
            state["scene"], state["cycle"] = path.name.split(".")[0], -1
            duration = args.duration if args.duration is not None else cr.DURATION
            cr.run_one(path, duration, args.vehicle)
    finally:
        sim.plan = loop_plan  # type: ignore[assignment]
        SpeedSolver.solve = solve  # type: ignore[method-assign]

    def worse(r: Solve) -> bool:
        return r.long_distance > r.distance + args.loss and r.long_violation <= r.violation + _SLACK

    print(f"{len(rows)} speed solves; long SQP: {args.iterations} iterations; worse: > {args.loss} m shorter")
    print("| scene | solves | restarts | restarted kept | worse | worse & restarted | max loss [m] |")
    print("|---|---|---|---|---|---|---|")
    by_scene: dict[str, list[Solve]] = {}
    for r in rows:
        by_scene.setdefault(r.scene, []).append(r)
    totals: Counter[str] = Counter()
    for scene, rs in by_scene.items():
        bad = [r for r in rs if worse(r)]
        counts = {
            "solves": len(rs),
            "restarts": sum(r.restarts > 0 for r in rs),
            "restarted": sum(r.restarted for r in rs),
            "worse": len(bad),
            "worse_restarted": sum(r.restarted for r in bad),
        }
        totals.update(counts)
        loss = max((r.long_distance - r.distance for r in bad), default=0.0)
        print(f"| {scene} | " + " | ".join(str(v) for v in counts.values()) + f" | {loss:.1f} |")
    print(
        "| total | "
        + " | ".join(str(totals[k]) for k in ("solves", "restarts", "restarted", "worse", "worse_restarted"))
        + " | |"
    )
    for r in rows:
        if worse(r):
            print(
                f"  {r.scene} cycle {r.cycle}: {r.status} restarted={r.restarted} {r.distance:.1f} m "
                f"(min {r.min_speed:.2f} m/s, viol {r.violation:.3g}) vs {r.long_distance:.1f} m "
                f"(min {r.long_min_speed:.2f} m/s, viol {r.long_violation:.3g}, {r.long_status})"
            )
    if args.dump is not None:
        bad = [(asdict(r), p) for r, p in zip(rows, problems, strict=True) if worse(r)]
        args.dump.write_bytes(pickle.dumps(bad))
    if args.json is not None:
        args.json.write_text(json.dumps([asdict(r) for r in rows]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
