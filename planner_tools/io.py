"""Planning requests as plain JSON data ⇄ :class:`~planner.problem.PlanningProblem`, without pydantic.

The format is the body of ``POST /v1/plan`` (``reference_line``, ``lane``, ``obstacles``, ``ego``,
``vehicle``, ``options``, and optionally ``road`` and ``goal``); the HTTP layer validates it with its
own models (``app.models``, with size limits for a public service), this module is what local clients
such as the command line use. It checks what the planner needs — required and unknown keys, JSON types
(a number is a JSON number, not a string or a boolean), finiteness, signs, shapes — and raises
:class:`~planner.errors.InvalidInputError` naming the field (``obstacles[2].circle.radius``).
Geometric problems (a reference that runs back on itself, …) are the planner's to find, as for any
problem. Every field of :class:`~planner.problem.Options` is read, a superset of the HTTP request's
options. Units: metres [m], seconds [s], radians [rad].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import fields
from typing import Any, TypeVar, get_args

import numpy as np

from planner.errors import InvalidInputError
from planner.goal import Goal, GoalCircle, GoalPolygon, GoalPosition
from planner.problem import (
    CAR_FIELDS,
    CircleObstacle,
    DynamicObstacle,
    Ego,
    Generator,
    Lane,
    Obstacle,
    Options,
    PlanningProblem,
    PolygonObstacle,
    Road,
    Vehicle,
)
from planner.reference import FloatArray

_TOP = {"reference_line", "lane", "obstacles", "ego", "vehicle", "options", "road", "goal"}
_EGO = {"x", "y", "heading", "speed", "acceleration", "curvature"}
_VEHICLE = (
    "length",
    "width",
    "max_speed",
    "max_acceleration",
    "max_deceleration",
    "max_lateral_acceleration",
    "max_curvature",
)
#: every field of :class:`Options` with its annotation (a superset of the HTTP request's options)
_OPTION_TYPES = {f.name: str(f.type) for f in fields(Options)}
#: options that must be positive, and the smallest value of integer options
_POSITIVE_OPTIONS = {"horizon_time", "dt", "time_budget_ms"}
_MIN_INTEGER = {"num_candidates": 1, "num_points": 10}


def _object(value: Any, where: str, allowed: set[str], required: tuple[str, ...] = ()) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise InvalidInputError("must be an object", field=where or None)
    for key in value:
        if key not in allowed:
            raise InvalidInputError("is not a known field", field=_join(where, str(key)))
    for key in required:
        if key not in value:
            raise InvalidInputError("is required", field=_join(where, key))
    return value


def _join(where: str, key: str) -> str:
    return f"{where}.{key}" if where else key


def _number(value: Any, where: str, *, minimum: float | None = None, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InvalidInputError("must be a number", field=where)
    number = float(value)
    if not math.isfinite(number):
        raise InvalidInputError("must be finite", field=where)
    if positive and not number > 0.0:
        raise InvalidInputError("must be positive", field=where)
    if minimum is not None and number < minimum:
        raise InvalidInputError(f"must be ≥ {minimum:g}", field=where)
    return number


def _integer(value: Any, where: str, *, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise InvalidInputError("must be an integer", field=where)
    if value < minimum:
        raise InvalidInputError(f"must be ≥ {minimum}", field=where)
    return int(value)


def _list(value: Any, where: str, *, min_length: int = 0) -> list[Any]:
    if not isinstance(value, list | tuple):
        raise InvalidInputError("must be a list", field=where)
    if len(value) < min_length:
        raise InvalidInputError(f"must have at least {min_length} items", field=where)
    return list(value)


def _points(value: Any, where: str, *, min_length: int) -> FloatArray:
    items = _list(value, where, min_length=min_length)
    out = np.empty((len(items), 2))
    for i, item in enumerate(items):
        pair = _list(item, f"{where}[{i}]")
        if len(pair) != 2:
            raise InvalidInputError("must be a point [x, y]", field=f"{where}[{i}]")
        out[i] = [_number(pair[0], f"{where}[{i}][0]"), _number(pair[1], f"{where}[{i}][1]")]
    return out


def _width(value: Any, where: str, n: int) -> float | FloatArray:
    if isinstance(value, list | tuple):
        if len(value) != n:
            raise InvalidInputError(
                f"has {len(value)} values but reference_line has {n} points; give one width per "
                "reference point or a single number",
                field=where,
            )
        return np.array([_number(w, f"{where}[{i}]", minimum=0.0) for i, w in enumerate(value)])
    return _number(value, where, minimum=0.0)


def _obstacle(value: Any, where: str) -> Obstacle:
    if not isinstance(value, Mapping):
        raise InvalidInputError("must be an object", field=where)
    kinds = [k for k in ("polygon", "circle", "prediction") if k in value]
    if len(kinds) != 1:
        raise InvalidInputError(
            "an obstacle is an object with exactly one of 'polygon', 'circle' or 'prediction'", field=where
        )
    kind = kinds[0]
    allowed = {"id", kind} | ({"length", "width"} if kind == "prediction" else set())
    required = ("id", kind) + (("length", "width") if kind == "prediction" else ())
    data = _object(value, where, allowed, required)
    ob_id = data["id"]
    if not isinstance(ob_id, str) or not ob_id:
        raise InvalidInputError("must be a non-empty string", field=f"{where}.id")
    if kind == "polygon":
        polygon = _points(data["polygon"], f"{where}.polygon", min_length=3)
        rel = polygon - polygon[0]
        area = 0.5 * abs(
            float(np.sum(rel[:, 0] * np.roll(rel[:, 1], -1) - np.roll(rel[:, 0], -1) * rel[:, 1]))
        )
        if not area > 1e-6:
            raise InvalidInputError(
                "the polygon has no area: its points coincide or are collinear", field=f"{where}.polygon"
            )
        return PolygonObstacle(id=ob_id, polygon=polygon)
    if kind == "circle":
        circle = _object(data["circle"], f"{where}.circle", {"center", "radius"}, ("center", "radius"))
        center = _points([circle["center"]], f"{where}.circle.center", min_length=1)[0]
        radius = _number(circle["radius"], f"{where}.circle.radius", positive=True)
        return CircleObstacle(id=ob_id, center=center, radius=radius)
    length = _number(data["length"], f"{where}.length", positive=True)
    width = _number(data["width"], f"{where}.width", positive=True)
    states = _list(data["prediction"], f"{where}.prediction", min_length=1)
    rows = np.empty((len(states), 4))
    for i, st in enumerate(states):
        at = f"{where}.prediction[{i}]"
        state = _object(st, at, {"t", "x", "y", "heading"}, ("t", "x", "y", "heading"))
        rows[i] = [_number(state[k], f"{at}.{k}") for k in ("t", "x", "y", "heading")]
        if i > 0 and not rows[i, 0] > rows[i - 1, 0]:
            raise InvalidInputError(
                f"t must increase strictly: {rows[i, 0]} follows {rows[i - 1, 0]}", field=f"{at}.t"
            )
    return DynamicObstacle(id=ob_id, length=length, width=width, prediction=rows)


W = TypeVar("W", bound=Lane)


def _widths(value: Any, key: str, n: int, kind: type[W]) -> W:
    data = _object(value, key, {"left_width", "right_width"}, ("left_width", "right_width"))
    return kind(
        left_width=_width(data["left_width"], f"{key}.left_width", n),
        right_width=_width(data["right_width"], f"{key}.right_width", n),
    )


def _goal(value: Any) -> Goal:
    data = _object(value, "goal", {"position", "time", "speed"})
    position: GoalPosition | None = None
    if data.get("position") is not None:
        shape = _object(data["position"], "goal.position", {"polygon", "circle"})
        if len(shape) != 1:
            raise InvalidInputError("must have exactly one of 'polygon' or 'circle'", field="goal.position")
        if "polygon" in shape:
            position = GoalPolygon(_points(shape["polygon"], "goal.position.polygon", min_length=3))
        else:
            where = "goal.position.circle"
            circle = _object(shape["circle"], where, {"center", "radius"}, ("center", "radius"))
            center = _points([circle["center"]], f"{where}.center", min_length=1)[0]
            position = GoalCircle(center, _number(circle["radius"], f"{where}.radius", positive=True))
    time, speed = (_interval(data.get(key), f"goal.{key}") for key in ("time", "speed"))
    return Goal(position=position, time=time, speed=speed)  # checks the intervals' order and signs


def _interval(value: Any, where: str) -> tuple[float, float] | None:
    if value is None:
        return None
    pair = _list(value, where)
    if len(pair) != 2:
        raise InvalidInputError("must be a pair [low, high]", field=where)
    return _number(pair[0], f"{where}[0]"), _number(pair[1], f"{where}[1]")


def _option(key: str, value: Any) -> Any:
    where, kind = f"options.{key}", _OPTION_TYPES[key]
    if value is None and "None" in kind:
        return None
    if kind == "bool":
        if not isinstance(value, bool):
            raise InvalidInputError("must be true or false", field=where)
        return value
    if kind == "Generator":
        if value not in get_args(Generator):
            raise InvalidInputError(f"must be one of {', '.join(get_args(Generator))}", field=where)
        return value
    if kind.startswith("int"):
        return _integer(value, where, minimum=_MIN_INTEGER.get(key, 0))
    if key in _POSITIVE_OPTIONS:
        return _number(value, where, positive=True)
    return _number(value, where, minimum=0.0)


def problem_from_json(data: Any) -> PlanningProblem:
    """The :class:`PlanningProblem` of a planning request's JSON data (a ``dict`` from ``json.load``).

    Raises:
        InvalidInputError: for a missing, unknown, mistyped or out-of-range field (``field`` names it).
    """
    top = _object(data, "", _TOP, ("reference_line", "lane", "ego"))
    reference = _points(top["reference_line"], "reference_line", min_length=2)
    n = reference.shape[0]
    lane = _widths(top["lane"], "lane", n, Lane)
    road = None if top.get("road") is None else _widths(top["road"], "road", n, Road)
    goal = None if top.get("goal") is None else _goal(top["goal"])
    obstacles = tuple(
        _obstacle(o, f"obstacles[{i}]") for i, o in enumerate(_list(top.get("obstacles", []), "obstacles"))
    )
    seen: set[str] = set()
    for i, ob in enumerate(obstacles):
        if ob.id in seen:
            raise InvalidInputError("another obstacle has this id", field=f"obstacles[{i}].id")
        seen.add(ob.id)

    ego_data = _object(top["ego"], "ego", _EGO, ("x", "y", "heading"))
    curvature = ego_data.get("curvature")
    ego = Ego(
        x=_number(ego_data["x"], "ego.x"),
        y=_number(ego_data["y"], "ego.y"),
        heading=_number(ego_data["heading"], "ego.heading"),
        speed=_number(ego_data.get("speed", 0.0), "ego.speed", minimum=0.0),
        acceleration=_number(ego_data.get("acceleration", 0.0), "ego.acceleration"),
        curvature=None if curvature is None else _number(curvature, "ego.curvature"),
    )

    vehicle_data = _object(top.get("vehicle", {}), "vehicle", set(_VEHICLE) | set(CAR_FIELDS))
    # a car's fields may be null (the point model: no wheelbase); the offset may be 0, the rest > 0
    vehicle = Vehicle(
        **{
            k: _number(v, f"vehicle.{k}", minimum=0.0 if k == "rear_axle_offset" else None,
                       positive=k != "rear_axle_offset")
            for k, v in vehicle_data.items()
            if not (v is None and k in CAR_FIELDS)
        }
    )  # fmt: skip

    opt = _object(top.get("options", {}), "options", set(_OPTION_TYPES))
    values = {key: _option(key, value) for key, value in opt.items()}
    return PlanningProblem(
        reference_line=reference,
        lane=lane,
        ego=ego,
        obstacles=obstacles,
        vehicle=vehicle,
        options=Options(**values),
        road=road,
        goal=goal,
    )


def _width_json(width: float | FloatArray) -> float | list[float]:
    arr = np.asarray(width, dtype=float)
    return float(arr) if arr.ndim == 0 else [float(w) for w in arr.tolist()]


def _obstacle_json(ob: Obstacle) -> dict[str, Any]:
    if isinstance(ob, PolygonObstacle):
        return {"id": ob.id, "polygon": np.asarray(ob.polygon, dtype=float).tolist()}
    if isinstance(ob, CircleObstacle):
        center = [float(v) for v in np.asarray(ob.center, dtype=float)]
        return {"id": ob.id, "circle": {"center": center, "radius": float(ob.radius)}}
    return {
        "id": ob.id,
        "length": float(ob.length),
        "width": float(ob.width),
        "prediction": [
            {"t": t, "x": x, "y": y, "heading": h} for t, x, y, h in np.asarray(ob.prediction).tolist()
        ],
    }


def _goal_json(goal: Goal) -> dict[str, Any]:
    out: dict[str, Any] = {}
    if isinstance(goal.position, GoalPolygon):
        out["position"] = {"polygon": np.asarray(goal.position.polygon, dtype=float).tolist()}
    elif isinstance(goal.position, GoalCircle):
        center = [float(v) for v in goal.position.center]
        out["position"] = {"circle": {"center": center, "radius": float(goal.position.radius)}}
    for key in ("time", "speed"):
        interval = getattr(goal, key)
        if interval is not None:
            out[key] = [float(v) for v in interval]
    return out


def problem_to_json(problem: PlanningProblem) -> dict[str, Any]:
    """The planning request of ``problem`` as JSON data (what :func:`problem_from_json` reads back),
    with every option (the HTTP layer refuses those it does not publish, such as ``lateral_margin``)."""
    e, v, o = problem.ego, problem.vehicle, problem.options
    return {
        "reference_line": np.asarray(problem.reference_line, dtype=float).tolist(),
        "lane": {
            "left_width": _width_json(problem.lane.left_width),
            "right_width": _width_json(problem.lane.right_width),
        },
        "obstacles": [_obstacle_json(ob) for ob in problem.obstacles],
        "ego": {
            "x": float(e.x),
            "y": float(e.y),
            "heading": float(e.heading),
            "speed": float(e.speed),
            "acceleration": float(e.acceleration),
            "curvature": None if e.curvature is None else float(e.curvature),
        },
        "vehicle": {
            **{k: float(getattr(v, k)) for k in _VEHICLE},
            **{k: float(getattr(v, k)) for k in CAR_FIELDS if getattr(v, k) is not None},
        },
        "options": {k: getattr(o, k) for k in _OPTION_TYPES},
        **(
            {}
            if problem.road is None
            else {
                "road": {
                    "left_width": _width_json(problem.road.left_width),
                    "right_width": _width_json(problem.road.right_width),
                }
            }
        ),
        **({} if problem.goal is None else {"goal": _goal_json(problem.goal)}),
    }
