"""Candidates: Algorithm 4 folds back on a wide U-turn, Algorithm 5 never does (the paper's claim)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.candidates import CandidateSet, _consistent_offsets, generate_candidates
from planner.ego import ego_frenet
from planner.errors import InvalidInputError
from planner.frenet import to_frenet
from planner.lane import lane_bounds
from planner.problem import Ego, Lane, Options, Vehicle
from planner.reference import ReferenceLine, build_reference
from planner.roads import arc, demo_problem, straight, u_turn
from planner.validation import backward_steps, self_intersects

SCENARIOS = Path(__file__).resolve().parents[1] / "data" / "commonroad"


def _u_turn_case(radius: float, inner_width: float) -> tuple[ReferenceLine, Lane, Ego]:
    ref = build_reference(u_turn(radius=radius, leg=30.0, step=1.0))
    lane = Lane(left_width=inner_width, right_width=3.5)
    ego = Ego(x=-12.0, y=0.0, heading=0.0, speed=5.0)
    return ref, lane, ego


def _options(generator: str, seed: int = 0, n: int = 60) -> Options:
    return Options(num_candidates=n, num_points=100, generator=generator, seed=seed, target_speed=7.0)  # type: ignore[arg-type]


def _broken(ref: ReferenceLine, cands: CandidateSet) -> list[int]:
    """Indices of candidates with a κ·d ≥ 1 point, a backward step or a self-intersection."""
    out = []
    for i in range(cands.count):
        s, d, xy = cands.points(i)
        if (
            np.any(ref.kappa_at(s) * d >= 1.0)
            or np.any(np.diff(s) <= 0)
            or backward_steps(ref, xy) > 0
            or self_intersects(xy)
        ):
            out.append(i)
    return out


def test_naive_candidates_fold_back_on_a_wide_u_turn() -> None:
    ref, lane, ego = _u_turn_case(radius=6.0, inner_width=10.0)
    cands = generate_candidates(ref, lane, ego, Vehicle(), _options("naive"))
    broken = _broken(ref, cands)
    assert broken, "naive offsets should fold back where κ·d ≥ 1"
    # The fold is real: some naive point lies beyond the centre of curvature and runs backwards.
    assert np.any(cands.kappa * cands.d >= 1.0)
    assert any(backward_steps(ref, cands.points(i)[2]) > 0 for i in broken)
    assert any(self_intersects(cands.points(i)[2]) for i in broken)


@settings(max_examples=25, deadline=None)
@given(
    radius=st.floats(3.0, 15.0),
    extra=st.floats(1.05, 2.2),
    seed=st.integers(0, 10_000),
)
def test_transf_kappa_candidates_never_fold_back(radius: float, extra: float, seed: int) -> None:
    ref, lane, ego = _u_turn_case(radius=radius, inner_width=extra * radius + 1.0)
    cands = generate_candidates(ref, lane, ego, Vehicle(), _options("transf_kappa", seed=seed))
    assert _broken(ref, cands) == []
    # Each kept point is TransF-κ's own answer for its Cartesian position.
    fr = to_frenet(ref, cands.xy[cands.valid])
    np.testing.assert_allclose(fr.s, cands.s[cands.valid], atol=1e-6)
    np.testing.assert_allclose(fr.d, cands.d[cands.valid], atol=1e-6)


def test_transf_kappa_repairs_what_naive_breaks_with_the_same_seed() -> None:
    ref, lane, ego = _u_turn_case(radius=6.0, inner_width=10.0)
    naive = generate_candidates(ref, lane, ego, Vehicle(), _options("naive"))
    fixed = generate_candidates(ref, lane, ego, Vehicle(), _options("transf_kappa"))
    assert _broken(ref, naive)
    assert fixed.repaired.any()
    assert not fixed.valid.all()  # the folded stretch was jumped
    assert _broken(ref, fixed) == []


def test_candidates_start_at_the_ego_and_stay_in_the_lane() -> None:
    problem = demo_problem()
    ref = build_reference(problem.reference_line)
    start = ego_frenet(ref, problem.ego)
    for generator in ("naive", "transf_kappa"):
        options = replace(problem.options, generator=generator, num_candidates=50)  # type: ignore[arg-type]
        cands = generate_candidates(ref, problem.lane, problem.ego, problem.vehicle, options)
        np.testing.assert_allclose(cands.xy[:, 0], [[problem.ego.x, problem.ego.y]] * 50, atol=1e-9)
        np.testing.assert_allclose(cands.s[:, 0], start.s, atol=1e-9)
        bounds = lane_bounds(ref, problem.lane, cands.s[0], half_width=problem.vehicle.width / 2, margin=0.2)
        if generator == "naive":
            assert np.all(cands.d <= bounds.upper + 1e-9)
            assert np.all(cands.d >= bounds.lower - 1e-9)
        else:  # repaired points carry TransF-κ's answer; the lane is measured at their own s
            s, d = cands.s[cands.valid], cands.d[cands.valid]
            b = lane_bounds(ref, problem.lane, s, half_width=problem.vehicle.width / 2, margin=0.2)
            assert np.all(d <= b.upper + 1e-6) and np.all(d >= b.lower - 1e-6)


def test_candidates_are_reproducible_from_the_seed() -> None:
    ref, lane, ego = _u_turn_case(radius=6.0, inner_width=10.0)
    a = generate_candidates(ref, lane, ego, Vehicle(), _options("transf_kappa", seed=7))
    b = generate_candidates(ref, lane, ego, Vehicle(), _options("transf_kappa", seed=7))
    c = generate_candidates(ref, lane, ego, Vehicle(), _options("transf_kappa", seed=8))
    np.testing.assert_array_equal(a.d, b.d)
    np.testing.assert_array_equal(a.valid, b.valid)
    assert not np.array_equal(a.d, c.d)


def test_candidates_follow_the_ego_state_smoothly() -> None:
    """The profile starts with the ego's offset and slope, then settles with zero slope."""
    ref = build_reference(straight(200.0))
    ego = Ego(x=10.0, y=1.0, heading=0.1, speed=10.0)
    cands = generate_candidates(ref, Lane(4.0, 4.0), ego, Vehicle(), _options("transf_kappa", n=20))
    ds = np.diff(cands.s[0])[0]
    slope0 = (cands.d[:, 1] - cands.d[:, 0]) / ds
    np.testing.assert_allclose(cands.d[:, 0], 1.0, atol=1e-9)
    np.testing.assert_allclose(slope0, np.tan(0.1), atol=0.02)
    assert not cands.repaired.any()  # nothing to repair on a straight road
    end_slope = (cands.d[:, -1] - cands.d[:, -2]) / ds
    assert np.all(np.abs(end_slope) < 0.05)


def test_ego_past_the_end_is_rejected() -> None:
    ref = build_reference(straight(100.0))
    with pytest.raises(InvalidInputError) as err:
        generate_candidates(ref, Lane(3.0, 3.0), Ego(x=120, y=0, heading=0.0), Vehicle(), Options())
    assert err.value.field == "ego"


def _load(name: str) -> dict:
    return json.loads((SCENARIOS / name).read_text())


def _scenario_names() -> list[str]:
    return sorted(p.name for p in SCENARIOS.glob("*_*.json"))


@pytest.mark.parametrize("name", _scenario_names())
def test_commonroad_scenarios_project_and_generate(name: str) -> None:
    req = _load(name)
    ref = build_reference(req["reference_line"])
    lane = Lane(
        left_width=np.asarray(req["lane"]["left_width"], dtype=float),
        right_width=np.asarray(req["lane"]["right_width"], dtype=float),
    )
    e = req["ego"]
    ego = Ego(x=e["x"], y=e["y"], heading=e["heading"], speed=e.get("speed", 0.0))
    vehicle = Vehicle(**req["vehicle"])
    # The reference itself projects onto itself.
    fr = to_frenet(ref, ref.points)
    np.testing.assert_allclose(fr.s, ref.s, atol=1e-6)
    np.testing.assert_allclose(fr.d, 0.0, atol=1e-6)
    start = ego_frenet(ref, ego)
    assert abs(start.d) < 5.0
    for generator in ("naive", "transf_kappa"):
        options = Options(num_candidates=40, generator=generator, target_speed=e.get("speed") or 5.0)  # type: ignore[arg-type]
        cands = generate_candidates(ref, lane, ego, vehicle, options)
        assert cands.count == 40
        assert np.isfinite(cands.xy).all()
        if generator == "transf_kappa":
            assert _broken(ref, cands) == []


def test_reference_running_back_on_itself_is_rejected_at_its_point() -> None:
    from planner.errors import InvalidReferenceError

    with pytest.raises(InvalidReferenceError) as err:
        build_reference([[0.0, 0.0], [10.0, 0.0], [5.0, 0.0]])
    assert err.value.field == "reference_line.1"


@settings(max_examples=20, deadline=None)
@given(radius=st.floats(8.0, 40.0), turn=st.floats(0.3, 2.0), eps=st.floats(1e-7, 1e-2))
def test_own_offset_bounds_are_the_lane_where_nothing_else_is_near(
    radius: float, turn: float, eps: float
) -> None:
    """A corner between two straights, lane well inside the curve's radius: no other stretch of the
    reference is near, so the candidates' own bounds are the lane bounds at every column, also a hair
    away from a reference sample.

    Regression: where the Frenet line is not exactly normal to the curve (around the curve's ends), a
    sample ``eps`` away along the curve gave a largest empty disc of radius ≈ 0, so one column of every
    candidate was pulled onto the reference (a 7 m spike in the demo U-turn's candidates).
    """
    corner = arc(radius, turn, step=0.5)
    heading = turn
    out = corner[-1] + straight(30.0, heading=heading, step=0.5)[1:]
    ref = build_reference(np.vstack((straight(30.0)[:-1] - [30.0, 0.0], corner, out)))
    lane = Lane(left_width=0.3 * radius, right_width=0.3 * radius)
    inner = ref.s[2:-2]
    s_row = np.concatenate([inner - eps, inner + eps])
    bounds = lane_bounds(ref, lane, s_row, half_width=0.9, margin=0.2)
    limits = _consistent_offsets(ref, s_row, bounds, separation=0.9)
    np.testing.assert_array_equal(limits.upper_own, bounds.upper)
    np.testing.assert_array_equal(limits.lower_own, bounds.lower)
