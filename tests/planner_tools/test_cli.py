"""The ``kappa-planner`` command line and the JSON request reader behind it."""

from __future__ import annotations

import csv
import json
import re
import sys
import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from app.schemas import PlanningRequest, demo_request, to_problem
from planner.errors import InvalidInputError
from planner.problem import PlanningProblem
from planner.roads import straight
from planner_tools import extras, render  # noqa: F401 (render imports the extra's modules once)
from planner_tools.cli import main
from planner_tools.extras import TOOLS
from planner_tools.figures import main as figures_main
from planner_tools.io import problem_from_json, problem_to_json

ROOT = Path(__file__).resolve().parents[2]
COMMONROAD = sorted(p for p in (ROOT / "tests/data/commonroad").glob("*.json") if p.name != "index.json")


def _same(a: PlanningProblem, b: PlanningProblem) -> None:
    np.testing.assert_array_equal(a.reference_line, b.reference_line)
    for side in ("left_width", "right_width"):
        np.testing.assert_array_equal(getattr(a.lane, side), getattr(b.lane, side))
    assert (a.ego, a.vehicle, a.options) == (b.ego, b.vehicle, b.options)
    assert [type(o) for o in a.obstacles] == [type(o) for o in b.obstacles]
    for x, y in zip(a.obstacles, b.obstacles, strict=True):
        assert x.id == y.id
        for name in ("polygon", "center", "radius", "prediction", "length", "width"):
            if hasattr(x, name):
                np.testing.assert_array_equal(getattr(x, name), getattr(y, name))


@pytest.mark.parametrize("path", COMMONROAD, ids=[p.stem for p in COMMONROAD])
def test_reader_agrees_with_the_http_layer(path: Path) -> None:
    data = json.loads(path.read_text())
    _same(problem_from_json(data), to_problem(PlanningRequest.model_validate(data)))


def test_reader_round_trips_the_demo() -> None:
    data = demo_request().model_dump(mode="json")
    problem = problem_from_json(data)
    _same(problem, to_problem(demo_request()))
    _same(problem_from_json(json.loads(json.dumps(problem_to_json(problem)))), problem)
    data["options"].update(time_budget_ms=50.0, generator="naive", target_speed=None)
    _same(problem_from_json(data), to_problem(PlanningRequest.model_validate(data)))


def _demo() -> dict[str, Any]:
    return demo_request().model_dump(mode="json")


@pytest.mark.parametrize(
    ("edit", "field"),
    [
        (lambda d: d.pop("ego"), "ego"),
        (lambda d: d["ego"].update(speed=True), "ego.speed"),
        (lambda d: d["ego"].update(x="1"), "ego.x"),
        (lambda d: d["ego"].update(speed=-1.0), "ego.speed"),
        (lambda d: d.update(colour="red"), "colour"),
        (lambda d: d["options"].update(generator="magic"), "options.generator"),
        (lambda d: d["options"].update(num_candidates=2.5), "options.num_candidates"),
        (lambda d: d["vehicle"].update(length=0.0), "vehicle.length"),
        (lambda d: d["lane"].update(left_width=[1.0, 2.0]), "lane.left_width"),
        (lambda d: d["obstacles"][0].update(polygon=[[0, 0], [1, 0], [0, 1]]), "obstacles[0]"),
        (lambda d: d["obstacles"][0]["circle"].update(radius=-1.0), "obstacles[0].circle.radius"),
        (lambda d: d["reference_line"][3].append(1.0), "reference_line[3]"),
        (lambda d: d["reference_line"][0].__setitem__(0, float("nan")), "reference_line[0][0]"),
    ],
)
def test_reader_names_the_bad_field(edit: Any, field: str) -> None:
    data = _demo()
    edit(data)
    with pytest.raises(InvalidInputError) as err:
        problem_from_json(data)
    assert err.value.field == field


def test_reader_checks_predictions() -> None:
    data = _demo()
    data["obstacles"].append(
        {
            "id": "car",
            "length": 4.0,
            "width": 2.0,
            "prediction": [
                {"t": 0.0, "x": 0, "y": 0, "heading": 0},
                {"t": 0.0, "x": 1, "y": 0, "heading": 0},
            ],
        }
    )
    with pytest.raises(InvalidInputError) as err:
        problem_from_json(data)
    assert err.value.field == "obstacles[1].prediction[1].t"
    data["obstacles"][1]["id"] = "cone"
    data["obstacles"][1]["prediction"][1]["t"] = 1.0
    with pytest.raises(InvalidInputError) as err:
        problem_from_json(data)
    assert err.value.field == "obstacles[1].id"


def _names(requirements: list[str]) -> set[str]:
    """Distribution names of requirement strings, normalised (``Pillow>=10`` → ``pillow``)."""
    return {re.split(r"[\[<>=~!; ]", r, maxsplit=1)[0].lower().replace("_", "-") for r in requirements}


def test_entry_point_and_extras_are_declared() -> None:
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["scripts"]["kappa-planner"] == "planner_tools.cli:main"
    optional = project["optional-dependencies"]
    for extra in (TOOLS, extras.COMMONROAD):
        assert _names(optional[extra.name]) == {d.lower() for d in extra.modules.values()}
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
