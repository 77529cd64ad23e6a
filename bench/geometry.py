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


def nearest_segment_projection(ref: ReferenceLine, pts: np.ndarray, chunk: int = 2_000) -> np.ndarray:
    """Plain numpy baseline: orthogonal projection onto the nearest segment, all pairs, chunked."""
    a = ref.points[:-1]
    e = ref.seg_dir
    ell = ref.seg_len
    s_out = np.empty(pts.shape[0])
    for i in range(0, pts.shape[0], chunk):
        p = pts[i : i + chunk, None, :] - a[None, :, :]
        u = np.clip(np.einsum("ijk,jk->ij", p, e), 0.0, ell)
        foot = p - u[..., None] * e[None, :, :]
        dist = np.einsum("ijk,ijk->ij", foot, foot)
        j = np.argmin(dist, axis=1)
        s_out[i : i + chunk] = ref.s[j] + u[np.arange(j.size), j]
    return s_out


def bench_projection() -> None:
    x = np.linspace(0.0, 1000.0, 401)
    road = np.column_stack((x, 30.0 * np.sin(x / 80.0)))
    ref = build_reference(road, max_spacing=0.5)
    rng = np.random.default_rng(0)
    n = 100_000
    pts = to_cartesian(ref, rng.uniform(0.0, ref.length, n), rng.uniform(-6.0, 6.0, n))
    t_kappa = timed(lambda: to_frenet(ref, pts), repeats=7)
    t_plain = timed(lambda: nearest_segment_projection(ref, pts), repeats=2)
    med_k, med_p = statistics.median(t_kappa), statistics.median(t_plain)
    print(f"reference: {ref.size} samples, spacing {ref.spacing:.3f} m, length {ref.length:.0f} m")
    print(
        f"TransF-κ            {n} points: median {med_k * 1e3:7.1f} ms  "
        f"→ {n / med_k / 1e6:5.2f} M points/s   (target ≥ 2 M/s; min {min(t_kappa) * 1e3:.1f} ms)"
    )
    print(
        f"numpy nearest-seg.  {n} points: median {med_p * 1e3:7.1f} ms  "
        f"→ {n / med_p / 1e6:5.2f} M points/s   (all pairs, chunked)"
    )


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
