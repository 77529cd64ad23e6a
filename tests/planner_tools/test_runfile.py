"""The run file ``/viewer`` plays back: what it holds is the run, to its stated precision, in the shape
its JSON Schema (``app/static/viewer/run.schema.json``) describes; the command line writes it."""

from __future__ import annotations

import gzip
import json
from dataclasses import replace
from pathlib import Path
from typing import Any

import jsonschema_rs
import numpy as np
import pytest

from planner.problem import PlanningProblem
from planner.roads import demo_problem
from planner_tools.cli import main
from planner_tools.io import problem_to_json
from planner_tools.runfile import SCALE, decode, encode, encode_xy, read_run, run_data, write_run
from planner_tools.sim import SimResult, simulate

SCHEMA = json.loads(
    (Path(__file__).resolve().parents[2] / "app" / "static" / "viewer" / "run.schema.json").read_text()
)
#: largest error of a fixed-point value: half its unit, and float rounding
HALF = {name: 0.5 / scale + 1e-9 for name, scale in SCALE.items()}


def _demo(generator: str = "transf_kappa") -> PlanningProblem:
    problem = demo_problem()
    return replace(problem, options=replace(problem.options, generator=generator))


@pytest.fixture(scope="module")
def result() -> SimResult:
    return simulate(_demo(), duration=1.0)


@pytest.fixture(scope="module")
def data(result: SimResult) -> dict[str, Any]:
    return run_data(result, {"road": "demo"})


def test_series_round_trip_to_their_precision() -> None:
    rng = np.random.default_rng(3)
    values = np.cumsum(rng.normal(size=500)) * 37.0
    np.testing.assert_allclose(decode(encode(values, 100), 100), values, atol=HALF["xy"])
    xy = rng.uniform(-1e4, 1e4, size=(200, 2))
    np.testing.assert_allclose(decode(encode_xy(xy), SCALE["xy"], pairs=True), xy, atol=HALF["xy"])
    assert encode([], 100) == [] and decode([], 100).shape == (0,)
    # deltas, not values: a straight, evenly spaced path is a run of equal small integers
    assert encode_xy([[1000.0, 5.0], [1000.5, 5.0], [1001.0, 5.0]]) == [100000, 500, 50, 0, 50, 0]


def test_the_run_file_matches_its_schema(data: dict[str, Any]) -> None:
    validator = jsonschema_rs.validator_for(SCHEMA)
    assert [str(e) for e in validator.iter_errors(data)] == []
    broken = {**data, "cycles": [{**data["cycles"][0], "status": "maybe"}]}
    assert not validator.is_valid(broken)


def test_the_run_file_holds_the_run(result: SimResult, data: dict[str, Any]) -> None:
    assert data["format"] == "kappa-planner-run" and data["version"] == 1
    assert data["request"] == json.loads(json.dumps(problem_to_json(result.problem)))
    assert data["generator"] == "transf_kappa" and data["termination"] == result.termination
    motion = result.motion
    driven = data["driven"]
    np.testing.assert_allclose(decode(driven["t"], SCALE["t"]), motion.t, atol=HALF["t"])
    xy = decode(driven["xy"], SCALE["xy"], pairs=True)
    np.testing.assert_allclose(xy, np.column_stack((motion.x, motion.y)), atol=HALF["xy"])
    for name, values in (("yaw", motion.yaw), ("v", motion.v), ("s", motion.s), ("d", motion.d)):
        np.testing.assert_allclose(decode(driven[name], SCALE[name]), values, atol=HALF[name])
    assert driven["cycle"] == motion.step.tolist()
    assert len(data["cycles"]) == len(result.steps) == 10
    for cycle, step in zip(data["cycles"], result.steps, strict=True):
        assert cycle["t"] == pytest.approx(step.state.t) and cycle["status"] == step.status
        assert cycle["chosen"] == step.chosen and cycle["message"] == step.message
        traj = step.trajectory
        assert traj is not None
        tr = cycle["trajectory"]
        assert tr["dt"] == pytest.approx(result.problem.options.dt)
        np.testing.assert_allclose(
            decode(tr["xy"], SCALE["xy"], pairs=True), np.column_stack((traj.x, traj.y)), atol=HALF["xy"]
        )
        for name in ("heading", "curvature", "v", "a", "s", "d"):
            np.testing.assert_allclose(decode(tr[name], SCALE[name]), getattr(traj, name), atol=HALF[name])
        assert step.candidates_xy is not None
        assert len(cycle["candidates"]) == step.candidates_xy.shape[0]
        for series, xy_c in zip(cycle["candidates"], step.candidates_xy, strict=True):
            kept = xy_c[np.isfinite(xy_c).all(axis=1)]
            np.testing.assert_allclose(decode(series, SCALE["xy"], pairs=True), kept, atol=HALF["xy"])
        assert cycle["folded"] == np.flatnonzero(step.candidates_folded).tolist() == []


def test_alg4_folds_are_those_of_the_naive_run_from_the_same_state(data: dict[str, Any]) -> None:
    # both runs start from the same state: the naive run's first candidates are Algorithm 4's
    naive = simulate(_demo("naive"), duration=0.1)
    first = naive.steps[0]
    assert first.candidates_folded is not None and first.candidates_folded.any()
    expected = np.flatnonzero(first.candidates_folded).tolist()
    assert data["cycles"][0]["alg4_folds"] == expected
    naive_data = run_data(naive)
    assert naive_data["cycles"][0]["alg4_folds"] == naive_data["cycles"][0]["folded"] == expected


def test_written_compressed_read_back_and_reproducible(result: SimResult, tmp_path: Path) -> None:
    out = write_run(result, tmp_path / "run.json.gz", {"road": "demo"})
    raw = out.read_bytes()
    assert raw[:2] == b"\x1f\x8b"
    assert read_run(out) == json.loads(json.dumps(run_data(result, {"road": "demo"})))
    assert write_run(result, tmp_path / "again.json.gz", {"road": "demo"}).read_bytes() == raw
    plain = tmp_path / "run.json"
    plain.write_bytes(gzip.decompress(raw))
    assert read_run(plain) == read_run(out)
    # a few MB at most for a 35 s run (350 cycles of 32 candidates × 100 points)
    per_cycle = len(raw) / len(result.steps)
    assert 350 * per_cycle < 3e6


def test_the_command_line_writes_run_files(tmp_path: Path) -> None:
    road = tmp_path / "demo.json"
    road.write_text(json.dumps(problem_to_json(demo_problem())))
    quick = ["--duration", "0.3", "--no-gif", "--quiet"]
    assert main(["simulate", str(road), "--out", str(tmp_path / "sim"), "--frame-every", "100", *quick]) == 0
    run = read_run(tmp_path / "sim" / "run.json.gz")
    assert len(run["cycles"]) == 3 and run["source"] == {"road": str(road)}
    assert main(["compare", str(road), "--out", str(tmp_path / "cmp"), *quick]) == 0
    for generator in ("naive", "transf_kappa"):
        assert read_run(tmp_path / "cmp" / f"run_{generator}.json.gz")["generator"] == generator
