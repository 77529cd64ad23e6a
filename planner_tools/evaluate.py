"""One scene's closed loop and its judgement, as ``bench/commonroad.py``, ``kappa-planner commonroad`` and
``kappa-planner evaluate`` run and judge it (one implementation; :mod:`planner_tools.scale` runs many of
them on Ray).

A **scene** is a file: a CommonRoad XML scenario (``*.xml``, ``*.xml.gz``), a planning request JSON (the
body of ``POST /v1/plan``) or a reduced CommonRoad scenario JSON. :func:`prepare` turns it into a planning
problem and a goal:

* the request — converted from the XML by :mod:`planner_tools.commonroad`, or the JSON as it is; its vehicle
  (``vehicle``): ``car``, CommonRoad's vehicle type 2 (the scenario's vehicle, the default), ``point``,
  the same footprint as the point model, or ``request``, the request's own;
* a CommonRoad scenario to judge against — the XML itself, or for a JSON ``X.json`` the file ``X.xml``
  or ``X.xml.gz`` beside it (:func:`commonroad_file`). With one
  (:class:`~planner_tools.crjudge.CommonRoadScene`) the request carries the scenario's ``goal`` and
  ``options.speed_limit``; the run ends when commonroad-io finds the goal reached, at a collision the
  drivability checker finds (the simulator's own contacts with the request's obstacles are counted, not
  ended on: a request's predictions may outlast the scenario's), or when the goal's time window has
  closed (at most ``duration``); it is judged by CommonRoad's goal check, the drivability checker's
  collision checker and feasibility check, and the road of the lanelets (see
  :mod:`planner_tools.crjudge`). A scenario without a goal state is driven for ``duration`` (to the
  reference's end at most) and judged on surviving it.
* recorded vehicles that leave the recorded area before its recording ends drive on past their last
  state for the planning horizon and leave the run then (:func:`planner_tools.commonroad.
  continued_predictions`, ``Prepared.leaves``), instead of stopping dead where their recording ends;
* without one (a JSON with no XML beside it), as before: the goal is an arc length on the reference
  (``s_min`` from ``index.json`` beside the request; for a goal given by time only
  :func:`survival_goal_s`), collisions are the simulator's, feasibility the drivability checker's when
  the extra ``commonroad`` is installed.

**Success** = goal reached ∧ no collision ∧ every driven transition feasible; a scene without a goal
succeeds by surviving its run (no collision, feasible). :func:`run_scene` returns an :class:`Outcome`, one
flat row of plain values (``results.csv``; :data:`COLUMNS` says what each column means) that
:func:`table` renders like ``bench/commonroad.py``'s table.
"""

from __future__ import annotations

import csv
import io
import math
import tempfile
import time
import traceback
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import shapely

from planner.errors import InvalidInputError
from planner.frenet import to_frenet
from planner.problem import Options, PlanningProblem
from planner.reference import build_reference
from planner_tools.commonroad import (
    CommonRoadError,
    Conversion,
    car_vehicle,
    continued_predictions,
    driven_states,
    feasible_transitions,
    load,
    point_vehicle,
    scenario_name,
    start_curvature_limit,
)
from planner_tools.extras import COMMONROAD
from planner_tools.io import problem_from_json
from planner_tools.sim import GOAL_MARGIN_LENGTHS, Goal, SimResult, simulate

#: vehicles a scene can be driven with (see the module docstring)
VEHICLES = ("car", "point", "request")
#: default longest simulated time per scene [s]
DURATION = 35.0
#: share of the time allowed that a time-only goal's distance is planned for (no CommonRoad scenario)
SURVIVAL_SHARE = 0.6
#: the step [s] at which a run without a CommonRoad scenario has its transitions judged
FEASIBILITY_DT = 0.1
#: a request's planning horizon without ``options.horizon_time`` [s]
_DEFAULT_HORIZON = next(f.default for f in fields(Options) if f.name == "horizon_time")
#: file suffixes of scenes
SUFFIXES = (".xml", ".xml.gz", ".json")


@dataclass(frozen=True)
class Settings:
    """How scenes are run: ``vehicle`` (:data:`VEHICLES`), at most ``duration`` simulated seconds,
    a replan every ``replan_period`` [s], and whether an animation is drawn (``gif``)."""

    vehicle: str = "car"
    duration: float = DURATION
    replan_period: float = 0.1
    gif: bool = False


#: the default settings
DEFAULTS = Settings()

# --------------------------------------------------------------------------------------------------
# Scenes
# --------------------------------------------------------------------------------------------------


def is_scene(path: Path) -> bool:
    name = path.name.lower()
    return name != "index.json" and any(name.endswith(s) for s in SUFFIXES)


def find_scenes(inputs: Iterable[str | Path]) -> list[Path]:
    """The scene files of ``inputs`` (files, or folders whose scene files are taken, sorted), in order,
    each once; ``index.json`` (the requests' index beside them) is not a scene and is passed over.

    Raises:
        CommonRoadError: for an input that does not exist or a file that is not a scene.
    """
    out: list[Path] = []
    for item in map(Path, inputs):
        if item.is_dir():
            found = sorted(p for p in item.iterdir() if p.is_file() and is_scene(p))
        elif item.is_file():
            if item.name.lower() == "index.json":  # the requests' index, as a shell's *.json passes it
                continue
            if not is_scene(item):
                raise CommonRoadError(f"{item}: not a scene (CommonRoad XML, .xml.gz or a request JSON)")
            found = [item]
        else:
            raise CommonRoadError(f"{item}: no such file or folder")
        out.extend(p for p in found if p not in out)
    return out


def scene_ids(paths: Sequence[Path]) -> list[str]:
    """A name per scene: its file name, with its folder's name in front where two share one."""
    names = [p.name for p in paths]
    return [f"{p.parent.name}/{p.name}" if names.count(p.name) > 1 else p.name for p in paths]


def commonroad_file(path: Path) -> Path | None:
    """The CommonRoad XML a scene is judged against: itself, or for a JSON ``X.json`` the ``X.xml`` or
    ``X.xml.gz`` beside it; None if there is none."""
    if not path.name.lower().endswith(".json"):
        return path
    for suffix in (".xml", ".xml.gz"):
        beside = path.with_name(scenario_name(path) + suffix)
        if beside.is_file():
            return beside
    return None


# --------------------------------------------------------------------------------------------------
# Preparing a scene
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Prepared:
    """A scene ready to run: its name, conversion, request (what the planner gets at t = 0, JSON data)
    and problem, the simulator's goal, the duration [s], the CommonRoad scene that judges it (or None),
    the speed limit's source, the goal's arc length [m] on the reference when it has one, the
    CommonRoad collision check, and when each recorded vehicle leaves the scene [s]
    (:func:`planner_tools.commonroad.continued_predictions`)."""

    name: str
    conversion: Conversion
    request: dict[str, Any]
    problem: PlanningProblem
    goal: Goal | None
    duration: float
    judge: Any | None = None
    speed_limit_source: str = ""
    goal_s: float | None = None
    collision: Callable[[Any], bool] | None = field(default=None, repr=False)
    leaves: dict[str, float] = field(default_factory=dict, repr=False)


def survival_goal_s(conv: Conversion, duration: float) -> float:
    """The goal's arc length [m] on the reference without a CommonRoad scenario: the conversion's
    ``s_min``, or for a goal given by time only ``s_ego + target_speed · duration · SURVIVAL_SHARE``, a
    distance it can reach in the time allowed; at most the reference's end less a vehicle length."""
    problem = problem_from_json(conv.request)
    ref = build_reference(problem.reference_line)
    end = _map_end(conv, ref.length) - problem.vehicle.length
    s_min = conv.goal.get("s_min")
    if s_min is not None:
        return float(min(s_min, end))
    s_ego = float(to_frenet(ref, [[problem.ego.x, problem.ego.y]]).s[0])
    speed = problem.options.target_speed or problem.vehicle.max_speed
    return float(min(end, s_ego + speed * duration * SURVIVAL_SHARE))


def _map_end(conv: Conversion, length: float) -> float:
    """Where the map ends on the conversion's reference of ``length`` [m]: its end less the straight
    continuation past the map's edge (:data:`planner_tools.commonroad.MAP_EDGE_EXTENSION`), which the
    planner plans on but a run does not drive to as its goal."""
    return length - float(conv.info.get("map_edge_extension_m", 0.0))


def with_vehicle(conv: Conversion, vehicle: str) -> Conversion:
    """``conv`` with the vehicle ``vehicle`` (:data:`VEHICLES`)."""
    if vehicle not in VEHICLES:
        raise CommonRoadError(f"vehicle must be one of {', '.join(VEHICLES)}, not {vehicle!r}")
    if vehicle == "request" or not isinstance(conv.request.get("vehicle"), dict):
        return conv  # a request without a vehicle: problem_from_json names the field
    made = (car_vehicle if vehicle == "car" else point_vehicle)(conv.request["vehicle"])
    request = {**conv.request, "vehicle": made}
    ego = request.get("ego")
    if isinstance(ego, dict) and isinstance(ego.get("curvature"), (int, float)):
        request["ego"] = {**ego, "curvature": _start_curvature(ego, made)}
    return replace(conv, request=request)


def _start_curvature(ego: dict[str, Any], vehicle: dict[str, Any]) -> Any:
    """The ego's measured curvature [1/m] within ``vehicle``'s limits at its speed, as the converter holds
    a start's (:func:`planner_tools.commonroad.start_curvature_limit`; a point model's curvature limit is
    below a car's); as it is where the speed or the vehicle is not one the planner accepts (it then names
    the field)."""
    try:
        limit = start_curvature_limit(float(ego.get("speed", 0.0)), vehicle)
    except (TypeError, ValueError, InvalidInputError):
        return ego["curvature"]
    return float(np.clip(ego["curvature"], -limit, limit))


def _goal_arc_length(request: dict[str, Any]) -> float | None:
    """The arc length [m] on the request's reference of its goal region's centroid (a circle's centre),
    or None without a goal position."""
    position = (request.get("goal") or {}).get("position")
    if not position:
        return None
    if "circle" in position:
        centre = np.asarray(position["circle"]["center"], dtype=float)
    else:
        centre = np.asarray(shapely.Polygon(position["polygon"]).centroid.coords[0], dtype=float)
    ref = build_reference(np.asarray(request["reference_line"], dtype=float))
    return float(to_frenet(ref, centre[None, :]).s[0])


def _cycles_to(t: float, period: float) -> float:
    """``t`` [s] rounded up to whole replan periods (at least one)."""
    return max(1, math.ceil(t / period - 1e-9)) * period


def prepare(
    path: str | Path, settings: Settings = DEFAULTS, *, planning_problem_id: int | None = None
) -> Prepared:
    """A scene file ready to run (see the module docstring).

    Raises:
        CommonRoadError: a file that cannot be read or converted, or a missing extra.
        InvalidInputError: a request the planner refuses.
    """
    p = Path(path)
    conv = with_vehicle(load(p, planning_problem_id=planning_problem_id), settings.vehicle)
    name = scenario_name(p)
    xml = commonroad_file(p)
    judge = None
    if xml is not None and not COMMONROAD.missing():
        from planner_tools.crjudge import CommonRoadScene

        judge = CommonRoadScene.from_file(xml, planning_problem_id)
    request = dict(conv.request)
    source = ""
    duration = settings.duration
    goal: Goal | None
    goal_s: float | None
    if judge is None:
        goal_s = survival_goal_s(conv, duration)
        goal = Goal(s_min=goal_s)
    else:
        options = dict(request["options"])
        ego = request["ego"]
        limit = judge.speed_limit(judge.route_lanelets(request["reference_line"], [ego["x"], ego["y"]]))
        target = options.get("target_speed")
        source = limit.source
        if target is not None:
            options["speed_limit"] = max(round(limit.value, 3), float(target))
            if limit.value < float(target):  # the contract asks speed_limit ≥ target_speed
                source = f"target; {limit.source} {limit.value:.2f} below it"
        request["options"] = options
        cr_goal = judge.goal_request()
        if cr_goal:
            request["goal"] = cr_goal
        goal_s = _goal_arc_length(request)
        goal = None
        if judge.has_goal:
            goal = Goal(check=judge.goal_check())
            window = judge.goal_window()
            if window is not None:
                duration = min(duration, _cycles_to(window[1], settings.replan_period))
        elif conv.info.get("map_edge_extension_m"):
            # no goal state: the simulator's default, the reference's end, but at the map's edge
            margin = GOAL_MARGIN_LENGTHS * float(request["vehicle"]["length"])
            goal = Goal(s_min=_map_end(conv, float(conv.info["length_m"])) - margin)
    horizon = float((request.get("options") or {}).get("horizon_time", _DEFAULT_HORIZON))
    obstacles, leaves = continued_predictions(request.get("obstacles", []), horizon)
    request["obstacles"] = obstacles
    problem = problem_from_json(request)
    collision = None
    if judge is not None:
        collision = judge.collision_check(duration, problem.vehicle.length, problem.vehicle.width)
    return Prepared(name, conv, request, problem, goal, duration, judge, source, goal_s, collision, leaves)


# --------------------------------------------------------------------------------------------------
# The outcome: one row
# --------------------------------------------------------------------------------------------------

#: results.csv's columns and what they mean (the README's table is made from it)
COLUMNS: dict[str, str] = {
    "scene": "the scene's file name",
    "vehicle": "car (CommonRoad's vehicle type 2), point (the point model) or request (the request's own)",
    "duration_s": "the longest simulated time asked for [s]",
    "status": "done, error (the scene raised or its worker died) or timeout (it ran past --timeout)",
    "error": "what went wrong (status error or timeout), else empty",
    "judge": "commonroad (judged against the scenario's XML) or sim (no XML: the simulator's own checks)",
    "has_goal": "whether the scenario has a goal (a scene without one succeeds by surviving its run)",
    "goal": "goal reached: CommonRoad's GoalRegion.is_reached on a driven state (judge sim: s_min reached)",
    "goal_time_s": "when the goal was first reached [s]",
    "collision": "a collision: the drivability checker's collision checker (judge sim: the simulator's)",
    "collided": "ids of the obstacles collided with, in order of contact (;-separated)",
    "rear_end": "how many of those are rear-end collisions by traffic from behind (see README)",
    "off_road_steps": "time steps whose footprint leaves the union of the scenario's lanelets",
    "feasible_transitions": "driven transitions the drivability checker finds feasible (KS, vehicle type 2)",
    "transitions": "driven transitions judged (one per scenario time step)",
    "feasible": "whether every driven transition is feasible",
    "success": "goal reached (or survived, without a goal) and no collision and feasible",
    "termination": "how the run ended: goal, collision or timeout (the duration or the goal's window)",
    "sim_time_s": "simulated time [s]",
    "cycles": "replan cycles",
    "ok": "plans with status ok",
    "stopped": "plans with status stopped",
    "fallback": "plans with status fallback",
    "plan_errors": "plan calls that raised (the vehicle brakes for that cycle)",
    "sim_collisions": "simulator sub-steps (0.01 s) whose footprint hits an obstacle of the request",
    "min_clearance_m": "smallest distance of the footprint to an obstacle of the request [m]",
    "lane_departure_m": "farthest a footprint corner or side point got outside the request's lane [m] "
    "(≤ 0: inside)",
    "cycle_p50_ms": "median wall time of a plan call [ms]",
    "cycle_p99_ms": "99th percentile of the plan calls' wall time [ms]",
    "cycle_max_ms": "longest plan call [ms]",
    "wall_s": "wall time of the scene: preparing, the closed loop and the judging [s]",
    "driven_m": "arc length driven along the reference [m]",
    "goal_m": "the goal region's centroid's arc length ahead of the start on the reference [m] (judge sim: "
    "s_min), when the goal has a position",
    "target_speed": "the request's target speed [m/s]",
    "speed_limit": "the request's options.speed_limit [m/s]",
    "speed_limit_source": "where the speed limit comes from: sign, lanelet type, scenario tag or default; "
    "target when that limit is below the target speed (the limit is then the target)",
}


@dataclass(frozen=True)
class Outcome:
    """One scene's row of ``results.csv`` (see :data:`COLUMNS`); None where not measured."""

    scene: str
    vehicle: str
    duration_s: float
    status: str = "done"
    error: str = ""
    judge: str = ""
    has_goal: bool | None = None
    goal: bool | None = None
    goal_time_s: float | None = None
    collision: bool | None = None
    collided: str = ""
    rear_end: int | None = None
    off_road_steps: int | None = None
    feasible_transitions: int | None = None
    transitions: int | None = None
    feasible: bool | None = None
    success: bool = False
    termination: str = ""
    sim_time_s: float | None = None
    cycles: int | None = None
    ok: int | None = None
    stopped: int | None = None
    fallback: int | None = None
    plan_errors: int | None = None
    sim_collisions: int | None = None
    min_clearance_m: float | None = None
    lane_departure_m: float | None = None
    cycle_p50_ms: float | None = None
    cycle_p99_ms: float | None = None
    cycle_max_ms: float | None = None
    wall_s: float | None = None
    driven_m: float | None = None
    goal_m: float | None = None
    target_speed: float | None = None
    speed_limit: float | None = None
    speed_limit_source: str = ""

    @classmethod
    def failed(cls, scene: str, settings: Settings, status: str, error: str, wall: float) -> Outcome:
        """The row of a scene that raised, died or hung."""
        return cls(scene, settings.vehicle, settings.duration, status=status, error=error, wall_s=wall)

    def row(self) -> dict[str, str]:
        """The CSV row: booleans as yes/no, numbers rounded, None as empty."""
        out: dict[str, str] = {}
        for key, value in asdict(self).items():
            if value is None:
                out[key] = ""
            elif isinstance(value, bool):
                out[key] = "yes" if value else "no"
            elif isinstance(value, float):
                out[key] = f"{value:.4g}" if abs(value) < 1e4 else f"{value:.1f}"
            else:
                out[key] = str(value)
        return out

    @classmethod
    def from_row(cls, row: dict[str, str]) -> Outcome:
        """The outcome of a CSV row written by :meth:`row` (unknown columns ignored)."""
        values: dict[str, Any] = {}
        for f in fields(cls):
            text = row.get(f.name, "")
            kind = str(f.type)
            if "bool" in kind:
                values[f.name] = None if text == "" else text == "yes"
            elif "int" in kind:
                values[f.name] = None if text == "" else int(float(text))
            elif "float" in kind:
                values[f.name] = None if text == "" else float(text)
            else:
                values[f.name] = text
        return cls(**values)


def write_csv(outcomes: Iterable[Outcome], out: Path) -> Path:
    """``results.csv``: a header of :data:`COLUMNS`, a row per outcome (written to a temporary file
    and renamed, so that a run stopped meanwhile leaves the previous file)."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(COLUMNS), lineterminator="\n")
    writer.writeheader()
    for o in outcomes:
        writer.writerow(o.row())
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(buffer.getvalue())
    tmp.replace(out)
    return out


def read_csv(path: Path) -> list[Outcome]:
    """The outcomes of a ``results.csv`` (none if it does not exist)."""
    if not path.is_file():
        return []
    with path.open(newline="") as fh:
        return [Outcome.from_row(row) for row in csv.DictReader(fh)]


# --------------------------------------------------------------------------------------------------
# Running and judging one scene
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SceneRun:
    """What :func:`run_scene` gives: the row, and (when asked for) the run itself and its GIF."""

    outcome: Outcome
    prepared: Prepared | None = field(default=None, repr=False)
    result: SimResult | None = field(default=None, repr=False)
    gif: bytes | None = field(default=None, repr=False)


def judge_run(prepared: Prepared, result: SimResult, settings: Settings, wall: float) -> Outcome:
    """The row of a finished run (see the module docstring)."""
    m = result.metrics
    vehicle = result.problem.vehicle
    counts = m.status_counts
    ms = np.array([st.planning_ms for st in result.steps]) if result.steps else np.zeros(1)
    start = float(result.motion.s[0])
    common: dict[str, Any] = {
        "scene": prepared.name,
        "vehicle": settings.vehicle,
        "duration_s": settings.duration,
        "termination": m.termination,
        "sim_time_s": m.sim_time,
        "cycles": m.steps,
        "ok": counts["ok"],
        "stopped": counts["stopped"],
        "fallback": counts["fallback"],
        "plan_errors": counts["error"],
        "sim_collisions": m.collisions,
        "min_clearance_m": m.min_clearance,
        "lane_departure_m": m.max_lane_departure,
        "cycle_p50_ms": float(np.percentile(ms, 50)),
        "cycle_p99_ms": float(np.percentile(ms, 99)),
        "cycle_max_ms": float(ms.max()),
        "driven_m": m.final_s - start,
        "goal_m": None if prepared.goal_s is None else float(prepared.goal_s) - start,
        "target_speed": result.problem.options.target_speed,
        "speed_limit": result.problem.options.speed_limit,
        "speed_limit_source": prepared.speed_limit_source,
    }
    if prepared.judge is not None:
        v = prepared.judge.judge(result.motion, vehicle.length, vehicle.width)
        survived = m.termination != "collision"
        reached = v.goal_reached if v.has_goal else survived
        return Outcome(
            **common,
            wall_s=wall,
            judge="commonroad",
            has_goal=v.has_goal,
            goal=v.goal_reached if v.has_goal else None,
            goal_time_s=v.goal_time,
            collision=v.collision,
            collided=";".join(v.collided),
            rear_end=len(v.rear_end),
            off_road_steps=v.off_road_steps,
            feasible_transitions=sum(v.feasible),
            transitions=len(v.feasible),
            feasible=v.all_feasible,
            success=bool(reached and not v.collision and v.all_feasible),
        )
    feasible: list[bool] | None = None
    if not COMMONROAD.missing():
        feasible = feasible_transitions(driven_states(result.motion, FEASIBILITY_DT), FEASIBILITY_DT)
    collided = m.collisions > 0
    return Outcome(
        **common,
        wall_s=wall,
        judge="sim",
        has_goal=True,
        goal=m.goal_reached,
        goal_time_s=m.time_to_goal,
        collision=collided,
        collided=";".join(m.collided_with),
        feasible_transitions=None if feasible is None else sum(feasible),
        transitions=None if feasible is None else len(feasible),
        feasible=None if feasible is None else all(feasible),
        success=bool(m.goal_reached and not collided and (feasible is None or all(feasible))),
    )


def run_scene(
    path: str | Path,
    settings: Settings = DEFAULTS,
    *,
    name: str | None = None,
    keep: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> SceneRun:
    """Prepare, drive and judge one scene; a scene that cannot be read or run becomes a row with its
    error (status ``error``). ``keep``: the run and its preparation come back too (not for Ray: large).
    ``name``: the row's scene name (default: the file's name)."""
    t0 = time.perf_counter()
    scene = name or Path(path).name
    try:
        prepared = prepare(path, settings)
        result = simulate(
            prepared.problem,
            duration=prepared.duration,
            replan_period=settings.replan_period,
            goal=prepared.goal,
            progress=progress,
            collision=prepared.collision,
            leaves=prepared.leaves,
        )
        outcome = judge_run(prepared, result, settings, 0.0)
        gif = _gif(result) if settings.gif else None
    except Exception as exc:  # any failure of one scene is its row, never a lost run
        wall = time.perf_counter() - t0
        return SceneRun(Outcome.failed(scene, settings, "error", _error_text(exc), wall))
    outcome = replace(outcome, scene=scene, wall_s=time.perf_counter() - t0)
    return SceneRun(outcome, prepared if keep else None, result if keep else None, gif)


def _error_text(exc: BaseException) -> str:
    where = traceback.extract_tb(exc.__traceback__)[-1:] if exc.__traceback__ else []
    at = f" (at {Path(where[0].filename).name}:{where[0].lineno})" if where else ""
    return f"{type(exc).__name__}: {exc}{at}".replace("\n", " ")


def _gif(result: SimResult) -> bytes:
    from planner_tools import render

    with tempfile.TemporaryDirectory(prefix="kappa-gif-") as tmp:
        out = Path(tmp) / "sim.gif"
        render.write_gif([result], out, stride=2, dpi=100, quiet=True)
        return out.read_bytes()


# --------------------------------------------------------------------------------------------------
# The table (bench/commonroad.py, summary.md)
# --------------------------------------------------------------------------------------------------


def _yes(value: bool | None) -> str:
    return "—" if value is None else ("yes" if value else "no")


def _num(value: float | None, digits: int = 2) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def _goal_text(o: Outcome) -> str:
    if o.has_goal is False:
        return "none"
    if o.goal and o.goal_time_s is not None:
        return f"yes ({o.goal_time_s:.1f} s)"
    return _yes(o.goal)


def _collision_text(o: Outcome) -> str:
    if o.collision is None:
        return "—"
    if not o.collision:
        return "no"
    hit = len(o.collided.split(";")) if o.collided else 1
    return f"{hit}" + (f" ({o.rear_end} rear-end)" if o.rear_end else "")


TABLE_HEAD = (
    "| scenario | goal (CommonRoad) | collisions (checker) | off-road steps | feasible transitions "
    "| success | sim collisions | min clearance [m] | lane departure [m] | plan median / p99 / max [ms] "
    "| steps | ok / stopped / fallback / error | end | driven [m] / goal [m] | speed limit [m/s] |"
)


def table(outcomes: Sequence[Outcome]) -> str:
    """The markdown table of ``outcomes`` and a line of totals."""
    lines = [TABLE_HEAD, "|" + "---|" * TABLE_HEAD.count(" |")]
    for o in outcomes:
        if o.status != "done":
            lines.append(f"| {o.scene} | {o.status}: {o.error} |" + " |" * (TABLE_HEAD.count(" |") - 2))
            continue
        feasible = "—" if o.transitions is None else f"{o.feasible_transitions} / {o.transitions}"
        goal = "—" if o.goal_m is None else f"{o.goal_m:.0f}"
        limit = "—" if o.speed_limit is None else f"{o.speed_limit:.1f} ({o.speed_limit_source})"
        cycle = f"{o.cycle_p50_ms:.0f} / {o.cycle_p99_ms:.0f} / {o.cycle_max_ms:.0f}"
        lines.append(
            f"| {o.scene} | {_goal_text(o)} | {_collision_text(o)} | {_num(o.off_road_steps, 0)} "
            f"| {feasible} | {'**yes**' if o.success else 'no'} | {o.sim_collisions} "
            f"| {_num(o.min_clearance_m)} | {_num(o.lane_departure_m)} | {cycle} "
            f"| {o.cycles} | {o.ok} / {o.stopped} / {o.fallback} / {o.plan_errors} | {o.termination} "
            f"| {_num(o.driven_m, 0)} / {goal} | {limit} |"
        )
    lines += ["", totals(outcomes)]
    return "\n".join(lines)


def totals(outcomes: Sequence[Outcome]) -> str:
    """One line: successes, goals, collisions (rear-end apart), feasibility, failures."""
    done = [o for o in outcomes if o.status == "done"]
    with_goal = [o for o in done if o.has_goal]
    reached = sum(bool(o.goal) for o in with_goal)
    hit = [o for o in done if o.collision]
    rear = sum(1 for o in hit if o.rear_end and o.rear_end == len(o.collided.split(";")))
    judged = [o for o in done if o.transitions is not None]
    feasible = sum(o.feasible_transitions or 0 for o in judged)
    transitions = sum(o.transitions or 0 for o in judged)
    share = f"{100.0 * feasible / transitions:.1f} %" if transitions else "—"
    failed = len(outcomes) - len(done)
    return (
        f"**{sum(o.success for o in done)} of {len(outcomes)} scenes succeed** (goal ∧ no collision ∧ "
        f"feasible). Goals reached: {reached} of {len(with_goal)} with a goal; runs with a collision: "
        f"{len(hit)} ({rear} of them only rear-end by traffic from behind); runs off the road: "
        f"{sum(1 for o in done if o.off_road_steps)}; all transitions feasible in "
        f"{sum(1 for o in judged if o.feasible)} of {len(judged)} runs ({feasible} / {transitions} "
        f"transitions, {share}); fallbacks: {sum(o.fallback or 0 for o in done)} in "
        f"{sum(1 for o in done if o.fallback)} runs"
        + (f"; {failed} scenes failed (error or timeout)." if failed else ".")
    )
