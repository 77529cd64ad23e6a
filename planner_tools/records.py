"""What a closed-loop run leaves on disk and on the terminal: ``metrics.json``, ``steps.csv``, the table.

* :func:`run_record` — a run's settings (replan period, vehicle model, goal) and its metrics, the data
  of ``metrics.json`` (:func:`write_json` writes it);
* :func:`write_steps_csv` — one row per replan cycle: the vehicle's state, the plan's status and
  planning time;
* :data:`METRIC_ROWS` — the rows of the metrics table, shared by :func:`summary` (text, one column per
  run) and the side-by-side figure (:func:`planner_tools.render.write_compare`).

Needs only the service's dependencies. Units: metres [m], seconds [s], radians [rad].
"""

from __future__ import annotations

import csv
import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from planner_tools.sim import SimResult

#: the metrics table: a row label and how it shows a run's ``metrics.to_dict()``
METRIC_ROWS: tuple[tuple[str, Callable[[dict[str, Any]], str]], ...] = (
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


def write_json(data: dict[str, Any], out: Path) -> Path:
    """``data`` as indented JSON with its non-ASCII characters kept (``metrics.json``)."""
    out.write_text(json.dumps(data, indent=1, ensure_ascii=False) + "\n")
    return out


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


def summary(results: Sequence[SimResult]) -> str:
    """The metrics table as text: a row per :data:`METRIC_ROWS` entry, a column per run."""
    names = [r.problem.options.generator for r in results]
    width = max(len(n) for n, _ in METRIC_ROWS) + 2
    lines = ["".ljust(width) + "".join(n.ljust(22) for n in names)]
    for name, fmt in METRIC_ROWS:
        lines.append(name.ljust(width) + "".join(fmt(r.metrics.to_dict()).ljust(22) for r in results))
    return "\n".join(lines)
