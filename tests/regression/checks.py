"""Property checks of a ``POST /v1/plan`` answer, from the request's and the answer's JSON alone.

Nothing here looks inside the server: the request is read as any client would send it (through
``app.conversions.to_problem`` to get the planner's view of it, defaults filled in) and the answer is taken
from its JSON, so the same checks hold against an in-process app or any running server.

What is checked is properties, not numbers:

* every answer: the JSON shape (keys, types, finite numbers), a status among the expected ones and a
  message; the trajectory starts at the ego at ``t = 0`` and is sampled every ``options.dt`` up to
  ``options.horizon_time``; speed never negative;
* ``ok`` and ``stopped``: :func:`planner.validation.trajectory_violations` (inside the lane, or the road
  when ``diagnostics.decision`` borrows it, clear of
  obstacles at every time, ``1 − κ·d > 0``, curvature and lateral-acceleration limits, acceleration
  limits, steps consistent with ``v·dt``, ``s`` increasing while moving, no self-intersection), plus
  circles checked exactly, the speed limit, the heading along the direction of motion, the reported
  curvature agreeing with the heading's change and the reported ``s, d`` with TransF-κ of the positions;
* ``fallback``: a reason, a braking profile (speed never increasing once a positive acceleration at the
  start is released, deceleration within the limit)
  and steps consistent with ``v·dt``; or, where the answer says it did not brake
  (``diagnostics.speed.profile`` other than ``braking``: braking is hit from behind), every check of
  ``ok`` but the hits of the vehicles behind the ego at the start;
* every status: the vehicle's limits (:func:`limit_problems`: curvature, steering, lateral and
  longitudinal acceleration), computed here from the answer; a fallback that brakes at full
  deceleration from the start is excused (nothing along its path does better: the state it starts
  from cannot keep them);
* a request with a goal (:func:`goal_problems`): ``diagnostics.goal`` present (absent without a goal),
  ``reached`` at ``t`` exactly when the trajectory first meets the goal at ``t`` (the centre inside the
  region by shapely's ``covers``, ``t`` in the window, the speed in the range within 1e-3 m/s).

Units: metres, seconds, radians.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import shapely
from pydantic import ValidationError

from app.conversions import to_problem
from app.models.plan import PlanResponse
from app.models.planning import PlanningRequest
from planner.collision import box_corners
from planner.frenet import to_frenet
from planner.problem import CircleObstacle, DynamicObstacle, PlanningProblem, PolygonObstacle
from planner.reference import build_reference
from planner.trajectory import Trajectory
from planner.validation import ViolationKind, trajectory_violations

STATUSES = ("ok", "stopped", "fallback")
TRAJECTORY_FIELDS = ("t", "x", "y", "heading", "curvature", "v", "a", "s", "d")
TOP_LEVEL = {"status", "message", "trajectory", "diagnostics"}

#: the first point may be this far from the ego [m]
START_TOL = 0.05
#: the first steering angle of a car whose steering rate is bounded vs the measured one [rad]
START_STEERING_TOL = 0.02
#: tolerance on the time grid [s]
TIME_TOL = 1e-6
#: a point moves when its speed exceeds this [m/s]
MOVING = 0.05
#: relative tolerance on the vehicle limits
REL_TOL = 1e-3
#: speed above max_speed tolerated [m/s] (the speed profile's limit is soft: an acceleration at the
#: start overshoots by a²/(2·jerk) before the jerk limit brings it to 0)
SPEED_TOL = 0.05
#: heading vs the direction of motion [rad], for steps longer than MIN_DIRECTION_STEP [m]
HEADING_TOL, MIN_DIRECTION_STEP = math.radians(3.0), 0.01
#: reported s, d vs TransF-κ of the positions [m]
FRENET_TOL = 0.05
#: a step's heading change vs its length × the mean reported curvature [rad], absolute + relative
TURN_ABS_TOL, TURN_REL_TOL = 0.05, 0.1
#: distance between consecutive points vs the mean speed × dt, absolute [m] + relative
STEP_ABS_TOL, STEP_REL_TOL = 0.05, 0.05


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def shape_problems(request: PlanningRequest, answer: Any) -> list[str]:
    """What is wrong with the JSON shape of ``answer`` to ``request``; [] if nothing."""
    if not isinstance(answer, dict):
        return [f"the answer is a {type(answer).__name__}, not an object"]
    out: list[str] = []
    expected = TOP_LEVEL | ({"candidates"} if request.options.return_candidates else set())
    if set(answer) != expected:
        out.append(f"top-level keys {sorted(answer)}, expected {sorted(expected)}")
    try:
        PlanResponse.model_validate_json(json.dumps(answer), strict=True)
    except ValidationError as exc:
        out.append(f"does not match PlanResponse: {exc.errors(include_url=False)[:5]}")
    points = answer.get("trajectory")
    if not isinstance(points, list) or len(points) < 2:
        return [*out, "trajectory is not a list of at least two points"]
    fields = _fields(request)
    for i, p in enumerate(points):
        if not isinstance(p, dict) or set(p) != set(fields):
            keys = sorted(p) if isinstance(p, dict) else type(p).__name__
            out.append(f"trajectory[{i}] has keys {keys}, expected {sorted(fields)}")
            break
        bad = [f for f in fields if not _number(p[f])]
        if bad:
            out.append(f"trajectory[{i}] has non-numbers or non-finite numbers in {bad}")
            break
    if not isinstance(answer.get("message"), str) or not answer["message"].strip():
        out.append("no message")
    return out


def _fields(request: PlanningRequest) -> tuple[str, ...]:
    """The keys of a trajectory point: a car's (a vehicle with a wheelbase) has its steering angle too."""
    return (
        (*TRAJECTORY_FIELDS, "steering_angle") if request.vehicle.wheelbase is not None else TRAJECTORY_FIELDS
    )


def trajectory_of(answer: dict[str, Any]) -> Trajectory:
    """The trajectory of a well-shaped answer as arrays."""
    points = answer["trajectory"]
    fields = [f for f in (*TRAJECTORY_FIELDS, "steering_angle") if f in points[0]]
    return Trajectory(**{f: np.array([p[f] for p in points], dtype=float) for f in fields})


def planned_point(problem: PlanningProblem, traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Where the kinematics apply: the centre, or a car's rear axle ``rear_axle_offset`` behind it along
    the yaw (its path's heading and curvature are the answer's)."""
    car = problem.vehicle.wheelbase is not None
    offset = float(problem.vehicle.rear_axle_offset or 0.0) if car else 0.0
    return traj.x - offset * np.cos(traj.heading), traj.y - offset * np.sin(traj.heading)


def _at(traj: Trajectory, i: int) -> str:
    return f"i={i} t={traj.t[i]:.2f}s (x={traj.x[i]:.2f}, y={traj.y[i]:.2f}, v={traj.v[i]:.2f})"


def common_problems(request: PlanningRequest, problem: PlanningProblem, traj: Trajectory) -> list[str]:
    """Checks every answer must pass, whatever its status: start, time grid, speed sign, steps."""
    out: list[str] = []
    ego, opts = problem.ego, request.options
    gap = float(np.hypot(traj.x[0] - ego.x, traj.y[0] - ego.y))
    if gap > START_TOL:
        out.append(f"starts {gap:.3f} m from the ego")
    if abs(traj.t[0]) > TIME_TOL:
        out.append(f"t[0] = {traj.t[0]} s, not 0")
    dt = np.diff(traj.t)
    if np.any(np.abs(dt - opts.dt) > TIME_TOL):
        i = int(np.argmax(np.abs(dt - opts.dt)))
        out.append(f"time step {dt[i]:.6f} s at i={i}, not options.dt = {opts.dt} s")
    if not opts.horizon_time - opts.dt - TIME_TOL < traj.t[-1] <= opts.horizon_time + TIME_TOL:
        out.append(f"ends at t = {traj.t[-1]:.3f} s, not within options.dt of {opts.horizon_time} s")
    if np.any(traj.v < 0.0):
        out.append(f"negative speed at {_at(traj, int(np.argmin(traj.v)))}")
    px, py = planned_point(problem, traj)
    step = np.hypot(np.diff(px), np.diff(py))
    # a step of arc length v·dt whose heading turns monotonically by Δθ ≤ π has a chord between
    # v·dt·cos(Δθ/2) and v·dt (every tangent within Δθ/2 of the chord's direction)
    arc = 0.5 * (traj.v[:-1] + traj.v[1:]) * dt
    shortest = arc * np.cos(0.5 * np.minimum(np.abs(np.diff(traj.heading)), np.pi))
    tolerance = STEP_ABS_TOL + STEP_REL_TOL * arc
    err = np.maximum(step - arc, shortest - step) - tolerance
    if np.any(err > 0):
        i = int(np.argmax(err))
        out.append(
            f"step {i}→{i + 1} moves {step[i]:.3f} m but the mean speed × dt makes {arc[i]:.3f} m "
            f"at {_at(traj, i)}"
        )
    return out


def full_problems(
    problem: PlanningProblem, traj: Trajectory, behind_ok: bool = False, *, borrowing: bool = False
) -> list[str]:
    """Every check of an ``ok`` or ``stopped`` trajectory; with ``behind_ok``, hits by the moving
    obstacles behind the ego at the start (:func:`behind_at_start`) left out; ``borrowing``: its lane
    decision borrows the road, so the footprint is checked in the road rather than the lane."""
    ref = build_reference(problem.reference_line)
    polygons = [
        (ob.id, shapely.make_valid(shapely.Polygon(np.asarray(ob.polygon, dtype=float))))
        for ob in problem.obstacles
        if isinstance(ob, PolygonObstacle)
    ]
    # the planner's own checks (dynamic obstacles at each time), as messages
    rear = behind_at_start(problem) if behind_ok else set()
    out = [
        v.message
        for v in trajectory_violations(ref, problem, traj, polygons, borrowing=borrowing)
        if not (v.kind is ViolationKind.HITS_MOVING_OBSTACLE and v.obstacle_id in rear)
    ]
    veh, ego = problem.vehicle, problem.ego

    prints = shapely.polygons(box_corners(traj.x, traj.y, traj.heading, veh.length, veh.width))
    for ob in problem.obstacles:
        if isinstance(ob, CircleObstacle):
            dist = shapely.distance(prints, shapely.Point(np.asarray(ob.center, dtype=float)))
            if np.any(dist <= ob.radius):
                i = int(np.argmin(dist))
                depth = ob.radius - dist[i]
                out.append(f"footprint hits obstacle {ob.id} by {depth:.3f} m at {_at(traj, i)}")

    vmax = max(veh.max_speed, ego.speed) * (1 + REL_TOL) + SPEED_TOL
    if np.any(traj.v > vmax):
        out.append(f"speed {traj.v.max():.2f} m/s above max_speed {veh.max_speed} m/s")

    px, py = planned_point(problem, traj)  # a car's rear axle moves along its yaw
    dx, dy = np.diff(px), np.diff(py)
    motion = np.arctan2(dy, dx)
    dh = np.angle(np.exp(1j * np.diff(traj.heading)))
    mid = traj.heading[:-1] + 0.5 * dh
    off = np.where(np.hypot(dx, dy) > MIN_DIRECTION_STEP, np.abs(np.angle(np.exp(1j * (mid - motion)))), 0.0)
    if np.any(off > HEADING_TOL):
        i = int(np.argmax(off))
        out.append(f"heading {math.degrees(off[i]):.1f}° off the direction of motion at {_at(traj, i)}")
    # the reported curvature is the heading's rate of change along the path
    length = np.hypot(dx, dy)
    turned = length * 0.5 * (traj.curvature[:-1] + traj.curvature[1:])
    excess = np.abs(dh - turned) - TURN_ABS_TOL - TURN_REL_TOL * np.abs(dh)
    excess = np.where(length > MIN_DIRECTION_STEP, excess, 0.0)
    if np.any(excess > 0):
        i = int(np.argmax(excess))
        out.append(
            f"the heading turns {dh[i]:.3f} rad over {length[i]:.2f} m but the reported curvature makes "
            f"{turned[i]:.3f} rad at {_at(traj, i)}"
        )

    wheelbase = veh.wheelbase
    if wheelbase is not None and traj.steering_angle is not None:  # δ = atan(W κ), within its limit
        delta = np.arctan(wheelbase * traj.curvature)
        if np.any(np.abs(delta - traj.steering_angle) > 1e-6):
            out.append("the steering angle is not atan(wheelbase × curvature)")
        limit = (
            veh.max_steering_angle
            if veh.max_steering_angle is not None
            else np.arctan(wheelbase * veh.max_curvature)
        )
        if np.any(np.abs(traj.steering_angle) > limit * (1 + REL_TOL) + 1e-4):
            out.append(f"steering angle {np.abs(traj.steering_angle).max():.3f} rad above {limit:.3f} rad")

    fr = to_frenet(ref, np.column_stack((traj.x, traj.y)))
    for name, mine, theirs in (("s", fr.s, traj.s), ("d", fr.d, traj.d)):
        diff = np.abs(mine - theirs)
        if np.any(diff > FRENET_TOL):
            i = int(np.argmax(diff))
            out.append(
                f"reported {name} = {theirs[i]:.3f} m but the position's is {mine[i]:.3f} m at {_at(traj, i)}"
            )
    return out


def behind_at_start(problem: PlanningProblem) -> set[str]:
    """Ids of the moving obstacles whose centre at ``t = 0`` lies behind the ego's along the reference."""
    ref = build_reference(problem.reference_line)
    movers = [ob for ob in problem.obstacles if isinstance(ob, DynamicObstacle)]
    if not movers:
        return set()
    starts = np.array([np.interp(0.0, ob.prediction[:, 0], c) for ob in movers for c in ob.prediction.T[1:3]])
    fr = to_frenet(ref, np.vstack((starts.reshape(-1, 2), [[problem.ego.x, problem.ego.y]])))
    return {ob.id for ob, s in zip(movers, fr.s[:-1], strict=True) if s < fr.s[-1]}


def limit_problems(problem: PlanningProblem, traj: Trajectory) -> list[str]:
    """The vehicle's own limits along ``traj``: while moving, ``|curvature| ≤ max_curvature`` (a car: its
    steering angle ``atan(W κ)`` within ``max_steering_angle``, default ``atan(W · max_curvature)``, and
    its rate within ``max_steering_rate``, from the measured angle of a moving ego with a curvature on);
    the lateral acceleration of the centre ``v² |κ| √(1 + (l_r κ)²)`` (``l_r`` a car's rear axle offset,
    else 0) within ``max_lateral_acceleration``; the
    acceleration within ``[−max_deceleration, max_acceleration]`` while moving. (Not ``max_speed``: a measured
    acceleration at the start may carry a fallback past it while the planner's jerk limit releases it;
    ``ok`` answers are held to it by :func:`full_problems`.)"""
    veh, out = problem.vehicle, []
    moving = traj.v > MOVING
    curv = np.abs(traj.curvature)
    car = veh.wheelbase is not None
    if np.any(moving & (curv > veh.max_curvature * (1 + REL_TOL) + 1e-4)):
        i = int(np.argmax(np.where(moving, curv, 0.0)))
        out.append(f"|curvature| {curv[i]:.4f} 1/m above max_curvature {veh.max_curvature} at {_at(traj, i)}")
    if car:
        assert veh.wheelbase is not None
        delta = np.arctan(veh.wheelbase * traj.curvature)
        limit = veh.max_steering_angle or float(np.arctan(veh.wheelbase * veh.max_curvature))
        if np.any(moving & (np.abs(delta) > limit * (1 + REL_TOL) + 1e-4)):
            out.append(f"|steering angle| {np.abs(delta).max():.3f} rad above {limit:.3f} rad")
        if veh.max_steering_rate is not None:
            rate = np.abs(np.diff(delta)) / np.diff(traj.t)
            if np.any(rate > veh.max_steering_rate * (1 + REL_TOL) + 1e-3):
                out.append(f"steering rate {rate.max():.3f} rad/s above {veh.max_steering_rate} rad/s")
            measured = problem.ego.curvature
            if measured is not None and problem.ego.speed > MOVING:
                # it steers at the measured angle now: no other at once
                jump = abs(float(delta[0]) - float(np.arctan(veh.wheelbase * measured)))
                if jump > START_STEERING_TOL:
                    out.append(f"the steering angle starts {jump:.3f} rad off the measured one")
    offset = float(veh.rear_axle_offset or 0.0) if car else 0.0
    lateral = traj.v**2 * curv * np.sqrt(1.0 + (offset * traj.curvature) ** 2)
    if np.any(lateral > veh.max_lateral_acceleration * (1 + REL_TOL) + 1e-3):
        i = int(np.argmax(lateral))
        out.append(
            f"lateral acceleration {lateral[i]:.2f} m/s² above {veh.max_lateral_acceleration} m/s² at "
            f"{_at(traj, i)}"
        )
    # the acceleration where the vehicle moves at the point or the next (a standing one's "acceleration"
    # changes no speed: a braking profile stopping a backward motion it cannot avoid reports one)
    driven = moving | np.append(moving[1:], False)
    a = traj.a[driven]
    if np.any((a > veh.max_acceleration + 1e-3) | (a < -veh.max_deceleration - 1e-3)):
        out.append(f"acceleration in [{a.min():.2f}, {a.max():.2f}] m/s² outside the limits")
    return out


def brakes_at_once(problem: PlanningProblem, traj: Trajectory) -> bool:
    """Whether ``traj`` brakes as hard as the vehicle can from the start: its acceleration falls strictly
    from the first point (a jerk-limited ramp, no pause) until it reaches ``−max_deceleration`` and stays
    there, and is only released (monotonically) as the vehicle comes to a stop within the horizon; or,
    where the vehicle stops before the ramp gets that far, falls strictly and is then released
    monotonically to a stop (the jerk-limited stop: nothing stops sooner); or it stands throughout."""
    decel, a = problem.vehicle.max_deceleration, traj.a
    if np.all(traj.v <= MOVING):
        return True
    full = a <= -decel * (1 - REL_TOL) - 1e-6
    if np.any(full):
        first = int(np.argmax(full))
        eased = np.flatnonzero(~full[first:])
    else:  # the deepest point of the ramp, where its release begins
        first = int(np.argmin(a))
        eased = np.array([0])
        if first == 0:
            return False
    if np.any(np.diff(a[: first + 1]) >= 0.0):
        return False
    if eased.size == 0:
        return True
    release = first + int(eased[0])
    return bool(np.all(np.diff(a[release:]) >= -1e-9) and traj.v[-1] <= MOVING)


def fallback_problems(problem: PlanningProblem, traj: Trajectory) -> list[str]:
    """A fallback brakes: speed never increases once a positive acceleration at the start is released,
    deceleration within the limit, slower at the end than at its peak."""
    out: list[str] = []
    veh = problem.vehicle
    # it may speed up only while it releases a positive acceleration at the start (the jerk limit)
    releasing = np.logical_and.accumulate((traj.a[:-1] > 0) & (np.diff(traj.a) < 0))
    faster = (np.diff(traj.v) > 1e-6) & ~releasing
    if np.any(faster):
        out.append(f"the fallback speeds up at {_at(traj, int(np.argmax(faster)))}")
    if np.any(traj.a < -veh.max_deceleration - 1e-3):
        out.append(f"the fallback brakes harder than max_deceleration: {traj.a.min():.2f} m/s²")
    if traj.v.max() > MOVING and not traj.v[-1] < traj.v.max():  # from its peak (the start, or the release)
        out.append("the fallback does not slow down")
    return out


def plan_problems(request_json: dict[str, Any], answer: Any, statuses: Sequence[str]) -> list[str]:
    """Every broken check of ``answer`` (the JSON of ``POST /v1/plan``) to ``request_json``; [] if none.

    ``statuses`` are the acceptable ones for this request.
    """
    request = PlanningRequest.model_validate(request_json)
    out = shape_problems(request, answer)
    if out:
        return out
    status = answer["status"]
    if status not in statuses:
        out.append(f"status {status!r} ({answer['message']}), expected one of {list(statuses)}")
    problem = to_problem(request)
    traj = trajectory_of(answer)
    out += common_problems(request, problem, traj)
    borrowing = answer["diagnostics"]["decision"]["lane"] != "keep"
    if status in ("ok", "stopped"):
        out += full_problems(problem, traj, borrowing=borrowing)
    elif answer["diagnostics"]["speed"]["profile"] != "braking":  # braking is hit from behind
        out += full_problems(problem, traj, behind_ok=True, borrowing=borrowing)
    else:
        out += fallback_problems(problem, traj)
    if status != "fallback" or not brakes_at_once(problem, traj):
        out += limit_problems(problem, traj)
    return out


#: a sample this close to the goal region's edge [m] may be judged either way
GOAL_EDGE_TOL = 1e-6
#: the speed range holds within this [m/s] (planner.goal.SPEED_TOLERANCE)
GOAL_SPEED_TOL = 1e-3


def goal_met(goal: dict[str, Any], traj: Trajectory, slack: float) -> np.ndarray:
    """Per sample, whether the trajectory meets the request's ``goal`` (its JSON), the region grown by
    ``slack`` [m] (shrunk where negative)."""
    ok = np.ones(traj.t.shape, dtype=bool)
    position = goal.get("position")
    if position is not None:
        if "circle" in position:
            region = shapely.Point(position["circle"]["center"]).buffer(position["circle"]["radius"], 256)
        else:
            region = shapely.make_valid(shapely.Polygon(position["polygon"]))
        region = region.buffer(slack) if slack else region
        ok &= np.array([region.covers(shapely.Point(x, y)) for x, y in zip(traj.x, traj.y, strict=True)])
    if goal.get("time") is not None:
        ok &= (traj.t >= goal["time"][0] - TIME_TOL) & (traj.t <= goal["time"][1] + TIME_TOL)
    if goal.get("speed") is not None:
        ok &= (traj.v >= goal["speed"][0] - GOAL_SPEED_TOL) & (traj.v <= goal["speed"][1] + GOAL_SPEED_TOL)
    return ok


def goal_problems(request_json: dict[str, Any], answer: dict[str, Any], statuses: Sequence[str]) -> list[str]:
    """What is wrong with a well-shaped answer's ``diagnostics.goal`` to ``request_json``; ``statuses``
    are the acceptable goal statuses ([] if nothing). A disc is tested as a 1024-gon inside it, so the
    claims are checked ``GOAL_EDGE_TOL`` inside and outside the region, and 2 mm more for a disc."""
    goal, report = request_json.get("goal"), answer["diagnostics"].get("goal")
    if goal is None:
        return [] if report is None else ["diagnostics.goal without a goal in the request"]
    if report is None:
        return ["no diagnostics.goal for a request with a goal"]
    out = [] if report["status"] in statuses else [f"goal {report} , expected one of {list(statuses)}"]
    traj = trajectory_of(answer)
    edge = GOAL_EDGE_TOL + (2e-3 if "circle" in (goal.get("position") or {}) else 0.0)
    loose, strict = goal_met(goal, traj, edge), goal_met(goal, traj, -edge)
    if report["status"] == "reached":
        at = np.flatnonzero(np.abs(traj.t - report["t"]) <= TIME_TOL)
        if at.size == 0 or not loose[at[0]]:
            out.append(f"goal reached at t = {report['t']}, where the trajectory does not meet it")
        elif strict[: at[0]].any():
            out.append(
                f"goal reached at t = {report['t']}, but met already at t = {traj.t[np.argmax(strict)]}"
            )
    elif strict.any():
        out.append(f"goal {report['status']}, but the trajectory meets it at t = {traj.t[np.argmax(strict)]}")
    return out


def error_problems(answer: Any) -> list[str]:
    """What is wrong with an error answer; its shape is
    ``{"error": {"code", "message", "details": [{"field", "message"}]}}``."""
    if not isinstance(answer, dict) or set(answer) != {"error"} or not isinstance(answer["error"], dict):
        return [f"not an error object: {str(answer)[:200]}"]
    err = answer["error"]
    out = []
    if set(err) != {"code", "message", "details"}:
        out.append(f"error keys {sorted(err)}")
    if not isinstance(err.get("code"), str) or not isinstance(err.get("message"), str):
        out.append("error code or message is not a string")
    details = err.get("details")
    if not isinstance(details, list) or not all(
        isinstance(d, dict) and set(d) == {"field", "message"} for d in details
    ):
        out.append(f"error details malformed: {details!r:.200}")
    return out
