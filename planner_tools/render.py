"""Drawings of the planner at work (matplotlib): closed-loop runs and candidate fans.

* :func:`write_key_frames` — a PNG of a run every few seconds and of its final state;
* :func:`write_gif` — an animation of runs side by side, in real time;
* :func:`write_compare` — Fig. 4 of the paper: a row per run, a column per point of progress along the
  reference, and the metrics table (:data:`planner_tools.records.METRIC_ROWS`);
* :func:`candidates_figure` — the candidates of Algorithm 4 (``naive``) and Algorithm 5
  (``transf_kappa``) side by side on the demo U-turn, whose inner side is wider than its radius: naive
  candidates that run backwards or cross themselves in red, the rest in blue.

* :func:`road_candidates_figure` — the same on a U-turn whose road (beyond a lane blocked by a parked
  car) is wider on the inside than the turn's radius: the candidates of the corridor the lane decision
  borrows (:mod:`planner.decision`).

A panel shows the road (lane edges, and the road's when the problem has one, where ``κ·d < 1``; the
reference), static obstacles, and per cycle the candidates (orange: those that fold back), the plan, the
driven path, the vehicle's footprint and the moving obstacles. Needs the optional extra ``tools``
(matplotlib, Pillow, tqdm).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Polygon
from matplotlib.text import Text
from PIL import Image
from tqdm import tqdm

from planner.candidates import CandidateSet, generate_candidates
from planner.collision import box_corners
from planner.frenet import to_cartesian
from planner.lane import lane_bounds
from planner.pipeline import plan
from planner.problem import (
    CircleObstacle,
    DynamicObstacle,
    Generator,
    Lane,
    PlanningProblem,
    PolygonObstacle,
)
from planner.reference import ReferenceLine, build_reference
from planner.roads import demo_problem, wide_u_turn_problem
from planner.validation import folds_back
from planner_tools.records import METRIC_ROWS
from planner_tools.sim import SimResult, obstacle_outlines

#: panel title of each generator
TITLES = {"naive": "Algorithm 4 (naive offsets)", "transf_kappa": "Algorithm 5 (TransF-κ)"}
#: colours: candidates that are fine / fold back, the plan, the driven path, the vehicle
C_CAND, C_FOLD, C_PLAN, C_DRIVEN, C_EGO = "tab:blue", "tab:orange", "crimson", "black", "tab:green"
#: the vehicle's colour once it has collided
C_HIT = "tab:red"
#: the road beyond the lane: its surface and its edges
C_ROAD, C_ROAD_EDGE = "0.85", "tab:brown"


# --------------------------------------------------------------------------------------------------
# Closed-loop runs
# --------------------------------------------------------------------------------------------------


class _Panel:
    """One axes showing one run at a chosen cycle; static road drawn once, the rest updated per frame."""

    def __init__(self, ax: Axes, result: SimResult, title: str) -> None:
        self.ax, self.result, self.title = ax, result, title
        problem, ref = result.problem, result.reference
        edges = _draw_edges(ax, ref, problem)
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


def _edges(ref: ReferenceLine, widths: Lane) -> list[np.ndarray]:
    """The left and right edges of a lane or road (n, 2) [m], NaN where an edge lies beyond the
    reference's centre of curvature (κ·d ≥ 1: it would fold back on itself)."""
    bounds = lane_bounds(ref, widths, ref.s, half_width=0.0, margin=0.0)
    return [
        np.where((ref.kappa * w < 1.0)[:, None], to_cartesian(ref, ref.s, w), np.nan)
        for w in (bounds.upper, bounds.lower)
    ]


def _draw_edges(ax: Axes, ref: ReferenceLine, problem: PlanningProblem) -> list[np.ndarray]:
    """Draw the lane's edges and, when the problem has a road, the road's (lighter, with the road's
    surface shaded); returns every edge drawn."""
    edges = _edges(ref, problem.lane)
    if problem.road is not None:
        road = _edges(ref, problem.road)
        finite = [e[np.isfinite(e[:, 0])] for e in road]
        if all(f.shape[0] > 1 for f in finite):
            ax.fill(*np.vstack((finite[0], finite[1][::-1])).T, color=C_ROAD, alpha=0.35, lw=0, zorder=0)
        for edge in road:
            ax.plot(edge[:, 0], edge[:, 1], "-", color=C_ROAD_EDGE, lw=1.0)
        edges += road
    for edge in edges[:2]:
        ax.plot(edge[:, 0], edge[:, 1], "-", color="0.3", lw=1.1)
    return edges


def _legend(fig: Figure, *, outside: bool = False, road: bool = False) -> None:
    handles = [
        Line2D([], [], color=C_CAND, lw=1, label="candidates"),
        Line2D([], [], color=C_FOLD, lw=1, label="candidates that fold back"),
        Line2D([], [], color=C_PLAN, lw=2, label="plan"),
        Line2D([], [], color=C_DRIVEN, lw=1.6, label="driven"),
        Line2D([], [], color="0.55", ls="--", lw=1, label="reference"),
    ]
    if road:
        handles += [
            Line2D([], [], color="0.3", lw=1.1, label="lane edge"),
            Line2D([], [], color=C_ROAD_EDGE, lw=1.0, label="road edge"),
        ]
    ncol = len(handles) if len(handles) <= 5 else (len(handles) + 1) // 2
    if outside:
        fig.legend(handles=handles, loc="outside lower center", ncol=ncol, fontsize=8, frameon=False)
    else:
        fig.legend(handles=handles, loc="lower center", ncol=ncol, fontsize=8, frameon=False)


def write_gif(
    results: Sequence[SimResult],
    out: Path,
    *,
    stride: int = 2,
    dpi: int = 100,
    quiet: bool = True,
    panel_size: tuple[float, float] = (5.2, 3.4),
) -> Path:
    """An animation of the runs side by side, one frame every ``stride`` cycles, in real time, each panel
    ``panel_size`` inches (width, height).

    Frames are mapped without dithering onto a small fixed palette of the figures' colours and their
    blends with white (flat areas stay flat, so the GIF compresses well)."""
    width, height = panel_size
    figsize = (width * len(results), height)
    fig, axes = plt.subplots(1, len(results), figsize=figsize, squeeze=False, dpi=dpi)
    panels = [
        _Panel(ax, r, TITLES.get(r.problem.options.generator, r.problem.options.generator))
        for ax, r in zip(axes[0], results, strict=True)
    ]
    _legend(fig, road=any(r.problem.road is not None for r in results))
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
    base = [to_rgb(c) for c in (C_CAND, C_FOLD, C_PLAN, C_EGO, "tab:red", "tab:purple", C_ROAD_EDGE)]
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
    _legend(fig, road=result.problem.road is not None)
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
    cells = [[fmt(m) for m in metrics] for _, fmt in METRIC_ROWS]
    table = table_ax.table(
        cellText=cells,
        rowLabels=[name for name, _ in METRIC_ROWS],
        colLabels=[TITLES.get(m["generator"], m["generator"]) for m in metrics],
        loc="center",
        cellLoc="center",
        colWidths=[0.25] * len(metrics),
    )
    table.auto_set_font_size(False)
    table.set_fontsize(8)
    table.scale(1.0, 1.15)
    _legend(fig, outside=True, road=any(r.problem.road is not None for r in results))
    fig.suptitle(
        "Closed loop on the same road: candidates and plan at equal progress along the reference", fontsize=11
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out


# --------------------------------------------------------------------------------------------------
# Candidates of Algorithm 4 and 5
# --------------------------------------------------------------------------------------------------


def _draw_road(ax: Axes, ref: ReferenceLine, problem: PlanningProblem) -> None:
    _draw_edges(ax, ref, problem)
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


def road_candidates_figure(out: Path, *, num_candidates: int = 40, seed: int = 0) -> Path:
    """Draw Algorithm 4 vs Algorithm 5 candidates of the corridor the lane decision borrows on
    :func:`planner.roads.wide_u_turn_problem` into ``out`` (PNG)."""
    problem = wide_u_turn_problem()
    problem = replace(problem, options=replace(problem.options, num_candidates=num_candidates, seed=seed))
    ref = build_reference(problem.reference_line)
    decision = plan(problem).diagnostics.decision
    if decision.corridor is None:
        raise RuntimeError(f"the scene does not borrow the road: {decision.reason.message}")
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.5), sharex=True, sharey=True)
    panels: tuple[tuple[Axes, Generator, str], ...] = (
        (axes[0], "naive", "Algorithm 4 (naive offsets)"),
        (axes[1], "transf_kappa", "Algorithm 5 (TransF-κ repair)"),
    )
    for ax, generator, title in panels:
        options = replace(problem.options, generator=generator)
        cands = generate_candidates(ref, decision.corridor, problem.ego, problem.vehicle, options)
        _draw_road(ax, ref, problem)
        broken = _draw_candidates(ax, ref, cands)
        ax.set_title(f"{title}\n{broken} of {cands.count} run backwards or self-intersect")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.set_xlabel("x [m]")
        ax.set_xlim(-30.0, 18.0)
        ax.set_ylim(-6.0, 24.0)
    axes[0].set_ylabel("y [m]")
    axes[0].legend(loc="lower left")
    fig.suptitle(f"{decision.lane}: {decision.reason.message}", fontsize=10)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
