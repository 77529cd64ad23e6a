"""One implementation of a scene's closed loop and judging (planner_tools.evaluate), and ``kappa-planner
evaluate`` on a local Ray (planner_tools.scale): the same rows as in one process, resuming, failures."""

from __future__ import annotations

import csv
import json
import shutil
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from planner_tools import evaluate as ev
from planner_tools.cli import main as cli_main
from planner_tools.commonroad import CommonRoadError, load

DATA = Path(__file__).resolve().parents[1] / "data" / "commonroad"
#: three shared scenes with different ends: a collision, a goal by time only, a goal missed
THREE = ("ZAM_Over-1_1.json", "BEL_Aarschot-3_1_T-1.json", "DEU_Test-1_1_T-1.json")
#: columns that are measured on the clock, which differ from run to run
TIMED = {"wall_s", "cycle_p50_ms", "cycle_p99_ms", "cycle_max_ms"}


def test_scenes_are_found_in_files_and_folders(tmp_path: Path) -> None:
    found = ev.find_scenes([DATA])
    names = {p.name for p in found}
    assert "index.json" not in names and "SOURCES.md" not in names
    assert {"ZAM_Over-1_1.json", "ZAM_Over-1_1.xml.gz", "C-DEU_B471-1_3_T-1.xml"} <= names
    assert len(found) == 19 + 19
    assert ev.find_scenes([DATA / "ZAM_Over-1_1.json", DATA]).count(DATA / "ZAM_Over-1_1.json") == 1
    assert ev.find_scenes(sorted(DATA.glob("*.json"))) == sorted(p for p in found if p.suffix == ".json")
    with pytest.raises(CommonRoadError, match="no such file"):
        ev.find_scenes([tmp_path / "missing.xml"])
    with pytest.raises(CommonRoadError, match="not a scene"):
        ev.find_scenes([DATA / "SOURCES.md"])
    assert ev.commonroad_file(DATA / "ZAM_Over-1_1.json") == DATA / "ZAM_Over-1_1.xml.gz"
    assert ev.commonroad_file(DATA / "DEU_Moabit-4_1_T-1.json") == DATA / "DEU_Moabit-4_1_T-1.xml"
    ids = ev.scene_ids([Path("a/x.json"), Path("b/x.json"), Path("b/y.json")])
    assert ids == ["a/x.json", "b/x.json", "y.json"]


def test_a_row_survives_the_csv(tmp_path: Path) -> None:
    row = ev.Outcome(
        "s.json", "car", 35.0, judge="commonroad", has_goal=True, goal=False, collision=True, collided="7;9",
        rear_end=1, off_road_steps=0, feasible_transitions=30, transitions=31, feasible=False, cycles=31,
        ok=30, stopped=0, fallback=1, plan_errors=0, cycle_p50_ms=12.5, wall_s=3.25, speed_limit=13.889,
        speed_limit_source="sign", termination="collision", sim_time_s=3.1, goal_m=None,
    )  # fmt: skip
    failed = ev.Outcome.failed("t.json", ev.Settings(), "timeout", "ran past 5 s", 5.0)
    ev.write_csv([row, failed], tmp_path / "results.csv")
    header = next(csv.reader((tmp_path / "results.csv").open()))
    assert header == list(ev.COLUMNS)
    back = ev.read_csv(tmp_path / "results.csv")
    assert back[0] == replace(row, speed_limit=13.89)  # 4 significant digits
    assert back[1] == failed


def test_a_scene_that_cannot_be_read_is_a_row_with_its_error(tmp_path: Path) -> None:
    broken = tmp_path / "broken.json"
    broken.write_text('{"lane": 1}')
    out = ev.run_scene(broken).outcome
    assert out.status == "error" and out.scene == "broken.json" and "reference_line" in out.error
    assert not out.success


def test_a_request_without_its_xml_is_judged_by_the_simulator(tmp_path: Path) -> None:
    shutil.copy(DATA / "ZAM_Over-1_1.json", tmp_path)
    shutil.copy(DATA / "index.json", tmp_path)
    run = ev.run_scene(tmp_path / "ZAM_Over-1_1.json", ev.Settings(duration=0.5), keep=True)
    assert run.outcome.judge == "sim" and run.outcome.goal_m is not None
    assert run.prepared is not None and "goal" not in run.prepared.request
    assert run.prepared.goal is not None and run.prepared.goal.s_min == pytest.approx(67.77)


def test_a_scene_judged_against_its_xml_carries_the_goal_and_the_speed_limit() -> None:
    pytest.importorskip("commonroad")
    run = ev.run_scene(DATA / "DEU_Test-1_1_T-1.json", ev.Settings(duration=0.3), keep=True)
    assert run.prepared is not None and run.result is not None
    request = run.prepared.request
    assert request["goal"]["time"] == [3.5, 4.0]
    assert request["options"]["speed_limit"] == pytest.approx(16.667)  # the sign, above the 12 m/s target
    assert request["vehicle"]["wheelbase"] == pytest.approx(2.578, abs=1e-3)  # CommonRoad's car
    assert run.result.problem.goal is not None
    assert run.result.problem.options.speed_limit == pytest.approx(16.667)
    o = run.outcome
    assert (o.judge, o.has_goal, o.goal, o.termination, o.cycles, o.transitions) == (
        "commonroad", True, False, "timeout", 3, 3,
    )  # fmt: skip
    # the run lasts until the goal's window closes at most
    assert ev.prepare(DATA / "DEU_Test-1_1_T-1.json").duration == pytest.approx(4.0)


def test_recorded_vehicles_that_leave_drive_on_and_leave_the_run() -> None:
    """USA_US101-6_1_T-1: 17 recorded cars leave the measured stretch before its recording ends (at
    8 s); held at their last states they were a wall of stopped cars across all five lanes ~160 m
    ahead. Prepared, each drives on for the horizon and leaves the run when its recording ends; a scene
    whose cars are all recorded to its end (BEL_Aarschot) is as it was."""
    pytest.importorskip("commonroad")
    raw = json.loads((DATA / "USA_US101-6_1_T-1.json").read_text())
    prepared = ev.prepare(DATA / "USA_US101-6_1_T-1.json")
    assert len(prepared.leaves) == 17 and prepared.leaves["322"] == pytest.approx(1.4)
    horizon = prepared.problem.options.horizon_time
    by_id = {ob.id: ob for ob in prepared.problem.obstacles}
    assert by_id["322"].prediction[-1, 0] == pytest.approx(1.4 + horizon)
    recorded = {ob["id"]: ob["prediction"] for ob in raw["obstacles"]}
    assert by_id["423"].prediction.shape[0] == len(recorded["423"])  # recorded to the end: as it was
    run = ev.run_scene(DATA / "USA_US101-6_1_T-1.json", ev.Settings(duration=2.0), keep=True)
    assert run.result is not None
    assert "322" in dict(run.result.steps[14].obstacles) and "322" not in dict(run.result.steps[15].obstacles)
    aarschot = ev.prepare(DATA / "BEL_Aarschot-3_1_T-1.json")
    assert aarschot.leaves == {}
    original = json.loads((DATA / "BEL_Aarschot-3_1_T-1.json").read_text())["obstacles"]
    assert aarschot.request["obstacles"] == original


def test_the_car_drives_lohmars_right_angle_bend_at_a_steady_speed_clear_of_the_car_behind() -> None:
    """DEU_Lohmar-26_1_T-1 with CommonRoad's car (steering at most 0.4 rad/s): a right-angle bend of
    radius ~3 m, a recorded car closing from behind. The car entered the bend at ~2.8 m/s; cycle by cycle
    its eased path's bounds, turned by the candidate's heading, closed in on it, each plan cut the bend
    less and turned in more sharply, and it crawled through at 0.7 m/s until the car behind ran into it.
    Bounded along the reference's heading and checked where the footprint is, the path keeps its line
    and the car its speed through the bend: the goal, no collision."""
    pytest.importorskip("commonroad")
    run = ev.run_scene(DATA / "DEU_Lohmar-26_1_T-1.json", ev.Settings(vehicle="car"), keep=True)
    out = run.outcome
    assert out.goal and not out.collision, (out.goal, out.collided)
    assert run.result is not None
    motion = run.result.motion
    bend = (motion.s > 30.0) & (motion.s < 36.0)  # the reference's curvature peaks at 0.35 1/m at 33 m
    entered = float(motion.v[np.argmax(bend)])
    assert entered > 2.0
    assert float(motion.v[bend].min()) >= 0.75 * entered  # was a quarter of it


# --------------------------------------------------------------------------------------------------
# On Ray
# --------------------------------------------------------------------------------------------------


def _rows(path: Path) -> dict[str, dict[str, str]]:
    with path.open(newline="") as fh:
        return {r["scene"]: {k: v for k, v in r.items() if k not in TIMED} for r in csv.DictReader(fh)}


def test_evaluate_on_a_local_ray_gives_the_rows_of_one_process(tmp_path: Path) -> None:
    """Three shared scenes on a local Ray of 2 workers: the same rows (outcomes, counts, distances) as
    run_scene gives in this process; a second run into the same folder keeps them and runs only what is
    new or failed: a scene that is not a request (an error row) and one that runs past its timeout."""
    pytest.importorskip("ray")
    pytest.importorskip("commonroad")
    scenes = [DATA / name for name in THREE]
    out = tmp_path / "eval"
    code = cli_main(["evaluate", *map(str, scenes), "--out", str(out), "--workers", "2", "--quiet"])
    assert code == 0
    on_ray = _rows(out / "results.csv")
    ev.write_csv([ev.run_scene(p).outcome for p in scenes], tmp_path / "here.csv")
    here = _rows(tmp_path / "here.csv")
    assert list(on_ray) == list(THREE)
    assert on_ray == here
    assert [on_ray[n]["termination"] for n in THREE] == ["collision", "goal", "goal"]
    assert all(r["status"] == "done" and r["judge"] == "commonroad" for r in on_ray.values())
    summary = (out / "summary.md").read_text()
    assert "Ray start-up" in summary and "| ZAM_Over-1_1.json |" in summary

    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"hello": 1}))
    report = ev_scale_evaluate([*scenes, bad], out, timeout=600.0)
    assert report.skipped == 3 and [o.scene for o in report.ran] == ["bad.json"]
    rows = {o.scene: o for o in ev.read_csv(out / "results.csv")}
    assert rows["bad.json"].status == "error" and "neither a planning request" in rows["bad.json"].error
    # a scene still running when its time is up (here: before its worker has even imported the planner)
    report = ev_scale_evaluate([DATA / "DEU_Moabit-4_1_T-1.json"], out, timeout=0.2)
    assert [(o.scene, o.status) for o in report.ran] == [("DEU_Moabit-4_1_T-1.json", "timeout")]
    rows = {o.scene: o for o in ev.read_csv(out / "results.csv")}
    assert list(rows) == ["DEU_Moabit-4_1_T-1.json", *THREE, "bad.json"]  # earlier scenes' rows stay
    assert _rows(out / "results.csv")["ZAM_Over-1_1.json"] == here["ZAM_Over-1_1.json"]


def ev_scale_evaluate(paths: list[Path], out: Path, timeout: float):  # type: ignore[no-untyped-def]
    from planner_tools.scale import evaluate

    return evaluate(paths, out, workers=2, timeout=timeout, quiet=True)


def test_evaluate_without_ray_says_how_to_install_it(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "ray", None)  # as if Ray were not installed
    assert cli_main(["evaluate", str(DATA / THREE[0]), "--out", str(tmp_path)]) == 2
    assert "kappa-planner[scale]" in capsys.readouterr().err


def test_the_readme_explains_every_column() -> None:
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    missing = [name for name in ev.COLUMNS if f"| `{name}` |" not in readme]
    assert not missing, f"README's table of results.csv lacks {missing}"


def test_a_measured_start_curvature_is_held_within_the_vehicle_it_is_driven_with() -> None:
    """A start converted for the car (curvature 0.5 1/m at 2 m/s, within the car's 0.70 1/m) driven as the
    point model (0.3 1/m): its curvature is that model's limit, not one it could not be driving; a
    curvature within both limits, and the requests' own vehicle, are left as they are."""
    conv = load(DATA / "DEU_Moabit-4_1_T-1.json")
    turning = replace(
        conv, request={**conv.request, "ego": {**conv.request["ego"], "speed": 2.0, "curvature": 0.5}}
    )
    assert ev.with_vehicle(turning, "car").request["ego"]["curvature"] == 0.5
    point = ev.with_vehicle(turning, "point").request
    assert point["vehicle"]["max_curvature"] < 0.5
    assert point["ego"]["curvature"] == pytest.approx(point["vehicle"]["max_curvature"])
    assert ev.with_vehicle(turning, "request").request["ego"]["curvature"] == 0.5
    gentle = replace(
        turning, request={**turning.request, "ego": {**turning.request["ego"], "curvature": -0.1}}
    )
    assert ev.with_vehicle(gentle, "point").request["ego"]["curvature"] == -0.1
