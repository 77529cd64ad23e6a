"""Borrowing the road in closed loop on random scenes: ``python bench/borrow_loops.py`` drives, per run, a
car or a point-model vehicle towards a lane-wide truck, parked or (in 40 % of the runs) crawling along the
lane, with the opposite lane in ``road``, and in 60 % of the runs an oncoming car in that lane, and prints
how the runs went (asserts nothing).

A scene (seeded, so each run is reproducible by its seed): a straight, or a bend of radius 50–250 m
between straights; the lane ±1.75 m, the road 3.5 m wider on the left (the opposite lane) and up to 1 m
on the right; the ego on the reference at 0–12 m/s; the truck 6–12 m long and 2.6–3.3 m wide, centred
within 0.2 m of the reference 15–70 m beyond the ego's stopping distance, crawling at 0.5–4 m/s in 40 %
of the runs (drawn apart: the other draws of a seed are those of a parked truck); the oncoming car
4.5 × 1.8 m at 4–15 m/s in the middle of the opposite lane, starting 10–160 m beyond the truck. Each run
replans every 0.1 s for ``--duration`` seconds (:func:`planner_tools.sim.simulate`).

Printed: the cycles per status, how many runs got past the truck (parked or crawling, with and without
oncoming traffic), and every run with a collision, a departure from the road, a fallback, an error, or
no oncoming traffic and yet not past the truck where it is at the end (its seed, statuses, end and arc
length).

    python bench/borrow_loops.py                       # 100 runs from seed 0
    python bench/borrow_loops.py --runs 300 --seed 700000 --duration 16
"""

from __future__ import annotations

import collections
import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from planner.frenet import to_cartesian  # noqa: E402 (after the path fix)
from planner.reference import build_reference  # noqa: E402
from planner.roads import arc, straight  # noqa: E402
from planner_tools.io import problem_from_json  # noqa: E402
from planner_tools.loops import along_reference, seeded_loops  # noqa: E402

#: a run's footprint this far outside the road [m] is a departure
DEPARTURE = 0.02


@dataclass(frozen=True)
class Scene:
    """A run's request (the planner's JSON) and where its truck is: arc length of its centre at the
    start, its length [m] and its speed [m/s]; whether an oncoming car is in it."""

    request: dict[str, Any]
    truck_s: float
    truck_length: float
    truck_speed: float
    oncoming: bool


def _road(rng: np.random.Generator) -> np.ndarray:
    """A straight, or a bend between straights [m] (points 0.5 m apart)."""
    if rng.random() < 1.0 / 3.0:
        return np.asarray(straight(260.0, step=0.5))
    lead = np.asarray(straight(30.0, step=0.5))
    radius, angle = float(rng.uniform(50, 250)), float(rng.uniform(0.3, 1.2)) * float(rng.choice([-1, 1]))
    bend = np.asarray(arc(radius, angle, step=0.5))
    points = np.vstack([lead, (bend - bend[0] + lead[-1])[1:]])
    heading = math.atan2(points[-1, 1] - points[-2, 1], points[-1, 0] - points[-2, 0])
    tail = np.asarray(straight(150.0, heading=heading, step=0.5))
    return np.vstack([points, (tail - tail[0] + points[-1])[1:]])


def scene(seed: int) -> Scene:
    """The scene of ``seed`` (module docstring)."""
    rng = np.random.default_rng(seed)
    points = _road(rng)
    ref = build_reference(points)

    def at(s: float, d: float) -> tuple[float, float, float]:
        """``(x, y, heading)`` [m, rad] at Frenet ``(s, d)`` (TransF-κ's inverse)."""
        x, y = to_cartesian(ref, s, d)
        return float(x), float(y), float(ref.heading_at(s))

    vehicle: dict[str, float] = {
        "length": 4.5,
        "width": 1.8,
        "max_speed": 20.0,
        "max_acceleration": 2.5,
        "max_deceleration": 7.0,
        "max_lateral_acceleration": 4.0,
        "max_curvature": 0.22,
    }
    if rng.random() < 0.5:
        vehicle |= {"wheelbase": 2.7, "rear_axle_offset": 1.35}
    s0, v0 = 10.0, float(rng.uniform(0, 12))
    x0, y0, h0 = at(s0, 0.0)
    request: dict[str, Any] = {
        "reference_line": points.round(4).tolist(),
        "lane": {"left_width": 1.75, "right_width": 1.75},
        "road": {"left_width": 1.75 + 3.5, "right_width": 1.75 + float(rng.uniform(0, 1.0))},
        "ego": {"x": x0, "y": y0, "heading": h0, "speed": v0, "acceleration": 0.0},
        "vehicle": vehicle,
        "obstacles": [],
        "options": {"target_speed": 10.0},
    }
    truck_s = s0 + v0**2 / 7.0 + 10.0 + float(rng.uniform(15, 70))
    length, width = float(rng.uniform(6, 12)), float(rng.uniform(2.6, 3.3))
    offset = float(rng.uniform(-0.2, 0.2))
    moving = np.random.default_rng((seed, 1))  # apart: a crawling truck leaves the other draws as they were
    crawl = float(moving.uniform(0.5, 4.0)) if moving.random() < 0.4 else 0.0
    if crawl > 0.0:
        times = np.arange(0.0, 20.0 + 1e-9, 0.2)
        states = _states(along_reference(ref, times, truck_s + crawl * times, offset))
        request["obstacles"].append({"id": "truck", "length": length, "width": width, "prediction": states})
    else:
        xc, yc, hc = at(truck_s, offset)
        along, across = np.array([math.cos(hc), math.sin(hc)]), np.array([-math.sin(hc), math.cos(hc)])
        corners = [
            np.array([xc, yc]) + sx * length / 2 * along + sy * width / 2 * across
            for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1))
        ]
        request["obstacles"].append({"id": "truck", "polygon": [c.tolist() for c in corners]})
    oncoming = bool(rng.random() < 0.6)
    if oncoming:
        start, speed = truck_s + float(rng.uniform(10, 160)), float(rng.uniform(4, 15))
        times = np.arange(0.0, 16.0 + 1e-9, 0.2)
        times = times[start - speed * times >= 0.0]  # until it leaves the reference's start
        states = _states(along_reference(ref, times, start - speed * times, 3.5, backwards=True))
        request["obstacles"].append({"id": "oncoming", "length": 4.5, "width": 1.8, "prediction": states})
    return Scene(request, truck_s, length, crawl, oncoming)


def _states(prediction: np.ndarray) -> list[dict[str, float]]:
    """A prediction's rows ``t, x, y, heading`` as the request's states."""
    return [{"t": t, "x": x, "y": y, "heading": h} for t, x, y, h in prediction.tolist()]


def main(argv: list[str] | None = None) -> int:
    past: collections.Counter[tuple[bool, bool, bool]] = collections.Counter()
    for loop in seeded_loops(__doc__, 16.0, argv, scene, lambda sc: problem_from_json(sc.request)):
        sc, m = loop.scene, loop.result.metrics
        truck_end = sc.truck_s + sc.truck_speed * float(loop.result.motion.t[-1])
        got_past = m.final_s > truck_end + sc.truck_length / 2 + 5.0
        past[(sc.truck_speed > 0.0, sc.oncoming, got_past)] += 1
        problems = loop.failures
        if m.max_road_departure is not None and m.max_road_departure > DEPARTURE:
            problems.append(f"{m.max_road_departure:.2f} m off the road")
        if not sc.oncoming and not got_past:
            problems.append("not past the truck, no oncoming traffic")
        loop.report(problems)
    for moving in (False, True):
        for oncoming in (False, True):
            got, total = (
                past[(moving, oncoming, True)],
                past[(moving, oncoming, True)] + past[(moving, oncoming, False)],
            )
            label = ("crawling" if moving else "parked") + (
                ", an oncoming car" if oncoming else ", no oncoming traffic"
            )
            print(f"  {label}: {got} of {total} past the truck")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
