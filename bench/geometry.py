"""Geometry benchmark: ``python bench/geometry.py`` prints throughput figures (asserts nothing).

* TransF-κ (Cartesian → Frenet) on 100 000 points against a ~2 000-sample reference, next to a plain
  numpy nearest-segment projection of the same points (every point against every segment, chunked).
* Candidate generation with Algorithm 5 repair: 1 000 candidates of 100 points on a U-turn whose
  inner side is wider than its radius (and Algorithm 4 for comparison).

Targets (issue 2): TransF-κ ≥ 2 million points/s; candidates ≥ 100 candidates of 100 points per ms.
"""

from __future__ import annotations

import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.candidates import generate_candidates
from planner.frenet import to_cartesian, to_frenet
from planner.problem import Ego, Lane, Options, Vehicle
from planner.reference import ReferenceLine, build_reference
from planner.roads import u_turn


def timed(fn: Callable[[], object], repeats: int) -> list[float]:
    fn()  # warm up
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def nearest_segment_projection(ref: ReferenceLine, pts: np.ndarray, chunk: int = 500) -> np.ndarray:
    """Plain numpy baseline: orthogonal projection onto the nearest segment, all pairs, chunked."""
    ax, ay = ref.points[:-1, 0], ref.points[:-1, 1]
    ex, ey = ref.seg_dir[:, 0], ref.seg_dir[:, 1]
    s_out = np.empty(pts.shape[0])
    for i in range(0, pts.shape[0], chunk):
        px = pts[i : i + chunk, 0:1] - ax
        py = pts[i : i + chunk, 1:2] - ay
        u = np.clip(px * ex + py * ey, 0.0, ref.seg_len)
        dist = (px - u * ex) ** 2 + (py - u * ey) ** 2
        j = np.argmin(dist, axis=1)
        s_out[i : i + chunk] = ref.s[j] + u[np.arange(j.size), j]
    return s_out


def nearest_point_projection(ref: ReferenceLine, pts: np.ndarray) -> np.ndarray:
    """The usual planner projection: nearest sample (k-d tree), then the better adjacent segment."""
    _, m = ref.tree.query(pts, workers=-1)
    best = np.full(pts.shape[0], np.inf)
    s_out = np.zeros(pts.shape[0])
    for j in (np.maximum(m - 1, 0), np.minimum(m, ref.size - 2)):
        rel = pts - ref.points[j]
        u = np.clip(np.einsum("ij,ij->i", rel, ref.seg_dir[j]), 0.0, ref.seg_len[j])
        dist = np.linalg.norm(rel - u[:, None] * ref.seg_dir[j], axis=1)
        closer = dist < best
        best = np.where(closer, dist, best)
        s_out = np.where(closer, ref.s[j] + u, s_out)
    return s_out


def bench_projection() -> None:
    x = np.linspace(0.0, 1000.0, 401)
    road = np.column_stack((x, 30.0 * np.sin(x / 80.0)))
    ref = build_reference(road, max_spacing=0.5)
    rng = np.random.default_rng(0)
    n = 100_000
    pts = to_cartesian(ref, rng.uniform(0.0, ref.length, n), rng.uniform(-6.0, 6.0, n))
    few = pts[:10_000]
    rows = (
        ("TransF-κ", pts, lambda: to_frenet(ref, pts), 7),
        ("nearest point (k-d tree)", pts, lambda: nearest_point_projection(ref, pts), 7),
        ("numpy all segments", few, lambda: nearest_segment_projection(ref, few), 2),
    )
    print(f"reference: {ref.size} samples, spacing {ref.spacing:.3f} m, length {ref.length:.0f} m")
    for name, p, fn, repeats in rows:
        times = timed(fn, repeats=repeats)
        med = statistics.median(times)
        print(
            f"{name:26s} {p.shape[0]:6d} points: median {med * 1e3:8.1f} ms → "
            f"{p.shape[0] / med / 1e6:5.2f} M points/s (min {min(times) * 1e3:.1f} ms)"
        )
    print("target: TransF-κ ≥ 2 M points/s")


def bench_candidates() -> None:
    ref = build_reference(u_turn(radius=6.0, leg=40.0, step=1.0))
    lane = Lane(left_width=10.0, right_width=3.5)
    ego = Ego(x=-20.0, y=0.0, heading=0.0, speed=5.0)
    n, p = 1000, 100
    print(f"U-turn: radius 6 m, inner width 10 m, reference {ref.size} samples")
    for generator in ("transf_kappa", "naive"):
        options = Options(num_candidates=n, num_points=p, generator=generator, target_speed=7.0)  # type: ignore[arg-type]
        times = timed(lambda o=options: generate_candidates(ref, lane, ego, Vehicle(), o), repeats=15)
        med = statistics.median(times)
        cands = generate_candidates(ref, lane, ego, Vehicle(), options)
        print(
            f"candidates {generator:12s} {n} × {p} points: median {med * 1e3:6.1f} ms "
            f"→ {n / (med * 1e3):6.1f} candidates/ms  (target ≥ 100/ms; "
            f"repaired {int(cands.repaired.sum())}, points jumped {int((~cands.valid).sum())})"
        )


def main() -> None:
    print(f"python {platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} cores")
    bench_projection()
    bench_candidates()


if __name__ == "__main__":
    main()
