"""Every conversion between the API's models and the planner's dataclasses, in one place.

:func:`to_problem` turns a validated request into a :class:`planner.problem.PlanningProblem`;
:func:`from_problem` goes the other way (the demo endpoint); :func:`candidates_data`,
:func:`candidate_data`, :func:`frenet_data`, :func:`cartesian_data` and :func:`plan_data` write the
answers as the JSON data of their response models: plain lists and dicts built from the arrays (no
model per point; finiteness checked on the arrays), ready for ``pydantic_core.to_json``.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache
from typing import Any, get_args

import numpy as np

from app.models.candidates import CandidatesDiagnostics
from app.models.goal import Goal, GoalCircle, GoalDisc, GoalPolygon
from app.models.plan import STAGES, DecisionReason, LateralBackend, RequestTiming, TrajectoryPoint
from app.models.planning import (
    AnyObstacle,
    Circle,
    CircleObstacle,
    DynamicObstacle,
    Ego,
    Lane,
    Options,
    PlanningRequest,
    PolygonObstacle,
    PredictedState,
    Road,
    Vehicle,
)
from planner import goal as pg
from planner import problem as pp
from planner.candidates import CandidateSet
from planner.decision import BlockKind, Decision, LaneChoice, ReasonKind
from planner.ego import EgoFrenet
from planner.follower import FollowerReason
from planner.frenet import FrenetPoints
from planner.goal import GoalReason, GoalReport, GoalStatus
from planner.reference import ReferenceLine
from planner.result import PlanResult
from planner.result import Status as PlanStatus
from planner.roads import demo_problem
from planner.speed import ProfileKind
from solvers.result import SolveInfo, SolverStatus

# -- requests ----------------------------------------------------------------------------------


def _array(value: Any) -> Any:
    return np.asarray(value, dtype=float) if isinstance(value, list) else float(value)


def _obstacle_to_problem(o: AnyObstacle) -> pp.Obstacle:
    if isinstance(o, PolygonObstacle):
        return pp.PolygonObstacle(id=o.id, polygon=np.asarray(o.polygon, dtype=float))
    if isinstance(o, CircleObstacle):
        return pp.CircleObstacle(
            id=o.id, center=np.asarray(o.circle.center, dtype=float), radius=o.circle.radius
        )
    states = np.array([[p["t"], p["x"], p["y"], p["heading"]] for p in o.prediction], dtype=float)
    return pp.DynamicObstacle(id=o.id, length=o.length, width=o.width, prediction=states)


def _goal_to_problem(goal: Goal) -> pg.Goal:
    position: pg.GoalPosition | None = None
    if isinstance(goal.position, GoalPolygon):
        position = pg.GoalPolygon(polygon=np.asarray(goal.position.polygon, dtype=float))
    elif isinstance(goal.position, GoalCircle):
        disc = goal.position.circle
        position = pg.GoalCircle(center=np.asarray(disc.center, dtype=float), radius=disc.radius)
    return pg.Goal(position=position, time=goal.time, speed=goal.speed)


def to_problem(request: PlanningRequest, *, time_budget_ms: float | None = None) -> pp.PlanningProblem:
    """The planner's :class:`~planner.problem.PlanningProblem` of a validated request;
    ``time_budget_ms`` [ms], when given, is the plan's budget instead of the request's (the service
    passes what remains of the request's budget once it has waited, :mod:`app.jobs`)."""
    options, r = request.options.model_dump(), request.road
    if time_budget_ms is not None:
        options["time_budget_ms"] = time_budget_ms
    return pp.PlanningProblem(
        reference_line=np.asarray(request.reference_line, dtype=float),
        lane=pp.Lane(
            left_width=_array(request.lane.left_width),
            right_width=_array(request.lane.right_width),
        ),
        ego=pp.Ego(**request.ego.model_dump()),
        obstacles=tuple(_obstacle_to_problem(o) for o in request.obstacles),
        vehicle=pp.Vehicle(**request.vehicle.model_dump()),
        options=pp.Options(**options),
        road=None if r is None else pp.Road(*map(_array, (r.left_width, r.right_width))),
        goal=None if request.goal is None else _goal_to_problem(request.goal),
    )


def _points(array: Any) -> list[tuple[float, float]]:
    return [(float(x), float(y)) for x, y in np.asarray(array, dtype=float).tolist()]


def _width_from_problem(width: Any) -> float | list[float]:
    arr = np.asarray(width, dtype=float)
    return float(arr) if arr.ndim == 0 else [float(w) for w in arr.tolist()]


def _obstacle_from_problem(o: pp.Obstacle) -> AnyObstacle:
    if isinstance(o, pp.PolygonObstacle):
        return PolygonObstacle(id=o.id, polygon=_points(o.polygon))
    if isinstance(o, pp.CircleObstacle):
        x, y = (float(v) for v in np.asarray(o.center, dtype=float))
        return CircleObstacle(id=o.id, circle=Circle(center=(x, y), radius=float(o.radius)))
    states = [
        PredictedState(t=t, x=x, y=y, heading=h)
        for t, x, y, h in np.asarray(o.prediction, dtype=float).tolist()
    ]
    return DynamicObstacle(id=o.id, length=float(o.length), width=float(o.width), prediction=states)


def _goal_from_problem(goal: pg.Goal) -> Goal:
    position: GoalPolygon | GoalCircle | None = None
    if isinstance(goal.position, pg.GoalPolygon):
        position = GoalPolygon(polygon=_points(goal.position.polygon))
    elif isinstance(goal.position, pg.GoalCircle):
        x, y = (float(v) for v in goal.position.center)
        position = GoalCircle(circle=GoalDisc(center=(x, y), radius=float(goal.position.radius)))
    return Goal(position=position, time=goal.time, speed=goal.speed)


def from_problem(problem: pp.PlanningProblem) -> PlanningRequest:
    """The request that :func:`to_problem` turns into ``problem`` (validated like any request).

    ``Options.lateral_margin`` and ``Options.min_path_length`` are not part of the HTTP contract and
    are dropped.
    """
    o = problem.options
    return PlanningRequest(
        reference_line=_points(problem.reference_line),
        lane=Lane(
            left_width=_width_from_problem(problem.lane.left_width),
            right_width=_width_from_problem(problem.lane.right_width),
        ),
        obstacles=[_obstacle_from_problem(ob) for ob in problem.obstacles],
        ego=Ego(
            x=problem.ego.x,
            y=problem.ego.y,
            heading=problem.ego.heading,
            speed=problem.ego.speed,
            acceleration=problem.ego.acceleration,
            curvature=problem.ego.curvature,
        ),
        vehicle=Vehicle(**{k: getattr(problem.vehicle, k) for k in Vehicle.model_fields}),
        options=Options(**{k: getattr(o, k) for k in Options.model_fields}),
        road=None
        if problem.road is None
        else Road(
            left_width=_width_from_problem(problem.road.left_width),
            right_width=_width_from_problem(problem.road.right_width),
        ),
        goal=None if problem.goal is None else _goal_from_problem(problem.goal),
    )


@cache
def demo_request() -> PlanningRequest:
    """The built-in demo problem (:func:`planner.roads.demo_problem`) as a request."""
    return from_problem(demo_problem())


@cache
def demo_goal() -> Goal:
    """A goal past the demo's U-turn: stop in the box after it, between 5 and 9 s from now."""
    return Goal.model_validate(
        {"position": {"polygon": [[-4, 13], [4, 13], [4, 19], [-4, 19]]}, "time": [5, 9], "speed": [0, 0.5]}
    )


def demo_with_follower(request: PlanningRequest, faster: float = 1.0) -> PlanningRequest:
    """``request`` (the demo's, or the demo's with its goal) with a car 15 m behind the ego in its lane,
    ``faster`` [m/s] faster, straight on for the horizon: a plan of it bounds the profile from below (a
    follower's speed problem, a QP of its own)."""
    ego = request.ego
    speed = ego.speed + faster
    times = np.linspace(0.0, float(request.options.horizon_time), 9)
    c, s = float(np.cos(ego.heading)), float(np.sin(ego.heading))
    start = np.array([ego.x - 15.0 * c, ego.y - 15.0 * s])
    prediction = [
        {
            "t": float(t),
            "x": float(start[0] + speed * t * c),
            "y": float(start[1] + speed * t * s),
            "heading": ego.heading,
        }
        for t in times
    ]
    follower = {"id": "follower", "length": 4.5, "width": 1.8, "prediction": prediction}
    data = request.model_dump(mode="json", exclude_none=True)
    data["obstacles"] = [*data.get("obstacles", []), follower]
    return PlanningRequest.model_validate(data)


# -- answers -----------------------------------------------------------------------------------


def _lateral_backend(info: SolveInfo) -> str:
    """The lateral QP's backend as the answer names it (``none`` for a QP that did not run); an unknown
    one is a bug (``ValueError``)."""
    backend = str(info.extras.get("backend", "none"))
    if backend not in get_args(LateralBackend):
        raise ValueError(f"unknown lateral QP backend {backend!r}")
    return backend


def _require_finite(what: str, *arrays: Any) -> None:
    """Raise ``ValueError`` (a bug of the server: answered 500) if any of ``arrays`` is not finite."""
    for array in arrays:
        if not np.isfinite(np.asarray(array, dtype=float)).all():
            raise ValueError(f"{what} holds a non-finite number")


def candidates_data(cs: CandidateSet, ref: ReferenceLine, start: EgoFrenet) -> dict[str, Any]:
    """The answer of ``/v1/candidates`` as the JSON data of
    :class:`~app.models.candidates.CandidatesResponse`: the candidates ``cs`` generated on ``ref``
    from the ego's Frenet state ``start``, and their diagnostics."""
    diagnostics = CandidatesDiagnostics(
        generated=cs.count,
        repaired=int(np.count_nonzero(cs.repaired)),
        generator=cs.generator,
        reference_samples=ref.size,
        reference_spacing=ref.spacing,
        reference_length=ref.length,
        reference_max_curvature=float(np.max(np.abs(ref.kappa))),
        ego_s=start.s,
        ego_d=start.d,
        kept_points=int(np.count_nonzero(cs.valid)),
    )
    return {"candidates": candidate_data(cs), "diagnostics": diagnostics.model_dump(mode="json")}


def frenet_data(fr: FrenetPoints) -> dict[str, Any]:
    """The answer of ``/v1/frenet`` (:class:`~app.models.coordinates.FrenetResponse`) as JSON data."""
    _require_finite("a Frenet coordinate", fr.s, fr.d)
    return {"s": fr.s.tolist(), "d": fr.d.tolist()}


def cartesian_data(xy: np.ndarray) -> dict[str, Any]:
    """The answer of ``/v1/cartesian`` (:class:`~app.models.coordinates.CartesianResponse`) as JSON
    data."""
    _require_finite("a Cartesian point", xy)
    return {"points": np.asarray(xy, dtype=float).tolist()}


def candidate_data(cs: CandidateSet) -> list[dict[str, Any]]:
    """The kept points of every candidate of ``cs`` in driving order, as the JSON data of a list of
    :class:`~app.models.candidates.Candidate` (plain lists and dicts: no model per point; finiteness
    checked on the arrays)."""
    keep = cs.valid
    _require_finite("a candidate", cs.s[keep], cs.d[keep], cs.xy[keep])
    out: list[dict[str, Any]] = []
    for i in range(cs.count):
        s, d, xy = cs.points(i)
        points = [
            {"s": a, "d": b, "x": x, "y": y}
            for a, b, x, y in zip(s.tolist(), d.tolist(), xy[:, 0].tolist(), xy[:, 1].tolist(), strict=True)
        ]
        out.append({"points": points, "repaired": bool(cs.repaired[i])})
    return out


#: the fields of a trajectory point of the point model, and of a car (its steering angle too)
_POINT_FIELDS = tuple(name for name in TrajectoryPoint.model_fields if name != "steering_angle")
_CAR_FIELDS = (*_POINT_FIELDS, "steering_angle")


def decision_data(decision: Decision) -> dict[str, Any]:
    """The lane decision as the JSON data of :class:`~app.models.plan.LaneDecision` (fields that do not
    apply left out)."""
    r = decision.reason
    reason: dict[str, Any] = {"kind": ReasonKind(r.kind).value, "message": r.message}
    for name in DecisionReason.model_fields:  # in the model's order, as it writes them
        value = getattr(r, name, None)
        if name in reason or value is None:
            continue
        if name in ("s", "t"):
            _require_finite(f"the decision's {name}", value)
            reason[name] = float(value)
        else:
            reason[name] = BlockKind(value).value if name == "block" else str(value)
    return {"lane": LaneChoice(decision.lane).value, "reason": reason}


def plan_data(result: PlanResult, request_ms: Mapping[str, float]) -> dict[str, Any]:
    """The answer to :func:`planner.pipeline.plan`'s ``result`` as the JSON data of
    :class:`~app.models.plan.PlanResponse` (plain lists and dicts built from the arrays, ready for
    ``pydantic_core.to_json``; each point's ``steering_angle`` only for a car; ``candidates`` only when
    the planner returned them; every stage of
    :data:`~app.models.plan.STAGES`, 0 for one that did not run; ``follower`` only when one still hits
    the trajectory), with ``request_ms``, the
    request's budget and how long it waited and ran (:class:`~app.models.plan.RequestTiming`).

    A non-finite number or an unknown solver status is a bug and raises ``ValueError``.
    """
    if result.status not in get_args(PlanStatus):
        raise ValueError(f"unknown plan status {result.status!r}")
    traj = result.trajectory
    names = _POINT_FIELDS if traj.steering_angle is None else _CAR_FIELDS
    columns = [np.asarray(getattr(traj, name), dtype=float) for name in names]
    _require_finite("the trajectory", *columns)
    rows = zip(*(c.tolist() for c in columns), strict=True)
    diag = result.diagnostics
    timing = [float(diag.timing_ms.get(name, 0.0)) for name in STAGES]
    _require_finite("the diagnostics", diag.lateral_qp.solve_time_ms, diag.speed.solve_time_ms, timing)
    data: dict[str, Any] = {
        "status": result.status,
        "message": str(result.message),
        "trajectory": [dict(zip(names, row, strict=True)) for row in rows],
    }
    if result.candidates is not None:
        data["candidates"] = candidate_data(result.candidates)
    data["diagnostics"] = {
        "candidates": {
            "generated": int(diag.candidates.generated),
            "repaired": int(diag.candidates.repaired),
            "collision_free": int(diag.candidates.collision_free),
        },
        "lateral_qp": {
            "status": SolverStatus(diag.lateral_qp.status).value,
            "iterations": int(diag.lateral_qp.iterations),
            "solve_time_ms": float(diag.lateral_qp.solve_time_ms),
            "backend": _lateral_backend(diag.lateral_qp),
        },
        "speed": {
            "status": SolverStatus(diag.speed.status).value,
            "iterations": int(diag.speed.iterations),
            "solve_time_ms": float(diag.speed.solve_time_ms),
            "profile": ProfileKind(diag.speed_profile).value,
        },
        "decision": decision_data(diag.decision),
        "timing_ms": dict(zip(STAGES, timing, strict=True)),
        "request": {name: float(request_ms[name]) for name in RequestTiming.model_fields},
    }
    if diag.goal is not None:
        data["diagnostics"]["goal"] = goal_data(diag.goal)
    if (follower := diag.follower) is not None:
        _require_finite("the diagnostics", follower.t)
        data["diagnostics"]["follower"] = {
            "obstacle_id": str(follower.obstacle_id),
            "t": float(follower.t),
            "reason": FollowerReason(follower.reason).value,
        }
    return data


def goal_data(report: GoalReport) -> dict[str, Any]:
    """A plan's :class:`~planner.goal.GoalReport` as the JSON data of
    :class:`~app.models.plan.GoalDiagnostics` (``t`` only when reached, ``reason`` only when
    unreachable)."""
    data: dict[str, Any] = {"status": GoalStatus(report.status).value}
    if report.t is not None:
        _require_finite("the goal's time", report.t)
        data["t"] = float(report.t)
    if report.reason is not None:
        data["reason"] = GoalReason(report.reason).value
    data["message"] = str(report.message)
    return data
