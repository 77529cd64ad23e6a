"""The run file of a closed-loop run: what ``/viewer`` plays back cycle by cycle (``run.json.gz``).

:func:`run_data` turns a :class:`~planner_tools.sim.SimResult` into plain JSON data and
:func:`write_run` writes it; :func:`decode` reads a series back (the viewer's ``viewer.js`` does the
same in the browser). The format is described by the JSON Schema ``app/static/viewer/run.schema.json``
(served at ``/viewer/run.schema.json``) and, in short:

* ``format`` ``"kappa-planner-run"``, ``version`` 1; ``source`` (what was run), ``request`` (the
  planning request at t = 0, as ``POST /v1/plan`` takes it plus the planner's own options),
  ``generator``, ``replan_period`` [s], ``duration`` [s], ``termination``, ``goal``, ``metrics``;
* ``scale``: every numeric series is **fixed point and delta coded**: a list of integers whose
  running sum divided by ``scale[name]`` is the value (``xy`` series interleave ``x, y`` and sum each
  separately); :data:`SCALE` is the precision (1 cm, 1 mrad, 1 cm/s, 1 cm/s², 10⁻⁴ 1/m);
* ``driven``: the executed motion at every simulator sub-step (``t`` [s], ``xy`` [m], ``yaw`` [rad],
  ``v`` [m/s], ``s``, ``d`` [m] on the reference, ``cycle``: the index of the cycle each sample
  belongs to);
* ``cycles``: one per replan: ``t`` [s], ``state`` ``[x, y, yaw, v]``, ``status``, ``message``,
  ``planning_ms``, ``chosen`` (candidate index or null), ``trajectory`` (its ``dt`` and the series
  ``xy``, ``heading``, ``curvature``, ``v``, ``a``, ``s``, ``d``; null when planning failed),
  ``candidates`` (the points each kept, an ``xy`` series per candidate), ``folded`` (indices of the
  candidates that run backwards along the reference or cross themselves as planned) and
  ``alg4_folds`` (indices of the candidates whose Algorithm 4 version — the naive offsets of the same
  seed from the same state — folds: for a ``naive`` run the same as ``folded``).

The file is that JSON, compact and gzip-compressed (the viewer reads it compressed or not): the demo
run (248 cycles of 32 candidates × 100 points) is 5.3 MB of JSON and 0.5 MB compressed. The size is
the candidates' (every kept point, so that Algorithm 5's jumps stay visible), and their fixed-point
deltas repeat along each candidate, which is what gzip compresses well.
"""

from __future__ import annotations

import gzip
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from planner.candidates import ego_frenet, generate_candidates
from planner.reference import FloatArray
from planner_tools.io import problem_to_json
from planner_tools.records import run_record
from planner_tools.sim import SimResult, SimStep, folded_candidates, problem_at

FORMAT = "kappa-planner-run"
VERSION = 1

#: fixed-point scale of each series: the value is the integer's running sum divided by this
SCALE: dict[str, int] = {
    "t": 1000,  # 1 ms
    "xy": 100,  # 1 cm
    "yaw": 1000,  # 1 mrad
    "heading": 1000,
    "curvature": 10_000,  # 10⁻⁴ 1/m
    "v": 100,  # 1 cm/s
    "a": 100,  # 1 cm/s²
    "s": 100,
    "d": 100,
}


def encode(values: ArrayLike, scale: int) -> list[int]:
    """A series as fixed-point deltas: ``round(value·scale)``, each less the previous one."""
    q = np.round(np.asarray(values, dtype=float) * scale).astype(np.int64)
    return np.diff(q, prepend=np.int64(0)).tolist()


def encode_xy(xy: ArrayLike, scale: int = SCALE["xy"]) -> list[int]:
    """Points (n, 2) as one list ``[x₀, y₀, Δx₁, Δy₁, …]`` of fixed-point deltas."""
    q = np.round(np.asarray(xy, dtype=float).reshape(-1, 2) * scale).astype(np.int64)
    return np.diff(q, axis=0, prepend=np.zeros((1, 2), dtype=np.int64)).ravel().tolist()


def decode(series: list[int], scale: int, *, pairs: bool = False) -> FloatArray:
    """The values of an encoded series: shape (n,), or (n, 2) with ``pairs``."""
    q = np.asarray(series, dtype=np.int64)
    if pairs:
        q = q.reshape(-1, 2)
    return np.cumsum(q, axis=0) / float(scale)


def _trajectory(step: SimStep) -> dict[str, Any] | None:
    traj = step.trajectory
    if traj is None:
        return None
    dt = float(np.median(np.diff(traj.t))) if traj.size > 1 else 0.0
    out: dict[str, Any] = {"dt": round(dt, 6), "xy": encode_xy(np.column_stack((traj.x, traj.y)))}
    for name in ("heading", "curvature", "v", "a", "s", "d"):
        out[name] = encode(getattr(traj, name), SCALE[name])
    return out


def _candidates(step: SimStep) -> list[list[int]]:
    xy = step.candidates_xy
    if xy is None:
        return []
    return [encode_xy(c[np.isfinite(c).all(axis=1)]) for c in xy]


def _indices(flags: ArrayLike | None) -> list[int]:
    return [] if flags is None else np.flatnonzero(np.asarray(flags, dtype=bool)).tolist()


def alg4_folds(result: SimResult, step: SimStep) -> list[int]:
    """Indices of the candidates of ``step`` whose Algorithm 4 version folds back.

    A naive run's candidates are Algorithm 4's: their own fold flags. Otherwise the naive candidates
    are generated again from the cycle's state with the same options and seed (the same end offsets
    and transition lengths, candidate by candidate) and tested the same way
    (:func:`planner_tools.sim.folded_candidates`).
    """
    if step.candidates_xy is None:
        return []
    problem = result.problem
    if problem.options.generator == "naive":
        return _indices(step.candidates_folded)
    naive = problem_at(replace(problem, options=replace(problem.options, generator="naive")), step.state)
    ref = result.reference
    cands = generate_candidates(
        ref, naive.lane, naive.ego, naive.vehicle, naive.options, start=ego_frenet(ref, naive.ego)
    )
    return _indices(folded_candidates(ref, cands))


def run_data(result: SimResult, source: dict[str, Any] | None = None) -> dict[str, Any]:
    """The run file's data of ``result`` (see the module docstring); ``source`` says what was run."""
    motion = result.motion
    record = run_record(result)
    cycles = []
    for step in result.steps:
        st = step.state
        cycles.append(
            {
                "t": round(st.t, 6),
                "state": [round(st.x, 3), round(st.y, 3), round(st.yaw, 4), round(st.speed, 3)],
                "status": step.status,
                "message": step.message,
                "planning_ms": round(step.planning_ms, 2),
                "chosen": step.chosen,
                "trajectory": _trajectory(step),
                "candidates": _candidates(step),
                "folded": _indices(step.candidates_folded),
                "alg4_folds": alg4_folds(result, step),
            }
        )
    return {
        "format": FORMAT,
        "version": VERSION,
        "source": source or {},
        "request": problem_to_json(result.problem),
        "generator": result.problem.options.generator,
        "replan_period": result.replan_period,
        "duration": round(result.duration, 6),
        "termination": result.termination,
        "goal": record["goal"],
        "metrics": record["metrics"],
        "scale": SCALE,
        "driven": {
            "t": encode(motion.t, SCALE["t"]),
            "xy": encode_xy(np.column_stack((motion.x, motion.y))),
            "yaw": encode(motion.yaw, SCALE["yaw"]),
            "v": encode(motion.v, SCALE["v"]),
            "s": encode(motion.s, SCALE["s"]),
            "d": encode(motion.d, SCALE["d"]),
            "cycle": motion.step.tolist(),
        },
        "cycles": cycles,
    }


def write_run(result: SimResult, out: Path, source: dict[str, Any] | None = None) -> Path:
    """Write the run file of ``result`` to ``out`` (compact JSON, UTF-8, gzip-compressed with no
    timestamp, so that the same run gives the same bytes); returns ``out``."""
    text = json.dumps(run_data(result, source), separators=(",", ":"), ensure_ascii=False, allow_nan=False)
    out.write_bytes(gzip.compress(text.encode("utf-8"), compresslevel=6, mtime=0))
    return out


def read_run(path: Path) -> dict[str, Any]:
    """The data of a run file, compressed or not."""
    raw = path.read_bytes()
    if raw[:2] == b"\x1f\x8b":
        raw = gzip.decompress(raw)
    data: dict[str, Any] = json.loads(raw)
    return data
