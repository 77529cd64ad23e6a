"""Closed loops on seeded random scenes, for the bench scripts that drive many of them
(``bench/borrow_loops.py``, ``bench/pass_loops.py``): their arguments, one simulated run per seed, the
failures every such script reports, and the cycles per status over all runs; and the predictions of the
vehicles they drive along the reference (:func:`along_reference`).

    for loop in seeded_loops(__doc__, 10.0, argv, scene, lambda sc: sc.problem):
        loop.report(loop.failures + [...])   # what else this script counts as gone wrong (loop.scene)
"""

from __future__ import annotations

import argparse
import collections
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

from planner.frenet import to_cartesian
from planner.problem import PlanningProblem
from planner.reference import FloatArray, ReferenceLine
from planner_tools.sim import SimResult, simulate

#: a script's scene: what it draws from a seed
Scene = TypeVar("Scene")


@dataclass(frozen=True)
class Loop(Generic[Scene]):
    """One seed's run: its ``scene``, the ``result`` and how many cycles ended in each status (``counts``)."""

    seed: int
    scene: Scene
    result: SimResult
    counts: collections.Counter[str]

    @property
    def failures(self) -> list[str]:
        """What went wrong in any such run: cycles that fell back or raised, contacts with obstacles."""
        out = [f"{name} {self.counts[name]}" for name in ("fallback", "error") if self.counts[name]]
        metrics = self.result.metrics
        if metrics.collisions:
            out.append(f"collision with {', '.join(metrics.collided_with)}")
        return out

    def report(self, problems: Sequence[str]) -> None:
        """Print the run (seed, statuses, where it ended) with ``problems``, if there are any."""
        if problems:
            m = self.result.metrics
            end = f"{m.termination} at s = {m.final_s:.1f} m"
            print(f"seed {self.seed}: {dict(self.counts)}, {end}: {'; '.join(problems)}")


def seeded_loops(
    doc: str | None,
    duration: float,
    argv: list[str] | None,
    scene_of: Callable[[int], Scene],
    problem_of: Callable[[Scene], PlanningProblem],
) -> Iterator[Loop[Scene]]:
    """Parse ``--runs``, ``--seed`` and ``--duration`` (default ``duration`` [s]) from ``argv`` (the
    script's ``doc`` its description), drive the problem of each seed's scene in closed loop
    (:func:`planner_tools.sim.simulate`) and yield the runs; when they are done, print how many ran, for
    how long, and the cycles per status over all."""
    parser = argparse.ArgumentParser(description=(doc or "").split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=100, help="how many scenes")
    parser.add_argument("--seed", type=int, default=0, help="the first scene's seed (then one up)")
    parser.add_argument("--duration", type=float, default=duration, help="simulated seconds per run")
    args = parser.parse_args(argv)
    statuses: collections.Counter[str] = collections.Counter()
    began = time.perf_counter()
    for seed in range(args.seed, args.seed + args.runs):
        scene = scene_of(seed)
        result = simulate(problem_of(scene), duration=args.duration)
        counts: collections.Counter[str] = collections.Counter(step.status for step in result.steps)
        statuses.update(counts)
        yield Loop(seed, scene, result, counts)
    wall = time.perf_counter() - began
    print(f"{args.runs} runs of {args.duration:g} s ({wall:.0f} s wall): cycles {dict(statuses)}")


def along_reference(
    ref: ReferenceLine, t: FloatArray, s: FloatArray, d: float, backwards: bool = False
) -> FloatArray:
    """A prediction (rows ``t, x, y, heading``) of a vehicle at arc lengths ``s`` [m] at times ``t`` [s],
    ``d`` [m] beside the reference, heading along it (against it if ``backwards``)."""
    xy = to_cartesian(ref, s, np.full_like(s, d))
    heading = ref.heading_at(s) + (math.pi if backwards else 0.0)
    return np.column_stack((t, xy[:, 0], xy[:, 1], heading))
