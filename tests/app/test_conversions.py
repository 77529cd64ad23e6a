"""app.conversions: a problem survives the round trip through a request."""

from __future__ import annotations

import numpy as np

from app.conversions import from_problem, to_problem
from planner.roads import demo_problem


def test_problem_round_trip() -> None:
    problem = demo_problem()
    again = to_problem(from_problem(problem))
    assert np.array_equal(again.reference_line, problem.reference_line)
    assert again.lane == problem.lane
    assert again.ego == problem.ego
    assert again.vehicle == problem.vehicle
    assert again.options == problem.options
    assert len(again.obstacles) == len(problem.obstacles)
    for a, b in zip(again.obstacles, problem.obstacles, strict=True):
        assert type(a) is type(b) and a.id == b.id

