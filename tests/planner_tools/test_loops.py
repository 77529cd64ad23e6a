"""Seeded closed loops for the bench scripts, and the vehicles they drive (planner_tools.loops)."""

from __future__ import annotations

import numpy as np
import pytest

from planner.problem import PlanningProblem
from planner.reference import build_reference
from planner.roads import box, straight, two_lane_problem
from planner_tools.loops import along_reference, seeded_loops


def _scene(seed: int) -> PlanningProblem:
    """A free straight for even seeds; for odd ones a box on the ego where it starts."""
    obstacles = (box("wall", 0.0, 0.0, 2.0, 2.0),) if seed % 2 else ()
    return two_lane_problem(straight(120.0), speed=5.0, obstacles=obstacles)  # type: ignore[arg-type]


def test_each_seed_runs_once_and_what_went_wrong_is_reported(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["--runs", "2", "--seed", "4", "--duration", "1"]
    loops = []
    for loop in seeded_loops("Runs.\n\nMore.", 10.0, argv, _scene, lambda problem: problem):
        loops.append(loop)
        loop.report([*loop.failures, "and this"] if loop.failures else [])
    assert [loop.seed for loop in loops] == [4, 5]
    free, hit = loops
    assert free.scene.obstacles == () and free.failures == []
    assert sum(free.counts.values()) == len(free.result.steps) > 0
    assert any(problem.startswith("collision with wall") for problem in hit.failures)
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 2  # the free run prints nothing; then the summary
    assert out[0].startswith("seed 5: ") and out[0].endswith("; and this")
    assert out[1].startswith("2 runs of 1 s (") and "cycles {" in out[1]


def test_a_vehicle_along_the_reference_is_where_and_heading_as_asked() -> None:
    ref = build_reference(straight(120.0))
    t = np.linspace(0.0, 4.0, 5)
    ahead = along_reference(ref, t, 10.0 + 3.0 * t, 1.5)
    np.testing.assert_allclose(ahead, np.column_stack((t, 10.0 + 3.0 * t, np.full(5, 1.5), np.zeros(5))))
    towards = along_reference(ref, t, 50.0 - 3.0 * t, -1.5, backwards=True)
    np.testing.assert_allclose(towards[:, 1:3], np.column_stack((50.0 - 3.0 * t, np.full(5, -1.5))))
    np.testing.assert_allclose(towards[:, 3], np.pi)
