"""One plan, as its stages: reference → candidates → decision → bounds → lateral QP → speed → trajectory.

Each stage is a function of the ones before; :func:`plan` only wires them and times them. A planning
failure is a status (``stopped`` when the road ahead is blocked, ``fallback`` when a stage fails or its
result breaks a check), always with a trajectory that brakes safely along the best path known.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import partial
from typing import Literal

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray
from scipy.ndimage import minimum_filter1d
from scipy.spatial import cKDTree
from shapely.geometry.base import BaseGeometry

from planner.bounds import LateralBounds, lateral_bounds, pass_left
from planner.candidates import (
    CandidateSet,
    EgoFrenet,
    check_ego_on_road,
    ego_frenet,
    generate_candidates,
    lane_bounds,
)
from planner.collision import (
    FrenetBoxes,
    box_corners,
    box_hits,
    frenet_boxes,
    is_static,
    obstacle_shape,
    prediction_at,
    vehicle_extent,
)
from planner.frenet import to_frenet
from planner.problem import DynamicObstacle, PlanningProblem
from planner.reference import FloatArray, ReferenceLine, build_reference
from planner.trajectory import Path, Trajectory, frenet_path, polyline_path, sample
from planner.validation import trajectory_violations
from solvers.lateral_qp import LateralQPProblem, LateralQPResult, LateralQPSolver
from solvers.result import SolveInfo, SolverStatus
from solvers.speed_problem import SpeedProblem, SpeedResult, integrate_jerk
from solvers.speed_profiles import braking_profile, cruise_profile
from solvers.speed_sqp import SpeedSolver

Status = Literal["ok", "stopped", "fallback"]

#: knot spacing of the lateral QP [m]
KNOT_SPACING = 0.5
#: most knots of the lateral QP
MAX_KNOTS = 240
#: lateral margin kept to obstacles beyond the footprint [m]
OBSTACLE_MARGIN = 0.3
#: gap kept behind a blocked point or a dynamic obstacle, beyond half the vehicle length [m]
STOP_GAP = 1.0
#: bounds handed to the QP are tightened by this, covering its tolerance [m]
QP_SLACK = 0.01
#: ADMM iterations of one lateral QP solve (a count, not a time: the same request gets the same answer)
QP_MAX_ITER = 4000
#: jerk allowed when braking for a blocked road or in the fallback [m/s³]
EMERGENCY_JERK = 30.0
#: time headway kept to a moving obstacle ahead: the vehicle may not be where it was this long ago [s]
HEADWAY = 1.0
#: time headway kept ahead of a vehicle coming from behind: the vehicle should be ahead of where that one
#: will be this much later [s] (a soft bound, weaker than the stop and the obstacles ahead). Half the
#: headway kept to the obstacles ahead: the gap behind is the follower's to keep, ours is not to brake
#: into it, and the two headways together must fit between a leader and a follower.
FOLLOWER_HEADWAY = 0.5 * HEADWAY
#: jerk bound of the lateral profile [1/m²]
LATERAL_JERK = 0.5
#: jerk bound of the speed profile [m/s³]
SPEED_JERK = 8.0
#: a speed profile needing more slack than this [m/s or m] is re-planned with the emergency jerk
SPEED_SLACK = 0.05
#: a speed profile past a stop or a space-time bound by more than this [m] is replaced by full braking
POSITION_SLACK = 0.01
#: share of the lateral-acceleration limit the speed profile plans with (its linearisation's tolerance)
LIMIT_MARGIN = 0.9
#: the speed limit at a point also holds this far either side of it [m]
LIMIT_REACH = 2.0
#: most steps of the speed profile
SPEED_STEPS = 80


@dataclass(frozen=True)
class CandidateStats:
    generated: int
    repaired: int
    collision_free: int


@dataclass(frozen=True)
class PlanDiagnostics:
    """What each stage did: candidate counts, solver infos, and wall time per stage [ms]."""

    candidates: CandidateStats
    lateral_qp: SolveInfo
    speed: SolveInfo
    timing_ms: dict[str, float]
    reference_samples: int
    knots: int
    chosen_candidate: int | None


@dataclass(frozen=True)
class PlanResult:
    """The answer: status, why, the trajectory, and (optionally) the candidates behind it."""

    status: Status
    message: str
    trajectory: Trajectory
    candidates: CandidateSet | None
    diagnostics: PlanDiagnostics
    violations: tuple[str, ...] = field(default=())


class _Timer:
    def __init__(self, budget_ms: float | None = None) -> None:
        self.ms: dict[str, float] = {}
        self._t0 = time.perf_counter()
        self._budget_ms = budget_ms

    def remaining_s(self) -> float | None:
        """Budget left [s] (at least 1 ms), or None without a budget."""
        if self._budget_ms is None:
            return None
        return max(1e-3 * self._budget_ms - (time.perf_counter() - self._t0), 1e-3)

    def overrun(self, stage: str) -> str | None:
        """Why the plan must stop after ``stage``, if the budget is spent; else None."""
        elapsed = 1e3 * (time.perf_counter() - self._t0)
        if self._budget_ms is None or elapsed <= self._budget_ms:
            return None
        return f"time budget of {self._budget_ms:g} ms spent after the {stage} stage ({elapsed:.0f} ms)"

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.ms[name] = self.ms.get(name, 0.0) + 1e3 * (time.perf_counter() - t0)


_NOT_RUN = SolveInfo(SolverStatus.FAILED, 0, 0.0, None, "not run")


def static_shapes(problem: PlanningProblem) -> list[tuple[str, BaseGeometry]]:
    """Outlines of the obstacles that stay put over the horizon (parked cars given as predictions too)."""
    horizon = problem.options.horizon_time
    return [(ob.id, obstacle_shape(ob)) for ob in problem.obstacles if is_static(ob, horizon)]


def _corridor(problem: PlanningProblem) -> float:
    """How far from the reference line [m] an obstacle can matter: the widest lane side and the
    vehicle's length, with a metre to spare."""
    widest = max(float(np.max(problem.lane.left_width)), float(np.max(problem.lane.right_width)))
    return widest + problem.vehicle.length + 1.0


def moving_obstacles(problem: PlanningProblem) -> list[DynamicObstacle]:
    horizon = problem.options.horizon_time
    return [ob for ob in problem.obstacles if isinstance(ob, DynamicObstacle) and not is_static(ob, horizon)]


def choose_candidate(
    cands: CandidateSet, boxes: FrenetBoxes, problem: PlanningProblem
) -> tuple[int, NDArray[np.bool_]]:
    """Score every candidate (offset, smoothness, progress, clearance) and return the best
    collision-free one (the best overall if none is free) with the collision-free mask."""
    ds = np.diff(cands.s, axis=1)
    dd = np.diff(cands.d, axis=1) / np.where(ds > 0, ds, 1.0)
    heading_error = np.arctan(np.concatenate((dd, dd[:, -1:]), axis=1))
    half_s, half_d = vehicle_extent(heading_error, problem.vehicle, OBSTACLE_MARGIN)
    hits = box_hits(boxes, cands.s, cands.d, half_s, half_d) & cands.valid
    free = ~hits.any(axis=1)
    valid = cands.valid
    count = valid.sum(axis=1)
    offset = np.where(valid, cands.d**2, 0.0).sum(axis=1) / count
    bend = np.abs(np.diff(dd, axis=1)).sum(axis=1)
    progress = np.where(valid, cands.s, -np.inf).max(axis=1) - cands.s[:, 0]
    span = max(float(progress.max()), 1e-6)
    cost = offset + 10.0 * bend + 20.0 * (1.0 - progress / span) + 1e6 * (~free)
    return int(np.argmin(cost)), np.asarray(free, dtype=bool)


def _smoothed_slope(d: FloatArray, s: FloatArray, window: float = 4.0) -> FloatArray:
    """Heading error [rad] of a lateral profile: its slope averaged over ``window`` [m]."""
    slope = np.arctan(np.gradient(d, s))
    width = max(1, round(window / max(float(s[1] - s[0]), 1e-6)))
    padded = np.pad(slope, (width // 2, width - 1 - width // 2), mode="edge")
    return np.asarray(np.convolve(padded, np.ones(width) / width, mode="valid"))


def _knots(start: EgoFrenet, s_end: float) -> FloatArray:
    n = int(np.clip(np.ceil((s_end - start.s) / KNOT_SPACING) + 1, 3, MAX_KNOTS))
    return np.linspace(start.s, s_end, n)


def curvature_allowance(s: FloatArray, start: EgoFrenet, problem: PlanningProblem) -> FloatArray:
    """Largest path curvature [1/m] at knots ``s`` [m]: ``κ_max``, and ``a_lat,max / v²`` for the speed
    ``v`` the vehicle can at best have slowed to there (braking at half its deceleration from ``v₀``),
    so that the speed profile can keep the lateral-acceleration limit."""
    v = problem.vehicle
    travelled = np.maximum(s - start.s, 0.0)
    v_sq = np.maximum(problem.ego.speed**2 - v.max_deceleration * travelled, 1.0)
    return np.minimum(0.9 * v.max_curvature, LIMIT_MARGIN * v.max_lateral_acceleration / v_sq)


def _lateral_qp(
    solver: LateralQPSolver,
    bounds: LateralBounds,
    d_ref: FloatArray,
    start: EgoFrenet,
    ref: ReferenceLine,
    allowance: FloatArray,
    time_limit_s: float | None = None,
) -> LateralQPResult:
    """Piecewise-jerk QP on ``d(s)``; ``d″`` bounds linearised at ``d_ref`` keep ``|κ_path| ≤ allowance``.

    For small ``d′`` the path's curvature is ``κ_x ≈ (d″/(1 − κd) + κ)/(1 − κd)``, so
    ``|κ_x| ≤ c`` ⇔ ``(−c(1 − κd) − κ)(1 − κd) ≤ d″ ≤ (c(1 − κd) − κ)(1 − κd)``, with ``1 − κd`` taken
    at ``d_ref``.
    """
    s = bounds.s
    lower = bounds.lower + QP_SLACK
    upper = np.maximum(bounds.upper - QP_SLACK, lower)
    kappa = ref.kappa_at(s)
    one = np.clip(1.0 - kappa * np.clip(d_ref, lower, upper), 0.05, None)
    with np.errstate(over="ignore"):  # a curvature limit near the largest float: ±inf, no bound
        ddd_upper = (allowance * one - kappa) * one
        ddd_lower = (-allowance * one - kappa) * one
    problem = LateralQPProblem(
        ds=float(s[1] - s[0]),
        d_lower=lower,
        d_upper=upper,
        d_ref=np.clip(d_ref, lower, upper),
        jerk_max=LATERAL_JERK,
        d0=start.d,
        dd0=start.dd,
        ddd0=start.ddd,
        ddd_lower=ddd_lower,
        ddd_upper=ddd_upper,
    )
    return solver.solve(problem, max_iter=QP_MAX_ITER, time_limit_s=time_limit_s)


@dataclass(frozen=True)
class _LateralResult:
    """The lateral stage's outcome: the bounds handed to the QP (cut before a block), the reference
    offsets at their knots, whether a block is the road's end, and the QP's answer."""

    bounds: LateralBounds
    d_ref: FloatArray
    road_end: bool
    qp: LateralQPResult

    @property
    def solved(self) -> bool:
        return self.qp.info.converged

    def better_than_unsolved(self) -> bool:
        """Solved, with no block on the way other than the road's end."""
        return self.solved and (self.bounds.blocked is None or self.road_end)

    def rank(self) -> tuple[float, bool]:
        """How good: the farther the first block (none: infinitely far), then solved over not."""
        blocked = self.bounds.blocked
        far = np.inf if blocked is None or self.road_end else float(self.bounds.s[-1])
        return far, self.solved


def _lateral(
    solver: LateralQPSolver,
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    knots: FloatArray,
    d_ref: FloatArray,
    boxes: FrenetBoxes,
    lane_margin: float | None,
    timer: _Timer,
) -> _LateralResult:
    """Bounds at ``knots`` (``lane_margin`` [m] to the lane's edges, default the options' margin) and the
    lateral QP on them, tracking the candidate's offsets ``d_ref`` [m]."""
    vehicle, options = problem.vehicle, problem.options
    lane = lane_bounds(
        ref, problem.lane, knots, half_width=0.5 * vehicle.width, margin=options.lateral_margin
    )
    left_of = pass_left(boxes, knots, d_ref, lane.lower, lane.upper)
    bounds = lateral_bounds(
        ref,
        problem.lane,
        knots,
        vehicle,
        margin=options.lateral_margin,
        boxes=boxes,
        left_of=left_of,
        heading_error=_smoothed_slope(d_ref, knots),
        lane_margin=lane_margin,
    )
    blocked = bounds.blocked
    # The vehicle's centre never gets beyond this: the speed stage stops its front STOP_GAP before the
    # reference's end.
    reach = ref.length - 0.5 * vehicle.length - STOP_GAP
    # a lane that runs out (narrower than the vehicle) at the reference's end is its end, not a block
    road_end = blocked is not None and knots[blocked] >= reach
    if blocked is not None:
        keep = max(blocked, 3)
        lower = bounds.lower[:keep]
        upper = np.maximum(bounds.upper[:keep], lower)
        bounds = LateralBounds(
            s=knots[:keep],
            lower=np.where(np.isfinite(lower), lower, start.d),
            upper=np.where(np.isfinite(upper), upper, start.d),
            blocked=blocked,
        )
        d_ref = d_ref[:keep]
    # Beyond that the path is never driven: the lane's end there (its width often falls to 0 at the last
    # point) must not bend the path before it. The bounds of the last knot within reach hold there.
    last = int(np.searchsorted(bounds.s, reach, side="right")) - 1
    if last >= 1:
        beyond = bounds.s > reach
        bounds = LateralBounds(
            s=bounds.s,
            lower=np.where(beyond, bounds.lower[last], bounds.lower),
            upper=np.where(beyond, bounds.upper[last], bounds.upper),
            blocked=bounds.blocked,
        )
    # The ego is where it is: where the bounds near the start exclude its offset (a conservative bound
    # it is already inside, as beside an obstacle it is passing), they open to it and close again
    # linearly over one vehicle length, so that the QP can start there; the checks judge the footprint.
    ramp = np.clip((bounds.s - start.s) / vehicle.length, 0.0, 1.0)
    bounds = LateralBounds(
        s=bounds.s,
        lower=np.minimum(bounds.lower, start.d + (bounds.lower - start.d) * ramp),
        upper=np.maximum(bounds.upper, start.d + (bounds.upper - start.d) * ramp),
        blocked=bounds.blocked,
    )
    allowance = curvature_allowance(bounds.s, start, problem)
    qp = _lateral_qp(solver, bounds, d_ref, start, ref, allowance, timer.remaining_s())
    if not qp.info.usable:  # too fast for the road: keep at least the vehicle's limit
        allowance = np.full(bounds.s.shape, 0.99 * vehicle.max_curvature)
        qp = _lateral_qp(solver, bounds, d_ref, start, ref, allowance, timer.remaining_s())
    return _LateralResult(bounds, d_ref, bool(road_end), qp)


def _speed_limit(path: Path, problem: PlanningProblem) -> FloatArray:
    """The speed profile's limit along ``path`` [m/s]: the target speed, within the vehicle's and the
    curvature's (the target is a cap: a faster vehicle behind does not raise it)."""
    v = problem.vehicle
    target = (
        v.max_speed
        if problem.options.target_speed is None
        else min(problem.options.target_speed, v.max_speed)
    )
    with np.errstate(divide="ignore"):
        lateral = np.sqrt(
            LIMIT_MARGIN * v.max_lateral_acceleration / np.maximum(np.abs(path.curvature), 1e-9)
        )
    # The lowest limit within LIMIT_REACH either side: the profile is checked only at its knots.
    step = float(path.sigma[-1] / max(path.sigma.shape[0] - 1, 1))
    size = 2 * max(1, int(np.ceil(LIMIT_REACH / max(step, 1e-6)))) + 1
    return np.asarray(minimum_filter1d(np.minimum(target, lateral), size=size, mode="nearest"))


def _space_time_bound(
    ref: ReferenceLine,
    path: Path,
    movers: list[DynamicObstacle],
    problem: PlanningProblem,
    t: FloatArray,
    start_s: float,
) -> FloatArray | None:
    """``σ_max(t_k)`` [m]: how far along the path the vehicle's centre may be at each time so that its
    footprint stays clear of every moving obstacle's box (follow or yield). Obstacles behind the ego
    at the start are not followed."""
    if not movers:
        return None
    half_s, half_d = vehicle_extent(np.zeros_like(path.s), problem.vehicle, OBSTACLE_MARGIN)
    # Only obstacles that come near the path at some time can bound the vehicle; mapping the others
    # by TransF-κ is most of this stage's cost in dense traffic. "Near": within twice the footprints'
    # reach (generous: a Frenet box may be larger than the shape it bounds).
    tree = cKDTree(np.column_stack((path.x, path.y)))
    own = float(np.hypot(half_s[0], half_d[0]))
    states = [prediction_at(ob, t) for ob in movers]
    reach = 2.0 * (own + max(float(np.hypot(ob.length, ob.width)) for ob in movers)) + KNOT_SPACING
    dist, _ = tree.query(np.concatenate(states)[:, :2], distance_upper_bound=reach)  # one query for all
    near = np.flatnonzero(np.isfinite(dist).reshape(len(movers), -1).any(axis=1))
    movers, states = [movers[k] for k in near], [states[k] for k in near]
    if not movers:
        return None
    s_min, s_max, d_min, d_max = _frenet_extents(ref, movers, states)  # (K, T)
    # Only obstacles ahead of the ego now are followed or yielded to; one coming from behind is the
    # follower's to avoid (braking for it as it overtakes would invite a rear-end collision).
    ahead = (0.5 * (s_min[:, :1] + s_max[:, :1]) > start_s) | (s_min[:, :1] > start_s)
    ps, pd = path.s[None, None, :], path.d[None, None, :]
    hit = (ps + half_s >= s_min[..., None]) & (ps - half_s <= s_max[..., None])
    hit &= (pd + half_d >= d_min[..., None]) & (pd - half_d <= d_max[..., None])  # (K, T, knots)
    first = np.where(hit.any(axis=2), np.argmax(hit, axis=2), -1)
    limit = np.where(first > 0, path.sigma[np.maximum(first - 1, 0)], np.where(first == 0, 0.0, np.inf))
    limit = np.where(ahead, limit, np.inf)
    return np.asarray(limit.min(axis=0))


def _frenet_extents(
    ref: ReferenceLine, movers: list[DynamicObstacle], states: list[FloatArray]
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """``(s_min, s_max, d_min, d_max)`` [m], each shape (K, T): the Frenet boxes of the K obstacles at their
    states ``states[k]`` (shape (T, 3)), from corners and edge midpoints mapped by TransF-κ in one call."""
    outlines = []
    for ob, st in zip(movers, states, strict=True):
        corners = box_corners(st[:, 0], st[:, 1], st[:, 2], ob.length, ob.width)  # (T, 4, 2)
        outlines.append(np.concatenate((corners, 0.5 * (corners + np.roll(corners, -1, axis=1))), axis=1))
    pts = np.stack(outlines)  # (K, T, 8, 2)
    fr = to_frenet(ref, pts.reshape(-1, 2))
    s_box = fr.s.reshape(pts.shape[:3])
    d_box = fr.d.reshape(pts.shape[:3])
    return s_box.min(axis=2), s_box.max(axis=2), d_box.min(axis=2), d_box.max(axis=2)


def _behind(ref: ReferenceLine, movers: list[DynamicObstacle], start_s: float) -> NDArray[np.bool_]:
    """Which of ``movers`` are behind the ego at the start: the middle of their Frenet box at ``t = 0`` at
    or behind the ego's ``start_s`` [m] — exactly those :func:`_space_time_bound` does not follow."""
    if not movers:
        return np.zeros(0, dtype=bool)
    s_min, s_max, _, _ = _frenet_extents(ref, movers, [prediction_at(ob, np.zeros(1)) for ob in movers])
    ahead = (0.5 * (s_min[:, 0] + s_max[:, 0]) > start_s) | (s_min[:, 0] > start_s)
    return np.asarray(~ahead, dtype=bool)


def followers(ref: ReferenceLine, movers: list[DynamicObstacle], start_s: float) -> list[DynamicObstacle]:
    """The moving obstacles behind the ego at the start (see :func:`_behind`)."""
    return [ob for ob, behind in zip(movers, _behind(ref, movers, start_s), strict=True) if behind]


def _follower_bound(
    ref: ReferenceLine,
    path: Path,
    movers: list[DynamicObstacle],
    problem: PlanningProblem,
    t: FloatArray,
    headway: float,
    start_s: float,
) -> FloatArray | None:
    """``σ_min(t_k)`` [m] at the knot times ``t`` (evenly spaced) [s]: how far along the path the
    vehicle's centre must be for its footprint to be ahead of the boxes of the moving obstacles behind it
    at the start (:func:`followers`) at every time in ``[t_k, t_k + headway]`` (``headway`` [s] rounded up
    to the knot spacing); ``−inf`` where free, ``None`` when free throughout.

    A vehicle bounds from the first time its box meets the footprint anywhere along the path, if it is
    then behind where the ego would be at its current speed, and for as long as it keeps meeting it:
    one that enters the path ahead (a cut-in after overtaking) or comes back after leaving it is not
    chased. At each time the bound is the knot after the last one whose footprint it meets.
    """
    if not movers:
        return None
    window = int(np.ceil(headway / float(t[1] - t[0]) - 1e-9))  # steps of the headway; t: ≥ 2 times
    t = t[0] + (t[1] - t[0]) * np.arange(t.size + window)  # the knots and the headway beyond them
    half_s, half_d = vehicle_extent(np.zeros_like(path.s), problem.vehicle, OBSTACLE_MARGIN)
    # as in _space_time_bound: map by TransF-κ only the obstacles that come near the path
    tree = cKDTree(np.column_stack((path.x, path.y)))
    own = float(np.hypot(half_s[0], half_d[0]))
    states = [prediction_at(ob, t) for ob in movers]
    reach = 2.0 * (own + max(float(np.hypot(ob.length, ob.width)) for ob in movers)) + KNOT_SPACING
    dist, _ = tree.query(np.concatenate(states)[:, :2], distance_upper_bound=reach)
    near = np.flatnonzero(np.isfinite(dist).reshape(len(movers), -1).any(axis=1))
    chosen = near[_behind(ref, [movers[k] for k in near], start_s)]
    if chosen.size == 0:
        return None
    s_min, s_max, d_min, d_max = _frenet_extents(
        ref, [movers[k] for k in chosen], [states[k] for k in chosen]
    )
    ps, pd = path.s[None, None, :], path.d[None, None, :]
    hit = (ps + half_s >= s_min[..., None]) & (ps - half_s <= s_max[..., None])
    hit &= (pd + half_d >= d_min[..., None]) & (pd - half_d <= d_max[..., None])  # (K, T, knots)
    meets = hit.any(axis=2)  # (K, T)
    first = np.argmax(meets, axis=1)
    rows = np.arange(meets.shape[0])
    behind_then = s_max[rows, first] <= start_s + max(problem.ego.speed, 0.0) * t[first]
    after = np.arange(meets.shape[1])[None, :] >= first[:, None]
    active = meets & ~(np.cumsum(after & ~meets, axis=1) > 0) & behind_then[:, None]  # the first run only
    if not active.any():
        return None
    last = hit.shape[2] - 1 - np.argmax(hit[..., ::-1], axis=2)  # last knot met, (K, T)
    at = np.where(active, path.sigma[np.minimum(last + 1, hit.shape[2] - 1)], -np.inf).max(axis=0)
    bound = sliding_window_view(at, window + 1).max(axis=1)  # the most ahead over each [t_k, t_k + headway]
    return np.asarray(bound)


def _speed(
    solver: SpeedSolver,
    path: Path,
    problem: PlanningProblem,
    s_stop: float,
    s_upper: FloatArray | None,
    steps: int,
    dt: float,
    jerk_max: float = SPEED_JERK,
    s_lower: FloatArray | None = None,
) -> SpeedResult:
    v = problem.vehicle
    ego = problem.ego
    target = (
        v.max_speed
        if problem.options.target_speed is None
        else min(problem.options.target_speed, v.max_speed)
    )
    limit = _speed_limit(path, problem)
    sp = SpeedProblem(
        dt=dt,
        steps=steps,
        v0=max(ego.speed, 0.0),
        a0=float(np.clip(ego.acceleration, -v.max_deceleration, v.max_acceleration)),
        limit_s=path.sigma,
        limit_v=limit,
        v_target=target,
        a_min=-v.max_deceleration,
        a_max=v.max_acceleration,
        jerk_max=jerk_max,
        s_stop=s_stop,
        s_upper=s_upper,
        s_lower=s_lower,
    )
    return solver.solve(sp)


def _braking(
    path: Path, problem: PlanningProblem, steps: int, dt: float, keep_speed: bool = False
) -> SpeedResult:
    """Full braking within the jerk limit along ``path`` (the fallback's speed profile); with
    ``keep_speed``, the acceleration released as fast and the speed kept instead (the fallback's
    alternative when braking is hit from behind)."""
    v = problem.vehicle
    sp = SpeedProblem(
        dt=dt,
        steps=steps,
        v0=max(problem.ego.speed, 0.0),
        a0=float(np.clip(problem.ego.acceleration, -v.max_deceleration, v.max_acceleration)),
        limit_s=path.sigma,
        limit_v=np.zeros_like(path.sigma),
        v_target=0.0,
        a_min=-v.max_deceleration,
        a_max=v.max_acceleration,
        jerk_max=EMERGENCY_JERK,
    )
    jerk = cruise_profile(sp) if keep_speed else braking_profile(sp)
    s, vel, a = integrate_jerk(dt, 0.0, sp.v0, sp.a0, jerk)
    t = np.arange(steps + 1, dtype=np.float64) * dt
    info = SolveInfo(SolverStatus.SOLVED, 0, 0.0, None, "cruise profile" if keep_speed else "braking profile")
    return SpeedResult(
        info=info,
        t=t,
        s=s,
        v=vel,
        a=a,
        jerk=jerk,
        speed_violation=0.0,
        position_violation=0.0,
        max_violation=0.0,
        qp_solves=0,
    )


@dataclass
class _Solvers:
    lateral: LateralQPSolver = field(default_factory=LateralQPSolver)
    speed: SpeedSolver = field(
        default_factory=lambda: SpeedSolver(
            max_iterations=2, tolerance=1e-3, restore_violation=SPEED_SLACK, qp_residual=1e-6
        )
    )


_THREAD = threading.local()


def _solvers() -> _Solvers:
    """The solvers of this thread (their built problems are reused between plans)."""
    if not hasattr(_THREAD, "solvers"):
        _THREAD.solvers = _Solvers()
    solvers: _Solvers = _THREAD.solvers
    return solvers


def plan(problem: PlanningProblem) -> PlanResult:
    """Plan a trajectory for ``problem``; never raises for a planning failure (only for invalid input)."""
    timer = _Timer(problem.options.time_budget_ms)
    solvers = _solvers()
    options, vehicle = problem.options, problem.vehicle
    with timer.stage("reference"):
        ref = build_reference(problem.reference_line)
        # Unknown ego curvature: taken as the road's, within what the vehicle can drive at its speed.
        reachable = min(
            vehicle.max_curvature, vehicle.max_lateral_acceleration / max(problem.ego.speed, 0.1) ** 2
        )
        start = ego_frenet(ref, problem.ego, max_curvature=LIMIT_MARGIN * reachable)
        check_ego_on_road(ref, problem.lane, start)
    with timer.stage("candidates"):
        cands = generate_candidates(ref, problem.lane, problem.ego, vehicle, options, start=start)
        shapes = static_shapes(problem)
        boxes = frenet_boxes(ref, shapes, reach=_corridor(problem))
        best, free = choose_candidate(cands, boxes, problem)
        s_c, d_c, _ = cands.points(best)
    candidate_path = polyline_path(ref, s_c, d_c)
    stats = CandidateStats(cands.count, int(cands.repaired.sum()), int(free.sum()))
    steps = int(min(SPEED_STEPS, max(1, round(options.horizon_time / options.dt))))
    dt_speed = options.horizon_time / steps

    def fallback(
        reason: str, path: Path, lateral: SolveInfo, speed: SolveInfo, planned: SpeedResult | None = None
    ) -> PlanResult:
        # Brake along the first path whose braking trajectory passes every check: the optimised one,
        # the longer uncut candidate, or straight on at the ego's offset (no steering while it stops).
        knots_ahead = _knots(start, max(float(s_c[-1]), start.s + 2.0 * KNOT_SPACING))
        hold = np.full(knots_ahead.shape, start.d)
        paths = (path, candidate_path, frenet_path(ref, knots_ahead, hold, 0.0 * hold, 0.0 * hold))
        tried = []
        for option in paths:
            prof = _braking(option, problem, steps, dt_speed)
            traj = sample(option, prof.t, prof.s - prof.s[0], prof.v, prof.a, prof.jerk, options.dt)
            bad = trajectory_violations(ref, problem, traj, shapes)
            tried.append((traj, bad))
            if not bad:
                break
        traj, bad = min(tried, key=lambda tb: len(tb[1]))
        message = reason if not bad else f"{reason}; the braking trajectory still breaks: {bad[0]}"
        if bad:
            # Full braking into a vehicle coming from behind is never better than keeping the speed:
            # when braking is hit from behind, keeping the speed and the planned profile (which may have
            # slowed for a leader's headway only) are weighed too. The first that passes every check is
            # taken; else the least severe (_severity), on a tie these before braking (a harder stop
            # gives the follower less time).
            rear = {
                f"footprint hits moving obstacle {ob.id}"
                for ob in followers(ref, moving_obstacles(problem), start.s)
            }
            hit_from_behind = [v for _, b in tried for v in b if v in rear]
            if hit_from_behind:
                others = (
                    [("the planned profile", planned)] if planned is not None and planned.info.usable else []
                )
                others.append(
                    ("keeping the speed", _braking(path, problem, steps, dt_speed, keep_speed=True))
                )
                weighed = []
                for label, prof in others:
                    alt = sample(path, prof.t, prof.s - prof.s[0], prof.v, prof.a, prof.jerk, options.dt)
                    alt_bad = trajectory_violations(ref, problem, alt, shapes)
                    weighed.append((label, alt, alt_bad))
                    if not alt_bad:
                        break
                weighed += [("braking", tr, b) for tr, b in tried]
                label, traj, bad = min(weighed, key=lambda c: _severity(c[2], rear))
                if label != "braking":
                    message = f"{reason}; braking is hit from behind ({hit_from_behind[0]}): {label} instead"
                    if bad:
                        message += f", which still breaks: {bad[0]}"
        diag = PlanDiagnostics(stats, lateral, speed, _total(timer), ref.size, knot_count, best)
        return PlanResult(
            "fallback", message, traj, cands if options.return_candidates else None, diag, tuple(bad)
        )

    knot_count = 0
    if reason := timer.overrun("candidates"):
        return fallback(reason, candidate_path, _NOT_RUN, _NOT_RUN)

    with timer.stage("lateral"):
        knots = _knots(start, max(float(s_c[-1]), start.s + 2.0 * KNOT_SPACING))
        d_ref = np.interp(knots, s_c, d_c)
        lateral = _lateral(solvers.lateral, ref, problem, start, knots, d_ref, boxes, None, timer)
        if options.lateral_margin > 0.0 and not lateral.better_than_unsolved():
            # Where the margin to the lane's edges leaves no room (a tight turn, a narrow passage), it is
            # dropped, as it is knot by knot where the lane is narrow (the margin to obstacles is kept).
            relaxed = _lateral(solvers.lateral, ref, problem, start, knots, d_ref, boxes, 0.0, timer)
            if relaxed.rank() > lateral.rank():
                lateral = relaxed
        bounds, d_ref, blocked, road_end, qp = (
            lateral.bounds,
            lateral.d_ref,
            lateral.bounds.blocked,
            lateral.road_end,
            lateral.qp,
        )
        knot_count = int(bounds.s.shape[0])

    note = ""
    block_at = float(bounds.s[-1])  # where a block stops the path [m] (the bounds end before it)
    if qp.info.usable:  # an unfinished iterate comes integrated from the initial state: the checks decide
        path = frenet_path(ref, bounds.s, qp.d, qp.dd, qp.ddd)
    elif blocked is not None:
        # Close to a block the few knots left may leave no room to steer: keep the current offset and
        # stop before the block (the checks below still decide).
        hold = np.full(bounds.s.shape, start.d)
        path = frenet_path(ref, bounds.s, hold, 0.0 * hold, 0.0 * hold)
        note = f" (no room to steer, lateral QP {qp.info.status}: keeping the current offset)"
        # At that offset the footprint (aligned with the reference, as the path is) may meet a static
        # obstacle before the block: the first knot where it meets one, with the lateral bounds' margin
        # along s and d, is the block then (the moving ones bound the speed profile).
        half_s, half_d = vehicle_extent(np.zeros_like(hold), vehicle, options.lateral_margin)
        met = np.flatnonzero(box_hits(boxes, bounds.s, hold, half_s, half_d))
        if met.size and met[0] < blocked:
            blocked, road_end = int(met[0]), False
            block_at = float(bounds.s[blocked])
            note += " (an obstacle on that offset)"
    else:
        return fallback(f"lateral QP failed: {qp.info.status}", candidate_path, qp.info, _NOT_RUN)
    if reason := timer.overrun("lateral"):
        return fallback(reason, path, qp.info, _NOT_RUN)

    with timer.stage("speed"):
        front = 0.5 * vehicle.length + STOP_GAP
        if blocked is not None:  # STOP_GAP before the last free knot (the path may run on: ≥ 3 knots)
            last_free = knots[max(blocked - 1, 0)] - STOP_GAP
            s_stop = max(float(np.interp(last_free, path.s, path.sigma, left=0.0)), 0.0)
        elif ref.length - front < path.s[-1]:  # the front stops STOP_GAP before the reference's end
            s_stop = max(float(np.interp(ref.length - front, path.s, path.sigma)), 0.0)
        else:  # never past the path's end (it reaches a braking distance beyond the horizon)
            s_stop = path.length
        t_knots = np.arange(steps + 1, dtype=np.float64) * dt_speed
        # Where an obstacle was HEADWAY ago, not where it is: a gap that grows with its speed.
        t_seen = np.maximum(t_knots - HEADWAY, 0.0)
        movers = moving_obstacles(problem)
        s_upper = _space_time_bound(ref, path, movers, problem, t_seen, start.s)
        if s_upper is not None:
            s_upper = np.maximum(s_upper - STOP_GAP, 0.0)
        # Mirrored for the vehicles behind: wherever they will be within FOLLOWER_HEADWAY. A soft bound that
        # gives way to the stop, to the obstacles ahead and to the speed limit (the target speed is a cap).
        s_lower = _follower_bound(ref, path, movers, problem, t_knots, FOLLOWER_HEADWAY, start.s)
        if s_lower is not None:
            s_lower = s_lower + STOP_GAP
        solve = partial(_speed, solvers.speed, path, problem, s_stop, s_upper, steps, dt_speed)
        jerk = EMERGENCY_JERK if blocked is not None and not road_end else SPEED_JERK
        speed = solve(jerk, s_lower)
        if max(speed.speed_violation, speed.position_violation) > SPEED_SLACK and jerk < EMERGENCY_JERK:
            # The comfortable jerk cannot slow down in time (a curve or an obstacle close ahead):
            # safety before comfort, brake as hard as the emergency jerk allows. (Not for a follower
            # bound alone: more jerk hardly speeds up sooner.)
            speed = solve(EMERGENCY_JERK, s_lower)
        planned = speed
        if speed.info.usable and speed.position_violation > POSITION_SLACK:
            # Past a stop or a space-time bound (the solver's limits are soft): full braking keeps every
            # s(t) as small as the limits allow, so it is the answer here (no creeping up to a block).
            speed = _braking(path, problem, steps, dt_speed)
    if not speed.info.usable:
        return fallback(f"speed profile failed: {speed.info.status}", path, qp.info, speed.info)
    if reason := timer.overrun("speed"):
        return fallback(reason, path, qp.info, speed.info)

    with timer.stage("trajectory"):
        traj = sample(path, speed.t, speed.s - speed.s[0], speed.v, speed.a, speed.jerk, options.dt)
        bad = trajectory_violations(ref, problem, traj, shapes)
        if bad and planned is not speed:
            # Full braking for a bound the plan overshot breaks a check (it is hit from behind): the plan
            # itself, if it passes every check, is the better answer.
            kept = sample(
                path, planned.t, planned.s - planned.s[0], planned.v, planned.a, planned.jerk, options.dt
            )
            if not trajectory_violations(ref, problem, kept, shapes):
                note += (
                    f" (up to {planned.position_violation:.2f} m past a stop or an obstacle's headway:"
                    f" braking breaks a check, {bad[0]})"
                )
                speed, traj, bad = planned, kept, []
    if bad:
        # A follower's bound may have given way to a stop or a leader: the fallback then also weighs
        # keeping speed and this profile against braking into the follower.
        return fallback(
            f"the optimised trajectory breaks a check: {bad[0]}", path, qp.info, speed.info, planned
        )
    status: Status = "stopped" if blocked is not None and not road_end else "ok"
    if road_end:
        message = f"planned; the lane ends {bounds.s[-1] - start.s:.1f} m ahead{note}"
    elif blocked is not None:
        message = f"the road is blocked {block_at - start.s:.1f} m ahead; stopping before it{note}"
    else:
        message = f"planned{note}"
    diag = PlanDiagnostics(stats, qp.info, speed.info, _total(timer), ref.size, int(bounds.s.shape[0]), best)
    return PlanResult(status, message, traj, cands if options.return_candidates else None, diag)


def _severity(bad: list[str], rear: set[str]) -> tuple[int, int, int]:
    """How bad a trajectory's failed checks ``bad`` are, to compare fallbacks: hits of obstacles other
    than the vehicles behind (``rear``, as the checks word them), then hits from behind, then the other
    checks (curvature, lane, …, which do not hit anything by themselves)."""
    hits = [b for b in bad if b.startswith("footprint hits ")]
    from_behind = sum(b in rear for b in hits)
    return len(hits) - from_behind, from_behind, len(bad) - len(hits)


def _total(timer: _Timer) -> dict[str, float]:
    out = dict(timer.ms)
    out["total"] = sum(timer.ms.values())
    return out
