"""The ``kappa-planner`` command line, ``python -m planner_tools.figures`` and the extras they need."""

from __future__ import annotations

import csv
import dataclasses
import json
import sys
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from PIL import Image

from planner.reference import build_reference
from planner.roads import straight, wide_u_turn_problem
from planner_tools import extras, render
from planner_tools.cli import main
from planner_tools.extras import TOOLS
from planner_tools.figures import main as figures_main

ROOT = Path(__file__).resolve().parents[2]


def _names(requirements: list[str]) -> set[str]:
    """Distribution names of requirement strings, normalised (``Pillow>=10`` → ``pillow``)."""
    return {canonicalize_name(Requirement(r).name) for r in requirements}


def test_entry_point_and_extras_are_declared() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["scripts"]["kappa-planner"] == "planner_tools.cli:main"
    optional = project["optional-dependencies"]
    for extra in (TOOLS, extras.COMMONROAD):
        assert _names(optional[extra.name]) == _names(list(extra.modules.values()))
        assert not _names(project["dependencies"]) & _names(optional[extra.name])


@pytest.mark.parametrize("module", sorted(TOOLS.modules))
def test_without_the_tools_extra_the_cli_says_what_to_install(
    module: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # the extra's modules are imported (by render): blocking one leaves the others whole
    monkeypatch.setitem(sys.modules, module, None)  # as if it were not installed
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"kappa-planner: error: the command line needs {TOOLS.modules[module]}: install ")
    assert "pip install 'kappa-planner[tools]'" in err
    assert "Traceback" not in err and not out.exists()
    assert figures_main(["candidates", "--out", str(tmp_path / "c.png")]) == 2
    assert "pip install 'kappa-planner[tools]'" in capsys.readouterr().err
    assert not (tmp_path / "c.png").exists()


def test_the_candidates_figure_is_drawn(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "fig" / "candidates.png"
    assert figures_main(["candidates", "--out", str(out), "--num-candidates", "6"]) == 0
    with Image.open(out) as png:
        assert png.size == (1430, 715)  # 13 × 6.5 in at 110 dpi
    assert f"wrote {out}" in capsys.readouterr().out


def test_the_road_candidates_figure_is_drawn(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "road_candidates.png"
    assert figures_main(["road-candidates", "--out", str(out), "--num-candidates", "12"]) == 0
    with Image.open(out) as png:
        assert png.size == (1430, 715)
    assert f"wrote {out}" in capsys.readouterr().out


def test_panels_draw_the_road_edges_beside_the_lanes() -> None:
    import matplotlib.pyplot as plt

    problem = wide_u_turn_problem()
    ref = build_reference(problem.reference_line)
    fig, ax = plt.subplots()
    try:
        assert len(render._draw_edges(ax, ref, dataclasses.replace(problem, road=None))) == 2
        edges = render._draw_edges(ax, ref, problem)
        assert len(edges) == 4
        road_left = edges[2]
        finite = road_left[np.isfinite(road_left[:, 0])]
        # the road's left edge 8.75 m from the reference on the straight legs, left out in the turn
        assert finite.shape[0] < road_left.shape[0]
        np.testing.assert_allclose(finite[0], [-40.0, 8.75], atol=1e-6)
    finally:
        plt.close(fig)


@pytest.fixture
def road(tmp_path: Path) -> Path:
    """A short straight road with a cone to pass."""
    request = {
        "reference_line": straight(60.0, step=5.0).tolist(),
        "lane": {"left_width": 5.0, "right_width": 3.5},
        "obstacles": [{"id": "cone", "circle": {"center": [25.0, -0.5], "radius": 0.5}}],
        "ego": {"x": 5.0, "y": 0.0, "heading": 0.0, "speed": 5.0},
        "options": {"target_speed": 6.0, "num_candidates": 8},
    }
    path = tmp_path / "road.json"
    path.write_text(json.dumps(request))
    return path


def test_simulate_writes_frames_metrics_and_a_gif(road: Path, tmp_path: Path, capsys: Any) -> None:
    out = tmp_path / "run"
    code = main(
        ["simulate", str(road), "--out", str(out), "--duration", "0.6", "--frame-every", "0.3", "--quiet"]
    )
    assert code == 0
    record = json.loads((out / "metrics.json").read_text())
    assert record["generator"] == "transf_kappa"
    metrics = record["metrics"]
    assert metrics["steps"] == 6 and metrics["termination"] == "timeout"
    assert metrics["sim_time"] == pytest.approx(0.6)
    assert sum(metrics["status_counts"].values()) == 6
    assert sorted(p.name for p in out.glob("frame_*.png")) == [
        "frame_000.0s.png",
        "frame_000.3s.png",
        "frame_000.6s_final.png",
    ]
    with Image.open(out / "sim.gif") as gif:
        assert gif.n_frames == 4  # cycles 0, 2, 4 and the final state
    with (out / "steps.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 6 and float(rows[-1]["t"]) == pytest.approx(0.5)
    assert "transf_kappa" in capsys.readouterr().out


def test_compare_runs_both_generators(road: Path, tmp_path: Path) -> None:
    out = tmp_path / "cmp"
    assert main(["compare", str(road), "--out", str(out), "--duration", "0.3", "--no-gif", "--quiet"]) == 0
    runs = json.loads((out / "metrics.json").read_text())["runs"]
    assert sorted(runs) == ["naive", "transf_kappa"]
    assert all(run["metrics"]["steps"] == 3 for run in runs.values())
    assert (out / "compare.png").stat().st_size > 10_000
    assert not (out / "compare.gif").exists()


def test_invalid_request_exits_with_status_2(tmp_path: Path, capsys: Any) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(
        json.dumps({"reference_line": [[0, 0], [10, 0]], "lane": {"left_width": 3, "right_width": 3}})
    )
    assert main(["simulate", str(bad), "--out", str(tmp_path / "x"), "--quiet"]) == 2
    assert "ego: is required" in capsys.readouterr().err
    assert main(["simulate", str(tmp_path / "missing.json"), "--out", str(tmp_path / "x"), "--quiet"]) == 2
    (tmp_path / "text.json").write_text("not json")
    assert main(["compare", str(tmp_path / "text.json"), "--out", str(tmp_path / "x"), "--quiet"]) == 2
