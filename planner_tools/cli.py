"""Command line: ``kappa-planner simulate | compare | demo`` — closed-loop runs, figures, animations.

* ``kappa-planner simulate ROAD.json --out DIR [--generator naive|transf_kappa]`` drives the planning
  request in ``ROAD.json`` (the body of ``POST /v1/plan``, e.g. from ``GET /v1/demo`` or
  ``tests/data/commonroad/*.json``) in closed loop (:func:`planner_tools.sim.simulate`) and writes a PNG per
  key frame (every ``--frame-every`` seconds and the last), ``sim.gif`` and ``metrics.json``.
* ``kappa-planner compare ROAD.json --out DIR`` runs both generators and draws them side by side like
  Fig. 4 of the paper (``compare.png``: road, obstacles, driven paths, candidate fans at four points
  along the road, a metrics table; ``compare.gif``), with ``metrics.json`` for both.
* ``kappa-planner demo --out DIR`` is ``compare`` on the built-in demo U-turn.

The request is read by :func:`planner_tools.io.problem_from_json` (no pydantic, no ``app`` import: the
command line is a client of the planner like the HTTP layer). Exit status: 0 on success (whatever the
run's outcome), 2 for an unreadable or invalid request.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Polygon
from matplotlib.text import Text
from PIL import Image
from tqdm import tqdm

from planner.candidates import lane_bounds
from planner.collision import box_corners
from planner.errors import PlannerError
from planner.frenet import to_cartesian
from planner.problem import DynamicObstacle, Generator, PlanningProblem
from planner.roads import demo_problem
from planner_tools import commonroad
from planner_tools.io import problem_from_json
from planner_tools.sim import BicycleModel, Goal, SimResult, obstacle_outlines, simulate

GENERATORS: tuple[Generator, ...] = ("naive", "transf_kappa")
TITLES = {"naive": "Algorithm 4 (naive offsets)", "transf_kappa": "Algorithm 5 (TransF-κ)"}
#: colours: candidates that are fine / fold back, the plan, the driven path, the vehicle
C_CAND, C_FOLD, C_PLAN, C_DRIVEN, C_EGO = "tab:blue", "tab:orange", "crimson", "black", "tab:green"
#: the vehicle's colour once it has collided
C_HIT = "tab:red"


# --------------------------------------------------------------------------------------------------
# Drawing
# --------------------------------------------------------------------------------------------------


class _Panel:
    """One axes showing one run at a chosen cycle; static road drawn once, the rest updated per frame."""

    def __init__(self, ax: Axes, result: SimResult, title: str) -> None:
        self.ax, self.result, self.title = ax, result, title
        problem, ref = result.problem, result.reference
        bounds = lane_bounds(ref, problem.lane, ref.s, half_width=0.0, margin=0.0)
        # an edge beyond the centre of curvature (κ·d ≥ 1) folds back on itself: left out
        edges = [
            np.where((ref.kappa * w < 1.0)[:, None], to_cartesian(ref, ref.s, w), np.nan)
            for w in (bounds.upper, bounds.lower)
        ]
        for edge in edges:
            ax.plot(edge[:, 0], edge[:, 1], "-", color="0.3", lw=1.1)
        ax.plot(ref.points[:, 0], ref.points[:, 1], "--", color="0.55", lw=0.9)
        pts = np.vstack([*(e[np.isfinite(e[:, 0])] for e in edges), ref.points])
        outlines = dict(obstacle_outlines(problem, 0.0))
        for ob in problem.obstacles:
            if not isinstance(ob, DynamicObstacle):
                ax.add_patch(Polygon(outlines[ob.id], closed=True, color="k", alpha=0.75, zorder=3))
        pad = 3.0
        lo, hi = pts.min(axis=0) - pad, pts.max(axis=0) + pad
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.grid(alpha=0.25)
        self.candidates = LineCollection([], lw=0.7, alpha=0.55, zorder=2)
        ax.add_collection(self.candidates)
        (self.driven,) = ax.plot([], [], "-", color=C_DRIVEN, lw=1.6, zorder=4)
        (self.plan,) = ax.plot([], [], "-", color=C_PLAN, lw=2.0, zorder=5)
        self.body = Polygon(np.zeros((4, 2)), closed=True, fc=C_EGO, ec="k", lw=0.8, alpha=0.9, zorder=6)
        ax.add_patch(self.body)
        self.movers: dict[str, Polygon] = {}
        for ob in problem.obstacles:
            if isinstance(ob, DynamicObstacle):
                self.movers[ob.id] = Polygon(np.zeros((4, 2)), closed=True, color="0.25", alpha=0.8, zorder=3)
                ax.add_patch(self.movers[ob.id])
        self.label: Text = ax.text(
            0.01,
            0.98,
            "",
            transform=ax.transAxes,
            va="top",
            ha="left",
            fontsize=8,
            family="monospace",
            bbox={"fc": "white", "ec": "none", "alpha": 0.8, "pad": 1.5},
            zorder=7,
        )
        ax.set_title(title, fontsize=10)

    def show(self, k: int) -> None:
        """Draw cycle ``k`` (``k = len(steps)``: the final state after the last cycle)."""
        res, m = self.result, self.result.motion
        n = len(res.steps)
        final = k >= n
        step = res.steps[min(k, n - 1)] if n else None
        t_now = float(m.t[-1]) if final or step is None else step.state.t
        upto = m.t <= t_now + 1e-9
        self.driven.set_data(m.x[upto], m.y[upto])
        i = int(np.flatnonzero(upto)[-1])
        corners = box_corners(m.x[i], m.y[i], m.yaw[i], res.problem.vehicle.length, res.problem.vehicle.width)
        self.body.set_xy(corners)
        self.body.set_facecolor(C_HIT if final and res.termination == "collision" else C_EGO)
        segs: list[np.ndarray] = []
        colours: list[str] = []
        if step is not None and step.candidates_xy is not None:
            folded = step.candidates_folded
            if folded is None:
                folded = np.zeros(step.candidates_xy.shape[0], dtype=bool)
            for xy, bad in zip(step.candidates_xy, folded, strict=True):
                keep = np.isfinite(xy[:, 0])
                segs.append(xy[keep])
                colours.append(C_FOLD if bad else C_CAND)
        self.candidates.set_segments(segs)
        self.candidates.set_colors(colours)
        if step is not None and step.trajectory is not None:
            self.plan.set_data(step.trajectory.x, step.trajectory.y)
        else:
            self.plan.set_data([], [])
        if self.movers:
            outlines = dict(obstacle_outlines(res.problem, t_now))
            for ob_id, patch in self.movers.items():
                patch.set_xy(outlines[ob_id])
        if step is None:
            self.label.set_text(f"t={t_now:5.1f} s  {res.termination}")
            return
        folded_n = 0 if step.candidates_folded is None else int(step.candidates_folded.sum())
        head = f"t={t_now:5.1f} s  v={m.v[i]:4.1f} m/s  s={m.s[i]:6.1f} m"
        tail = f"{res.termination} (last plan shown)" if final else step.status
        self.label.set_text(f"{head}\n{tail}, {folded_n} folded candidates")


def _legend(fig: Figure, *, outside: bool = False) -> None:
    handles = [
        Line2D([], [], color=C_CAND, lw=1, label="candidates"),
        Line2D([], [], color=C_FOLD, lw=1, label="candidates that fold back"),
        Line2D([], [], color=C_PLAN, lw=2, label="plan"),
        Line2D([], [], color=C_DRIVEN, lw=1.6, label="driven"),
        Line2D([], [], color="0.55", ls="--", lw=1, label="reference"),
    ]
    if outside:
        fig.legend(handles=handles, loc="outside lower center", ncol=5, fontsize=8, frameon=False)
    else:
        fig.legend(handles=handles, loc="lower center", ncol=5, fontsize=8, frameon=False)


def write_gif(
    results: Sequence[SimResult],
    out: Path,
    *,
    stride: int = 2,
    dpi: int = 100,
    quiet: bool = True,
) -> Path:
    """An animation of the runs side by side, one frame every ``stride`` cycles, in real time.

    Frames are mapped without dithering onto a small fixed palette of the figures' colours and their
    blends with white (flat areas stay flat, so the GIF compresses well)."""
    fig, axes = plt.subplots(1, len(results), figsize=(5.2 * len(results), 3.4), squeeze=False, dpi=dpi)
    panels = [
        _Panel(ax, r, TITLES.get(r.problem.options.generator, r.problem.options.generator))
        for ax, r in zip(axes[0], results, strict=True)
    ]
    _legend(fig)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    last = max(len(r.steps) for r in results)
    palette = _palette()
    frames: list[Image.Image] = []
    for k in tqdm([*range(0, last, stride), last], desc="gif", disable=quiet, leave=False):
        for p in panels:
            p.show(k)
        fig.canvas.draw()
        rgb = Image.fromarray(np.asarray(fig.canvas.buffer_rgba())).convert("RGB")  # type: ignore[attr-defined]
        frames.append(rgb.quantize(palette=palette, dither=Image.Dither.NONE))
    plt.close(fig)
    out.parent.mkdir(parents=True, exist_ok=True)
    duration_ms = round(1000.0 * results[0].replan_period * stride)
    frames[0].save(out, save_all=True, append_images=frames[1:], duration=duration_ms, loop=0, optimize=True)
    return out


def _palette() -> Image.Image:
    """A palette image: white, greys, and each drawing colour blended with white at 0–75 %."""
    base = [to_rgb(c) for c in (C_CAND, C_FOLD, C_PLAN, C_EGO, "tab:red", "tab:purple")]
    greys = [(g, g, g) for g in np.linspace(0.0, 1.0, 12)]
    blends = [tuple(w + (1.0 - w) * np.array(c)) for c in base for w in (0.0, 0.25, 0.5, 0.75)]
    colours = np.round(255 * np.array([*greys, *blends])).astype(np.uint8)
    pal = Image.new("P", (1, 1))
    pal.putpalette(colours.ravel().tolist() + [0, 0, 0] * (256 - colours.shape[0]))
    return pal


def write_key_frames(result: SimResult, out_dir: Path, *, every: float = 2.0, dpi: int = 110) -> list[Path]:
    """A PNG of the run every ``every`` seconds and of its final state."""
    fig, ax = plt.subplots(figsize=(8.0, 4.6))
    panel = _Panel(ax, result, TITLES.get(result.problem.options.generator, ""))
    _legend(fig)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    n = len(result.steps)
    per = max(1, round(every / result.replan_period))
    paths = []
    for k in [*range(0, n, per), n]:
        t = result.motion.t[-1] if k >= n else result.steps[k].state.t
        panel.show(k)
        path = out_dir / (f"frame_{t:05.1f}s.png" if k < n else f"frame_{t:05.1f}s_final.png")
        fig.savefig(path, dpi=dpi)
        paths.append(path)
    plt.close(fig)
    return paths


def _progress_frames(results: Sequence[SimResult], count: int) -> list[list[int]]:
    """Per run, the cycles where its vehicle first reaches ``count`` equally spaced arc lengths between
    the start and the farthest any run got (its final state, ``len(steps)``, where it never did)."""
    start = float(results[0].motion.s[0])
    farthest = max(float(r.motion.s.max()) for r in results)
    targets = np.linspace(start, farthest, count)
    out = []
    for r in results:
        s = np.array([st.s for st in r.steps])
        first = [np.flatnonzero(s >= target - 1e-9) for target in targets]
        out.append([int(f[0]) if f.size and i < count - 1 else len(r.steps) for i, f in enumerate(first)])
    return out


_TABLE_ROWS: tuple[tuple[str, Callable[[dict[str, Any]], str]], ...] = (
    ("outcome", lambda m: m["termination"]),
    ("time to goal [s]", lambda m: "—" if m["time_to_goal"] is None else f"{m['time_to_goal']:.1f}"),
    ("collisions (sub-steps)", lambda m: str(m["collisions"])),
    ("min clearance [m]", lambda m: "—" if m["min_clearance"] is None else f"{m['min_clearance']:.2f}"),
    ("backward steps / κ·d ≥ 1 steps", lambda m: f"{m['backward_steps']} / {m['fold_steps']}"),
    (
        "folded candidates: mean / cycles / chosen",
        lambda m: "{mean:.1f} / {cycles:.0f} / {chosen:.0f}".format(**m["folded_candidates"]),
    ),
    (
        "plans ok / stopped / fallback / error",
        lambda m: "{ok} / {stopped} / {fallback} / {error}".format(**m["status_counts"]),
    ),
    ("max |a_lat| [m/s²]", lambda m: f"{m['max_lateral_acceleration']:.2f}"),
    (
        "max |jerk| long. / lat. [m/s³]",
        lambda m: f"{m['max_longitudinal_jerk']:.1f} / {m['max_lateral_jerk']:.1f}",
    ),
    ("planning median / p95 [ms]", lambda m: "{median:.0f} / {p95:.0f}".format(**m["planning_ms"])),
)


def write_compare(results: Sequence[SimResult], out: Path, *, columns: int = 4, dpi: int = 110) -> Path:
    """Fig. 4 of the paper: a row per run, a column per point of progress, and a metrics table."""
    rows = len(results)
    fig = plt.figure(figsize=(4.4 * columns, 2.6 * rows + 2.6), layout="constrained")
    fig.get_layout_engine().set(h_pad=0.08)  # type: ignore[union-attr,call-arg]
    grid = fig.add_gridspec(rows + 1, columns, height_ratios=[*([1.0] * rows), 0.8])
    for r, (result, ks) in enumerate(zip(results, _progress_frames(results, columns), strict=True)):
        generator = result.problem.options.generator
        for c, k in enumerate(ks):
            ax = fig.add_subplot(grid[r, c])
            panel = _Panel(ax, result, "")
            panel.show(k)
            ax.tick_params(labelsize=7, labelbottom=r == rows - 1)
            letter = chr(ord("a") + r * columns + c)
            ax.set_title(f"({letter}) {TITLES.get(generator, generator)}", fontsize=9)
    table_ax = fig.add_subplot(grid[rows, :])
    table_ax.axis("off")
    metrics = [r.metrics.to_dict() for r in results]
    cells = [[fmt(m) for m in metrics] for _, fmt in _TABLE_ROWS]
    table = table_ax.table(
        cellText=cells,
        rowLabels=[name for name, _ in _TABLE_ROWS],
        colLabels=[TITLES.get(m["generator"], m["generator"]) for m in metrics],
        loc="center",
        cellLoc="center",
        colWidths=[0.25] * len(metrics),
    )
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    table.scale(1.0, 1.15)
    _legend(fig, outside=True)
    fig.suptitle(
        "Closed loop on the same road: candidates and plan at equal progress along the reference", fontsize=11
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


# --------------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------------


def run_record(result: SimResult) -> dict[str, Any]:
    """metrics.json data of one run: settings and metrics."""
    model = result.model
    goal = result.goal
    return {
        "generator": result.problem.options.generator,
        "replan_period_s": result.replan_period,
        "duration_s": round(result.duration, 3),
        "model": {
            "wheelbase_m": model.wheelbase,
            "rear_to_centre_m": model.rear_to_centre,
            "max_steering_rad": round(model.max_steering, 4),
            "max_steering_rate_rad_s": model.max_steering_rate,
            "substeps": model.substeps,
        },
        "goal": {
            "s_min": goal.s_min,
            "polygon": None if goal.polygon is None else np.asarray(goal.polygon).tolist(),
            "position": None if goal.position is None else np.asarray(goal.position).tolist(),
            "radius": goal.radius,
        },
        "metrics": result.metrics.to_dict(),
    }


def write_steps_csv(result: SimResult, out: Path) -> Path:
    """One row per replan cycle: the vehicle's state, the plan's status and planning time."""
    header = [
        "t", "x", "y", "yaw", "course", "speed", "acceleration", "curvature", "s", "d",
        "status", "planning_ms", "folded_candidates", "message",
    ]  # fmt: skip
    with out.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        for st in result.steps:
            x = st.state
            folded = "" if st.candidates_folded is None else int(st.candidates_folded.sum())
            w.writerow(
                [
                    *(f"{v:.4f}" for v in (x.t, x.x, x.y, x.yaw, x.course, x.speed, x.acceleration)),
                    f"{x.curvature:.5f}",
                    f"{st.s:.4f}",
                    f"{st.d:.4f}",
                    st.status,
                    f"{st.planning_ms:.2f}",
                    folded,
                    st.message,
                ]
            )
    return out


def _summary(results: Sequence[SimResult]) -> str:
    names = [r.problem.options.generator for r in results]
    width = max(len(n) for n, _ in _TABLE_ROWS) + 2
    lines = ["".ljust(width) + "".join(n.ljust(22) for n in names)]
    for name, fmt in _TABLE_ROWS:
        lines.append(name.ljust(width) + "".join(fmt(r.metrics.to_dict()).ljust(22) for r in results))
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------------
# Commands
# --------------------------------------------------------------------------------------------------


def _load(path: Path) -> PlanningProblem:
    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise PlannerError(f"cannot read {path}: {exc.strerror or exc}") from exc
    except json.JSONDecodeError as exc:
        raise PlannerError(f"{path} is not JSON: {exc}") from exc
    return problem_from_json(data)


def _run(problem: PlanningProblem, generator: Generator, args: argparse.Namespace) -> SimResult:
    problem = replace(problem, options=replace(problem.options, generator=generator))
    model = BicycleModel.for_vehicle(problem.vehicle, centre_midway=args.centre_midway)
    goal = None if args.goal_s is None else Goal(s_min=args.goal_s)
    disable = args.quiet or not sys.stderr.isatty()
    with tqdm(total=1, desc=generator, unit="cycle", disable=disable) as bar:

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


def _cmd_simulate(args: argparse.Namespace) -> int:
    problem = _load(args.road)
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    result = _run(problem, args.generator or problem.options.generator, args)
    quiet = args.quiet or not sys.stderr.isatty()
    frames = write_key_frames(result, out, every=args.frame_every)
    if not args.no_gif:
        write_gif([result], out / "sim.gif", stride=args.gif_stride, dpi=args.gif_dpi, quiet=quiet)
    write_steps_csv(result, out / "steps.csv")
    record = {"road": str(args.road), **run_record(result)}
    (out / "metrics.json").write_text(json.dumps(record, indent=1, ensure_ascii=False) + "\n")
    print(_summary([result]))
    print(f"wrote {len(frames)} frames, {'' if args.no_gif else 'sim.gif, '}steps.csv, metrics.json to {out}")
    return 0


def _compare(problem: PlanningProblem, road: str, args: argparse.Namespace) -> int:
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    results = [_run(problem, g, args) for g in GENERATORS]
    quiet = args.quiet or not sys.stderr.isatty()
    write_compare(results, out / "compare.png")
    if not args.no_gif:
        write_gif(results, out / "compare.gif", stride=args.gif_stride, dpi=args.gif_dpi, quiet=quiet)
    for r in results:
        write_steps_csv(r, out / f"steps_{r.problem.options.generator}.csv")
    record = {"road": road, "runs": {r.problem.options.generator: run_record(r) for r in results}}
    (out / "metrics.json").write_text(json.dumps(record, indent=1, ensure_ascii=False) + "\n")
    print(_summary(results))
    print(f"wrote compare.png, {'' if args.no_gif else 'compare.gif, '}steps_*.csv, metrics.json to {out}")
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    return _compare(_load(args.road), str(args.road), args)


def _cmd_demo(args: argparse.Namespace) -> int:
    return _compare(demo_problem(), "built-in demo U-turn (planner.roads.demo_problem)", args)


def _positive(text: str) -> float:
    value = float(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"must be positive: {text}")
    return value


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="kappa-planner",
        description="Closed-loop simulation of the TransF-κ planner: key frames, animation and metrics.",
    )
    sub = parser.add_subparsers(dest="command", required=True)
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--out", type=Path, required=True, help="output directory (created)")
    common.add_argument("--duration", type=_positive, default=None, help="longest simulated time [s]")
    common.add_argument("--replan-period", type=_positive, default=0.1, help="time between plans [s]")
    common.add_argument("--goal-s", type=float, default=None, help="goal: arc length reached [m]")
    common.add_argument("--no-gif", action="store_true", help="skip the animation")
    common.add_argument("--gif-stride", type=int, default=2, help="a GIF frame every N cycles")
    common.add_argument("--gif-dpi", type=int, default=100, help="GIF resolution [px/inch]")
    common.add_argument(
        "--centre-midway",
        action="store_true",
        help="a car referenced midway between its axles: its body yaws against the path by the slip "
        "angle, which the planner's footprint does not model (default: no slip at the centre, the "
        "vehicle the planner's contract describes)",
    )
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

    commonroad.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``kappa-planner``; returns the exit status."""
    args = _parser().parse_args(argv)
    try:
        code: int = args.func(args)
    except PlannerError as exc:
        print(f"kappa-planner: error: {exc}", file=sys.stderr)
        return 2
    return code


if __name__ == "__main__":
    sys.exit(main())
