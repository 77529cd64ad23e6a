"""Figures: ``python -m planner_tools.figures candidates --out candidates.png``.

``candidates`` draws the candidates of Algorithm 4 (``naive``) and Algorithm 5 (``transf_kappa``)
side by side on the demo U-turn, whose inner side is wider than its radius: naive candidates that run
backwards or cross themselves are drawn in red, the rest in blue.
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.axes import Axes
from matplotlib.patches import Circle, Polygon

from planner.candidates import CandidateSet, generate_candidates, lane_bounds
from planner.frenet import to_cartesian
from planner.problem import CircleObstacle, Generator, PlanningProblem, PolygonObstacle
from planner.reference import ReferenceLine, build_reference
from planner.roads import demo_problem
from planner.validation import folds_back


def _draw_road(ax: Axes, ref: ReferenceLine, problem: PlanningProblem) -> None:
    bounds = lane_bounds(ref, problem.lane, ref.s, half_width=0.0, margin=0.0)
    for offset, style in ((bounds.upper, "-"), (bounds.lower, "-")):
        edge = to_cartesian(ref, ref.s, offset)
        ax.plot(edge[:, 0], edge[:, 1], style, color="0.35", lw=1.2)
    ax.plot(ref.points[:, 0], ref.points[:, 1], "--", color="0.55", lw=1.0, label="reference")
    for ob in problem.obstacles:
        if isinstance(ob, CircleObstacle):
            ax.add_patch(Circle(tuple(ob.center), ob.radius, color="k", alpha=0.7))
        elif isinstance(ob, PolygonObstacle):
            ax.add_patch(Polygon(ob.polygon, closed=True, color="k", alpha=0.7))
    ax.plot([problem.ego.x], [problem.ego.y], "k^", ms=9, label="ego")


def _draw_candidates(ax: Axes, ref: ReferenceLine, cands: CandidateSet) -> int:
    broken = 0
    for i in range(cands.count):
        _, _, xy = cands.points(i)
        bad = folds_back(ref, xy)
        broken += int(bad)
        ax.plot(xy[:, 0], xy[:, 1], color="tab:red" if bad else "tab:blue", lw=0.8, alpha=0.8)
    return broken


def candidates_figure(out: Path, *, num_candidates: int = 40, seed: int = 0) -> Path:
    """Draw Algorithm 4 vs Algorithm 5 candidates on the demo U-turn into ``out`` (PNG)."""
    problem = demo_problem()
    ref = build_reference(problem.reference_line)
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.5), sharex=True, sharey=True)
    panels: tuple[tuple[Axes, Generator, str], ...] = (
        (axes[0], "naive", "Algorithm 4 (naive offsets)"),
        (axes[1], "transf_kappa", "Algorithm 5 (TransF-κ repair)"),
    )
    for ax, generator, title in panels:
        options = replace(problem.options, num_candidates=num_candidates, seed=seed, generator=generator)
        cands = generate_candidates(ref, problem.lane, problem.ego, problem.vehicle, options)
        _draw_road(ax, ref, problem)
        broken = _draw_candidates(ax, ref, cands)
        ax.set_title(f"{title}\n{broken} of {cands.count} run backwards or self-intersect")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_xlabel("x [m]")
    axes[0].set_ylabel("y [m]")
    axes[0].legend(loc="lower left")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m planner_tools.figures", description=__doc__)
    sub = parser.add_subparsers(dest="figure", required=True)
    cand = sub.add_parser("candidates", help="Algorithm 4 vs 5 candidates on the demo U-turn")
    cand.add_argument("--out", type=Path, default=Path("candidates.png"))
    cand.add_argument("--num-candidates", type=int, default=40)
    cand.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.figure == "candidates":
        path = candidates_figure(args.out, num_candidates=args.num_candidates, seed=args.seed)
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
