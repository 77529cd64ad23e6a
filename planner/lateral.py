"""The lateral stage: the chosen candidate's offsets smoothed into a drivable path by the lateral QP.

The path is the planned point's (:class:`planner.problem.Vehicle`): the vehicle's centre, or the rear
axle of a car, whose curvature limit and κ·d bound then apply to the path the rear axle drives and whose
footprint the bounds place from the rear axle along its heading. At knots ``s_i`` [m] (``knot_spacing``
apart, at most ``max_knots``) from the ego to the candidate's end,
the lateral bounds (:func:`planner.bounds.lateral_bounds`, obstacles passed on the candidate's side) are
cut before the first block, held beyond the reach of the planned point and opened to the ego's
offset near the start; the piecewise-jerk QP (:mod:`solvers.lateral_qp`) then tracks the candidate
within them, its ``d″`` bounded so that the path's curvature keeps :func:`curvature_allowance`.

Where the margin to the lane's edges leaves the QP no solution, it is dropped (the margin to obstacles
is kept); where the QP has no usable answer but the road is blocked ahead, the path holds the ego's
offset and the speed profile stops before the block (:func:`hold_path`).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy.ndimage import maximum_filter1d

from planner.bounds import KnotGeometry, LateralBounds, knot_geometry, lateral_bounds, pass_left
from planner.collision import FrenetBoxes, box_hits, boxes_overlap, footprint_extent, footprints
from planner.config import DEFAULT_CONFIG, LateralConfig, PlannerConfig
from planner.ego import EgoFrenet
from planner.kinematics import body_centre, curve_speed, lateral_curvature
from planner.lane import lane_bounds
from planner.problem import Lane, PlanningProblem, Vehicle, speed_cap
from planner.reference import FloatArray, ReferenceLine
from planner.st_bounds import static_shapes
from planner.timing import time_for
from planner.trajectory import Path, frenet_path
from planner.validation import (
    lane_overshoot,
    leaves_lane,
    outside_lane,
    return_length,
    start_overshoot,
    still_out,
)
from solvers.lateral_qp import LateralQPProblem, LateralQPResult, LateralQPSolver
from solvers.result import SolveInfo

#: a path this far outside its lateral bounds [m] breaks them (a relaxed QP's, not rounding)
_BOUND_TOL = 1e-3


def knots(
    ref: ReferenceLine, start: EgoFrenet, s_end: float, config: LateralConfig = DEFAULT_CONFIG.lateral
) -> FloatArray:
    """Knots [m] from the ego to ``s_end`` (at least two spacings on), ``knot_spacing`` apart or wider
    when there would be more than ``max_knots``; at least 3. Never so wide that the reference turns by
    more than ``max_knot_turn`` between two: the knots then end before ``s_end``."""
    s_end = max(s_end, start.s + 2.0 * config.knot_spacing)
    n = int(np.clip(np.ceil((s_end - start.s) / config.knot_spacing) + 1, 3, config.max_knots))
    span = ref.s[(ref.s >= start.s) & (ref.s <= s_end)]
    sharpest = float(np.max(np.abs(ref.kappa_at(span)))) if span.size else 0.0
    if sharpest > 0.0 and (s_end - start.s) / (n - 1) * sharpest > config.max_knot_turn:
        s_end = start.s + (n - 1) * max(config.max_knot_turn / sharpest, config.knot_spacing)
    return np.linspace(start.s, s_end, n)


def held_offset(ref: ReferenceLine, s: FloatArray, d: float) -> Path:
    """The path at the constant offset ``d`` [m] through knots ``s`` [m] (no steering)."""
    hold = np.full(s.shape, d)
    return frenet_path(ref, s, hold, 0.0 * hold, 0.0 * hold)


def smoothed_slope(d: FloatArray, s: FloatArray, window: float) -> FloatArray:
    """Heading error [rad] of a lateral profile ``d(s)`` [m]: its slope averaged over ``window`` [m]."""
    slope = np.arctan(np.gradient(d, s))
    width = max(1, round(window / max(float(s[1] - s[0]), 1e-6)))
    padded = np.pad(slope, (width // 2, width - 1 - width // 2), mode="edge")
    return np.asarray(np.convolve(padded, np.ones(width) / width, mode="valid"))


def _slowed_speed_sq(
    s: FloatArray, start: EgoFrenet, problem: PlanningProblem, braking_share: float
) -> FloatArray:
    """The squared speed [m²/s²] the vehicle can at best have slowed to at knots ``s`` [m], braking at
    ``braking_share`` of its deceleration from its speed at ``start`` (negative where it stands before)."""
    travelled = np.maximum(s - start.s, 0.0)
    decel = braking_share * problem.vehicle.max_deceleration
    return np.asarray(problem.ego.speed**2 - 2.0 * decel * travelled)


def curvature_allowance(
    s: FloatArray,
    start: EgoFrenet,
    problem: PlanningProblem,
    config: PlannerConfig = DEFAULT_CONFIG,
    braking_share: float = 0.5,
) -> FloatArray:
    """Largest path curvature [1/m] at knots ``s`` [m]: ``curvature_share · κ_max``, and the curvature
    at ``limit_margin · a_lat,max`` (:func:`planner.kinematics.lateral_curvature`: ``a/v²`` for the point
    model) for the speed ``v`` the vehicle can at best have slowed to there (braking at ``braking_share``
    of its deceleration from ``v₀``: half, or all of it to swerve round a block too close to stop for
    comfortably), so that the speed profile can keep the lateral-acceleration limit."""
    v = problem.vehicle
    v_sq = np.maximum(_slowed_speed_sq(s, start, problem, braking_share), 1.0)
    return np.minimum(
        config.lateral.curvature_share * v.curvature_limit,
        lateral_curvature(config.limit_margin * v.max_lateral_acceleration / v_sq, v),
    )


def curvature_rate_allowance(
    s: FloatArray,
    start: EgoFrenet,
    problem: PlanningProblem,
    config: PlannerConfig = DEFAULT_CONFIG,
    braking_share: float = 0.5,
) -> FloatArray | None:
    """Largest rate of change of a car's path curvature ``|dκ/dσ|`` [1/m²] at knots ``s`` [m] that keeps
    its steering rate within ``steering_rate_share · δ̇_max`` at the speed ``v`` it can at best have
    slowed to there (braking at ``braking_share`` of its deceleration from ``v₀``, as
    :func:`curvature_allowance`): ``|dδ/dt| = v · W/(1 + W²κ²) · |dκ/dσ| ≤ v · W · |dκ/dσ|``
    (:mod:`planner.kinematics`), so ``|dκ/dσ| ≤ share · δ̇_max / (W v)`` (``inf`` where it can stand).
    The speed profile slows for what the path asks (its steering-rate speed limit); this bound keeps
    the path to what braking can make drivable — a path that turns faster than that right ahead of a
    fast vehicle breaks the limit whatever the profile does. None for the point model or a car
    without ``max_steering_rate``."""
    v = problem.vehicle
    if v.wheelbase is None or v.max_steering_rate is None:
        return None
    speed = np.sqrt(np.maximum(_slowed_speed_sq(s, start, problem, braking_share), 0.0))
    rate = config.speed.steering_rate_share * v.max_steering_rate / v.wheelbase
    with np.errstate(divide="ignore"):
        return np.asarray(np.where(speed > 0.0, rate / np.maximum(speed, 1e-300), np.inf))


def straight_allowance(
    s: FloatArray,
    ref: ReferenceLine,
    problem: PlanningProblem,
    allowance: FloatArray,
    config: PlannerConfig = DEFAULT_CONFIG,
) -> FloatArray:
    """A tighter curvature allowance [1/m] at knots ``s`` [m] than ``allowance`` (:func:`curvature_allowance`)
    where the reference only jogs: in a window of ``straight_window`` [m] holding the knot, the
    reference's curvatures of either sign cancel out (their mean is less than ``jog_share`` of their mean
    magnitude — a kink of a fitted map, an S-shift), the curvature at ``limit_margin · a_lat,max`` for
    the cruise speed (the speed cap, or the ego's own where faster), never below the magnitude of the
    mean curvature around the knot; a bend of the road (one sign: its entry, its arc, its exit) keeps
    ``allowance``. Never above ``allowance``."""
    v = problem.vehicle
    # the speed it would cruise at unhindered: the speed cap, or the ego's own where that is faster
    speed = min(max(speed_cap(problem), problem.ego.speed), v.max_speed)
    cruise = lateral_curvature(config.limit_margin * v.max_lateral_acceleration / max(speed * speed, 1.0), v)
    half = 0.5 * config.lateral.straight_window
    grid = np.linspace(s[0] - half, s[-1] + half, max(3, int(np.ceil((s[-1] - s[0] + 2 * half) / 0.5)) + 1))
    kappa = ref.kappa_at(np.clip(grid, 0.0, ref.length))
    width = max(1, round(2 * half / float(grid[1] - grid[0])))
    box = np.ones(width) / width
    mean = np.convolve(kappa, box, mode="same")
    size = np.convolve(np.abs(kappa), box, mode="same")
    # a window that jogs makes every point in it part of the jog (its ends too, where a window centred
    # on them still sees one sign)
    # (curvatures within straight_slack are a straight's numerical noise, not a jog)
    jogs = (np.abs(mean) < config.lateral.jog_share * size) & (size > config.lateral.straight_slack)
    jog = maximum_filter1d(jogs.astype(np.uint8), width) > 0
    near = np.interp(s, grid, jog.astype(float)) > 0.0
    straight = np.where(near, np.maximum(cruise, np.abs(np.interp(s, grid, mean))), allowance)
    return np.asarray(np.minimum(allowance, straight))


def path_curvature(ref: ReferenceLine, s: FloatArray, qp: LateralQPResult) -> FloatArray:
    """The curvature [1/m] of the QP's path at its knots ``s`` [m], for small ``d′``:
    ``(d″/(1 − κd) + κ)/(1 − κd)`` (see :func:`lateral_problem`)."""
    kappa = ref.kappa_at(s)
    one = np.maximum(1.0 - kappa * qp.d, 1e-6)
    return np.asarray((qp.ddd / one + kappa) / one)


def reference_jerk(s: FloatArray, kappa: FloatArray, one: FloatArray) -> FloatArray:
    """The jerk ``d‴`` [1/m²] per interval of knots ``s`` [m] that evens out the reference's own change
    of curvature (``κ`` [1/m], ``1 − κd`` at the knots): ``−(1 − κd)² Δ(κ/(1 − κd)) / Δs``, the smaller
    ``1 − κd`` of the interval's ends (see :func:`lateral_problem`)."""
    stretch = np.minimum(one[:-1], one[1:])
    return np.asarray(-(stretch**2) * np.diff(kappa / one) / np.diff(s))


def jerk_bounds(
    s: FloatArray, kappa: FloatArray, one: FloatArray, rate: FloatArray, jerk: float
) -> tuple[FloatArray, FloatArray]:
    """Bounds on ``d‴`` [1/m²] per interval of knots ``s`` [m] (reference curvature ``κ`` [1/m] and
    ``1 − κd`` there) within ``±jerk`` that keep the path's ``|dκ_x/dσ|`` within ``rate`` [1/m²] at the
    interval's first knot (see :func:`lateral_problem`): ``d‴ ∈ r ± rate·(1 − κd)³`` about the
    :func:`reference_jerk` ``r``.
    Where the reference's own change is steeper than that, the bounds still include 0 (following the
    reference; the speed profile slows for it), so that holding ``d″`` stays feasible."""
    stretch = np.minimum(one[:-1], one[1:])
    own = reference_jerk(s, kappa, one)
    with np.errstate(over="ignore", invalid="ignore"):
        reach = rate[:-1] * stretch**3
        lo = own - reach
        hi = own + reach
    lo = np.nan_to_num(lo, nan=-np.inf)  # no rate bound (a vehicle that may stand there): inf − inf
    hi = np.nan_to_num(hi, nan=np.inf)
    lower = np.clip(np.minimum(lo, 0.0), -jerk, 0.0)
    upper = np.clip(np.maximum(hi, 0.0), 0.0, jerk)
    return np.asarray(lower), np.asarray(upper)


def solve_lateral(
    solver: LateralQPSolver,
    problem: LateralQPProblem,
    config: LateralConfig,
    time_limit_s: float | None = None,
    *,
    second_backend: bool = True,
    relax: bool = True,
    relax_later: bool = False,
    max_iter: int | None = None,
) -> LateralQPResult:
    """``problem`` solved by ``solver`` from a cold start within ``max_iter`` OSQP iterations (None:
    ``config.max_iter``) and ``time_limit_s`` [s] (None: none). ``second_backend``: what OSQP does not
    converge on goes to the solver's second backend; ``relax``: an infeasible QP gets the elastic
    problem's least-violating path (False: the proof only, ``infeasible``; :meth:`LateralQPSolver.relax`
    relaxes it later, which ``relax_later`` tells the solver to expect)."""
    # cold: the answer must not depend on what this process planned before
    return solver.solve(
        problem,
        max_iter=config.max_iter if max_iter is None else max_iter,
        time_limit_s=time_limit_s,
        warm_start=False,
        second_backend=second_backend,
        relax=relax,
        relax_later=relax_later,
    )


def lateral_problem(
    bounds: LateralBounds,
    d_ref: FloatArray,
    start: EgoFrenet,
    ref: ReferenceLine,
    allowance: FloatArray,
    config: LateralConfig,
    rate_allowance: FloatArray | None = None,
    smooth: bool = False,
) -> LateralQPProblem:
    """Piecewise-jerk QP on ``d(s)``; ``d″`` bounds linearised at ``d_ref`` keep ``|κ_path| ≤ allowance``,
    the jerk ``|d‴| ≤ jerk`` and, when given, ``|dκ_path/dσ| ≤ rate_allowance`` (per knot).

    For small ``d′`` the path's curvature is ``κ_x ≈ (d″/(1 − κd) + κ)/(1 − κd)``, so
    ``|κ_x| ≤ c`` ⇔ ``(−c(1 − κd) − κ)(1 − κd) ≤ d″ ≤ (c(1 − κd) − κ)(1 − κd)``, with ``1 − κd`` taken
    at ``d_ref`` (at least ``min_stretch``). The bounds are tightened by ``qp_slack`` [m].

    The rate (:func:`jerk_bounds`): over interval ``i``, ``Δκ_x ≈ Δd″/(1 − κd)² + Δ(κ/(1 − κd))`` and
    ``Δσ ≈ (1 − κd) Δs``, both with the smaller ``1 − κd`` of its ends; so the path also evens out the
    reference's own changes of curvature (a fitted polyline's ripple) where they alone would turn the
    wheel too fast. With ``smooth`` (and a rate allowance) the jerk term costs the path's own curvature
    rate rather than the offset's (:func:`reference_jerk`): the path eases into the reference's bends
    (a car's steering cannot jump), cutting them within the bounds.
    """
    s = bounds.s
    lower = bounds.lower + config.qp_slack
    upper = np.maximum(bounds.upper - config.qp_slack, lower)
    kappa = ref.kappa_at(s)
    one = np.clip(1.0 - kappa * np.clip(d_ref, lower, upper), config.min_stretch, None)
    with np.errstate(over="ignore"):  # a curvature limit near the largest float: ±inf, no bound
        ddd_upper = (allowance * one - kappa) * one
        ddd_lower = (-allowance * one - kappa) * one
    jerk_lower = jerk_upper = jerk_ref = None
    if rate_allowance is not None:  # a car whose steering rate is bounded: its path's curvature rate
        jerk_lower, jerk_upper = jerk_bounds(s, kappa, one, rate_allowance, config.jerk)
        jerk_ref = reference_jerk(s, kappa, one) if smooth else None
    return LateralQPProblem(
        ds=float(s[1] - s[0]),
        d_lower=lower,
        d_upper=upper,
        d_ref=np.clip(d_ref, lower, upper),
        jerk_max=config.jerk,
        jerk_lower=jerk_lower,
        jerk_upper=jerk_upper,
        jerk_ref=jerk_ref,
        d0=start.d,
        dd0=start.dd,
        ddd0=start.ddd,
        ddd_lower=ddd_lower,
        ddd_upper=ddd_upper,
    )


@dataclass(frozen=True)
class _Paths:
    """What one lateral stage works out about its QP answers, each once: an answer's path at its knots
    (:func:`planner.trajectory.frenet_path`) and the knots where its footprint leaves a surface
    (:func:`planner.validation.leaves_lane`). Several steps ask the same of one answer (the lane check
    of the choice in :func:`_attempt_at`, the straighter path's comparison in :func:`_attempt`, the
    stage's path and where it leaves the lane); what they get is what they computed before.

    Keyed by the answer's, the knots' and the surface's identities; each entry keeps them alive, so an
    identity is never reused while it is kept (one stage's few answers)."""

    ref: ReferenceLine
    problem: PlanningProblem
    _paths: dict[tuple[int, int], tuple[LateralQPResult, FloatArray, Path]] = field(default_factory=dict)
    _leaves: dict[tuple[int, int, int], tuple[LateralQPResult, FloatArray, Lane, NDArray[np.bool_]]] = field(
        default_factory=dict
    )

    def path(self, s: FloatArray, qp: LateralQPResult) -> Path:
        """The QP's path at its knots ``s`` [m]."""
        key = (id(qp), id(s))
        found = self._paths.get(key)
        if found is None:
            found = (qp, s, frenet_path(self.ref, s, qp.d, qp.dd, qp.ddd))
            self._paths[key] = found
        return found[2]

    def leaves(self, s: FloatArray, qp: LateralQPResult, surface: Lane) -> NDArray[np.bool_]:
        """Per knot of ``s`` [m], whether the footprint along the QP's path leaves ``surface`` (the lane, or
        a borrow's corridor) there (:func:`planner.validation.leaves_lane`)."""
        key = (id(qp), id(s), id(surface))
        found = self._leaves.get(key)
        if found is None:
            found = (qp, s, surface, self._leaves_at(s, qp, surface, slice(None)))
            self._leaves[key] = found
        return found[3]

    def _leaves_at(
        self, s: FloatArray, qp: LateralQPResult, surface: Lane, poses: slice | NDArray[np.intp]
    ) -> NDArray[np.bool_]:
        """:meth:`leaves` at the knots ``poses`` only (the first among them: leaves_lane's start)."""
        path = self.path(s, qp)
        heading = path.heading[poses]
        x, y = body_centre(path.x[poses], path.y[poses], heading, self.problem.vehicle)
        return leaves_lane(self.ref, self.problem, x, y, heading, surface)

    def in_lane(self, s: FloatArray, qp: LateralQPResult, surface: Lane) -> bool:
        """Whether the footprint along the QP's path stays on ``surface`` at its knots ``s`` [m] (the
        bounds are linearised at the candidate's heading; the path's own may differ).

        The pose whose planned point lies farthest outside ``surface`` by its own offset is checked
        first, with the start (whose overshoot the others are allowed): where it is out, so is the
        path, and the others need not be mapped. Those are the paths that leave the lane by metres,
        an unconverged iterate integrated from the start tens of metres off the road, say, whose
        outline points are the costliest to map (far from the reference many samples tie)."""
        if (id(qp), id(s), id(surface)) not in self._leaves:
            left, right = surface.widths(self.ref, s)
            worst = int(np.argmax(np.maximum(qp.d - left, -right - qp.d)))
            if bool(self._leaves_at(s, qp, surface, np.unique([0, worst]))[-1]):
                return False
        return not bool(np.any(self.leaves(s, qp, surface)))


@dataclass(frozen=True)
class _Corridor:
    """One set of bounds for the QP: the bounds (cut before a block), the reference offsets at their
    knots, whether a block is the road's end, and the surface the footprint keeps to (the lane, or a
    borrow's corridor)."""

    bounds: LateralBounds
    d_ref: FloatArray
    road_end: bool
    surface: Lane
    boxes: FrenetBoxes
    #: a car's eased path's bounds (:func:`_eased`), else None
    eased: LateralBounds | None = None

    @property
    def far(self) -> float:
        """How far the first block is (none, or the road's end: infinitely far) [m]."""
        blocked = self.bounds.blocked
        return np.inf if blocked is None or self.road_end else float(self.bounds.s[-1])


@dataclass(frozen=True)
class _Attempt:
    """A corridor, the QP's answer on it and whether its path keeps the footprint in the lane (checked
    when first asked: most plans never need to)."""

    corridor: _Corridor
    qp: LateralQPResult
    lane_check: Callable[[], bool]
    #: where the QP was proven infeasible and its least-violating path is left for later: the attempt with
    #: it weighed in (:meth:`settled`); ``qp`` is then the unrelaxed answer, never converged
    settle: Callable[[], _Attempt] | None = None

    @cached_property
    def in_lane(self) -> bool:
        """Whether the path keeps the footprint in the lane at its knots."""
        return self.lane_check()

    def settled(self) -> _Attempt:
        """This attempt with its least-violating path weighed in, where that was left for later."""
        return self if self.settle is None else self.settle()

    def best_rank(self) -> tuple[float, bool, bool]:
        """:meth:`rank`, or the highest settling can give (not solved; in the lane, say)."""
        return self.rank() if self.settle is None else (self.corridor.far, True, False)

    def better_than_unsolved(self) -> bool:
        """Solved, with no block on the way other than the road's end."""
        return self.qp.info.converged and self.corridor.far == np.inf

    def rank(self) -> tuple[float, bool, bool]:
        """How good: the farther the first block (none: infinitely far), then a path whose footprint
        stays in the lane, then solved over not."""
        return self.corridor.far, self.in_lane, self.qp.info.converged


def _qp_bounds(
    bounds: LateralBounds,
    d_ref: FloatArray,
    start: EgoFrenet,
    reach: float,
    vehicle_length: float,
    return_length: float | None = None,
) -> tuple[LateralBounds, FloatArray]:
    """The bounds handed to the QP and the reference offsets at their knots (see the module docstring);
    ``return_length`` [m]: where the ego's footprint starts outside its lane, how far it may take to be
    back (:func:`planner.validation.return_length`), else None."""
    s, lower, upper = bounds.s, bounds.lower, bounds.upper
    if bounds.blocked is not None:  # cut before the block (the path runs on: ≥ 3 knots)
        keep = max(bounds.blocked, 3)
        s, d_ref, lower = s[:keep], d_ref[:keep], lower[:keep]
        upper = np.maximum(upper[:keep], lower)
        lower = np.where(np.isfinite(lower), lower, start.d)
        upper = np.where(np.isfinite(upper), upper, start.d)
    # Beyond that the path is never driven: the lane's end there (its width often falls to 0 at the last
    # point) must not bend the path before it. The bounds of the last knot within reach hold there.
    last = int(np.searchsorted(s, reach, side="right")) - 1
    if last >= 1:
        beyond = s > reach
        lower = np.where(beyond, lower[last], lower)
        upper = np.where(beyond, upper[last], upper)
    # The ego is where it is: where the bounds near the start exclude its offset (a conservative bound
    # it is already inside, as beside an obstacle it is passing), they open to it and close again
    # linearly over one vehicle length, so that the QP can start there; the checks judge the footprint.
    # Where the footprint starts outside its lane they close no faster than the return the checks allow
    # (:func:`planner.validation.still_out`: a linear close asks a path that starts straight for a kink).
    left_open = 1.0 - np.clip((s - start.s) / vehicle_length, 0.0, 1.0)
    if return_length is not None:
        left_open = np.maximum(left_open, still_out(s - start.s, return_length))
    lower = np.minimum(lower, lower - (lower - start.d) * left_open)
    upper = np.maximum(upper, upper - (upper - start.d) * left_open)
    return LateralBounds(s=s, lower=lower, upper=upper, blocked=bounds.blocked), d_ref


@dataclass(frozen=True)
class _Knots:
    """What the corridors at one stage's knots share whatever their lane margin: the side each obstacle
    is passed on (``left_of``), the candidate's heading error [rad] per knot, the bounds'
    :class:`planner.bounds.KnotGeometry` (computed once for the corridor with its margin and without) and,
    where the ego's footprint starts outside the corridor, how far it may take to be back
    (``back`` [m], :func:`planner.validation.return_length`; else None)."""

    left_of: NDArray[np.bool_]
    heading_error: FloatArray
    geometry: KnotGeometry
    back: float | None


def _knots(
    ref: ReferenceLine,
    problem: PlanningProblem,
    at: FloatArray,
    d_ref: FloatArray,
    boxes: FrenetBoxes,
    config: PlannerConfig,
    corridor: Lane,
    sides: Mapping[str, bool],
) -> _Knots:
    """:class:`_Knots` at knots ``at`` [m] in ``corridor`` for the candidate's offsets ``d_ref`` [m], the
    obstacles in ``sides`` passed on the side a decision fixed, the others on the candidate's."""
    vehicle, options = problem.vehicle, problem.options
    lane = lane_bounds(ref, corridor, at, half_width=0.5 * vehicle.width, margin=options.lateral_margin)
    outside = start_overshoot(ref, problem, corridor)
    return _Knots(
        left_of=_sides(boxes, pass_left(boxes, at, d_ref, lane.lower, lane.upper), sides),
        heading_error=smoothed_slope(d_ref, at, config.lateral.heading_window),
        geometry=knot_geometry(ref, corridor, at, vehicle),
        back=return_length(problem, outside) if outside > 0.0 else None,
    )


def _corridor(
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    at: FloatArray,
    d_ref: FloatArray,
    boxes: FrenetBoxes,
    lane_margin: float | None,
    config: PlannerConfig,
    corridor: Lane,
    shared: _Knots,
) -> _Corridor:
    """Bounds at knots ``at`` in ``corridor`` (the lane, or a borrow's corridor; ``lane_margin`` [m] to
    its edges, default the options' margin) for the lateral QP tracking the candidate's offsets
    ``d_ref`` [m], with what the corridors at these knots share (``shared``: :func:`_knots`)."""
    vehicle = problem.vehicle

    def bounded(heading_error: FloatArray | None) -> LateralBounds:
        """The bounds with the footprint turned by ``heading_error`` [rad] per knot (None: not turned)."""
        return lateral_bounds(
            ref,
            corridor,
            at,
            vehicle,
            margin=problem.options.lateral_margin,
            boxes=boxes,
            left_of=shared.left_of,
            heading_error=heading_error,
            lane_margin=lane_margin,
            geometry=shared.geometry,
        )

    bounds = bounded(shared.heading_error)
    # The planned point never gets beyond this: the speed stage stops the front stop_gap before the
    # reference's end.
    reach = ref.length - vehicle.front_extent - config.stop_gap
    # a lane that runs out (narrower than the vehicle) at the reference's end is its end, not a block
    road_end = bounds.blocked is not None and at[bounds.blocked] >= reach
    eased = None
    if vehicle.max_steering_rate is not None and vehicle.wheelbase is not None:
        # the eased path's bounds (:func:`_eased`): the footprint along the reference's heading, cut where
        # these are; never narrower than these (where the turned footprint does not fit, they fall back)
        aligned = bounded(None)
        lower, upper = np.minimum(aligned.lower, bounds.lower), np.maximum(aligned.upper, bounds.upper)
        aligned = replace(aligned, lower=lower, upper=upper, blocked=bounds.blocked)
        eased, _ = _qp_bounds(aligned, d_ref, start, reach, vehicle.length, shared.back)
    bounds, d_ref = _qp_bounds(bounds, d_ref, start, reach, vehicle.length, shared.back)
    return _Corridor(bounds, d_ref, bool(road_end), corridor, boxes, eased)


def _attempt(
    solver: LateralQPSolver,
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    corridor: _Corridor,
    time_left: Callable[[], float | None],
    config: PlannerConfig,
    braking_share: float,
    paths: _Paths,
) -> _Attempt:
    """:func:`_attempt_at`; where its path bends more than :func:`straight_allowance` lets the vehicle
    cruise (a jog of the reference the lane has room to drive straight through), the QP once more with
    that allowance, whose path is taken if it converged and keeps the footprint in the lane: the speed
    profile need not slow for a bend the path can leave out."""
    bounds = corridor.bounds
    allowance = curvature_allowance(bounds.s, start, problem, config, braking_share)
    rate = curvature_rate_allowance(bounds.s, start, problem, config, braking_share)
    first = _attempt_at(solver, ref, problem, start, corridor, time_left, config, allowance, rate, paths)
    if not first.qp.info.converged:
        return first
    if not time_for(time_left, first.qp.info.solve_time_ms):
        return first  # the straighter path is optional: not past the budget
    straight = straight_allowance(bounds.s, ref, problem, allowance, config)
    bent = np.abs(path_curvature(ref, bounds.s, first.qp)) > straight + config.lateral.straight_slack
    # only beyond the first knots: the ego's own curvature at the start is a measurement
    ahead = bounds.s > start.s + problem.vehicle.length
    if not np.any(bent[ahead]):
        return first
    # optional: what OSQP does not settle within its iterations is not worth the second backend's time
    qp = solve_lateral(
        solver,
        lateral_problem(bounds, corridor.d_ref, start, ref, straight, config.lateral, rate, smooth=True),
        config.lateral,
        time_left(),
        second_backend=False,
        max_iter=config.lateral.straight_max_iter,
    )
    if not (qp.info.converged and paths.in_lane(bounds.s, qp, corridor.surface)):
        return first
    # taken only where it is faster to drive: a car's eased path through a real bend may be straighter at
    # a jog and yet need a slower curvature change for its steering rate elsewhere
    faster = _slowest(paths.path(bounds.s, qp), problem, ahead, config) > _slowest(
        paths.path(bounds.s, first.qp), problem, ahead, config
    )
    return _Attempt(corridor, qp, lambda: True) if faster else first


def _slowest(path: Path, problem: PlanningProblem, where: NDArray[np.bool_], config: PlannerConfig) -> float:
    """The lowest speed [m/s] a QP's ``path`` can be driven at where ``where`` holds (its curvature's and
    steering rate's limits, :func:`planner.kinematics.curve_speed`)."""
    speed = curve_speed(
        path.sigma, path.curvature, problem.vehicle, config.limit_margin, config.speed.steering_rate_share
    )
    return float(np.min(speed[where], initial=np.inf))


def _attempt_at(
    solver: LateralQPSolver,
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    corridor: _Corridor,
    time_left: Callable[[], float | None],
    config: PlannerConfig,
    allowance: FloatArray,
    rate: FloatArray | None,
    paths: _Paths,
) -> _Attempt:
    """The lateral QP in ``corridor`` within the curvature ``allowance`` [1/m] and, for a car, the
    curvature-rate ``rate`` [1/m²] per knot (:func:`curvature_allowance`,
    :func:`curvature_rate_allowance`), again with the vehicle's own curvature limit where the
    speed-dependent one leaves no solution or none that keeps the footprint in the lane; of the answers
    (and OSQP's own iterates beside the second backend's), the first in the lane, then solved. Where the
    QP was proven infeasible and OSQP's iterate keeps to the lane (no retry follows), the attempt comes
    back unsettled (its least-violating path not yet solved for, :meth:`_Attempt.settled`)."""
    bounds, d_ref = corridor.bounds, corridor.d_ref
    if rate is not None:
        # a car whose steering rate is bounded eases into the reference's bends where that keeps its
        # footprint in the lane; else it follows the reference as the point model does
        eased = _eased(solver, ref, problem, start, corridor, allowance, rate, time_left, config, paths)
        if eased is not None:
            return _Attempt(corridor, eased, lambda: True)
    qp_problem = lateral_problem(bounds, d_ref, start, ref, allowance, config.lateral, rate)
    # An infeasible QP's least-violating path (the elastic problem: the stage's costliest solve) is
    # solved only once the stage needs this attempt where that can wait (:meth:`_Attempt.settled`).
    qp = solve_lateral(solver, qp_problem, config.lateral, time_left(), relax=False, relax_later=True)
    if qp.info.converged and qp.first is None:  # OSQP solved it: nothing to choose from
        return _Attempt(corridor, qp, lambda: paths.in_lane(bounds.s, qp, corridor.surface))
    if qp.info.converged and paths.in_lane(bounds.s, qp, corridor.surface):
        # what the choice below takes (solved, in the lane, first): OSQP's iterate need not be checked
        return _Attempt(corridor, qp, lambda: True)
    # Where the second backend answered, OSQP's own iterate comes along: an exact path may press a bound
    # linearised at the candidate's heading, and a relaxed one break the lane; the first that keeps the
    # footprint in the lane is taken.
    options = [r for r in (qp, qp.first) if r is not None and r.info.usable]
    inside = [paths.in_lane(bounds.s, r, corridor.surface) for r in options]

    def relaxed_first() -> None:
        """The least-violating path, before OSQP's iterate (the order the choice breaks ties in)."""
        nonlocal qp, options, inside
        relaxed = solver.relax(qp_problem, qp, time_limit_s=time_left())
        if relaxed is not qp:
            options, inside = (
                [relaxed, *options],
                [paths.in_lane(bounds.s, relaxed, corridor.surface), *inside],
            )
            qp = relaxed

    if qp.infeasible and any(inside):
        # OSQP's iterate keeps to the lane, so no retry follows whatever the least-violating path does,
        # and nothing here is solved: the choice between the two can wait until the stage needs it
        def settle() -> _Attempt:
            relaxed_first()
            return _ranked(corridor, options, inside, qp)

        settled = functools.cache(settle)
        return _Attempt(corridor, qp, lambda: settled().in_lane, settle=settled)
    if qp.infeasible:
        relaxed_first()
    if not qp.info.converged and not any(inside) and time_for(time_left, qp.info.solve_time_ms):
        # too fast for the road, or no path in the lane: try the vehicle's own curvature limit
        limit = config.lateral.retry_curvature_share * problem.vehicle.curvature_limit
        allowance = np.full(bounds.s.shape, limit)
        retry_problem = lateral_problem(bounds, d_ref, start, ref, allowance, config.lateral, rate)
        retry = solve_lateral(solver, retry_problem, config.lateral, time_left())
        more = [r for r in (retry, retry.first) if r is not None and r.info.usable]
        inside += [paths.in_lane(bounds.s, r, corridor.surface) for r in more]
        options = options + more
        qp = retry if not options or not qp.info.usable else qp
    return _ranked(corridor, options, inside, qp)


def _ranked(
    corridor: _Corridor, options: list[LateralQPResult], inside: list[bool], fallback: LateralQPResult
) -> _Attempt:
    """The attempt with the first of ``options`` in the lane (``inside``), then solved; ``fallback``
    where there is no option."""
    qp = fallback
    if options:
        ranked = max(range(len(options)), key=lambda i: (inside[i], options[i].info.converged, -i))
        qp = options[ranked]
    found = any(inside)
    return _Attempt(corridor, qp, lambda: found)


def _eased(
    solver: LateralQPSolver,
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    corridor: _Corridor,
    allowance: FloatArray,
    rate: FloatArray,
    time_left: Callable[[], float | None],
    config: PlannerConfig,
    paths: _Paths,
) -> LateralQPResult | None:
    """A car's lateral QP in ``corridor`` that eases into the reference's bends (:func:`lateral_problem`'s
    ``smooth``, within the curvature ``allowance`` [1/m] and curvature-rate ``rate`` [1/m²] per knot),
    when it converges and its path keeps the footprint in the lane; else None.

    Its bounds (``corridor.eased``) place the footprint along the reference's heading, not turned by
    the candidate's heading error as the other QPs' are: the eased path leaves the candidate's heading
    anyway, and the candidate's bends towards the inside of a curve the closer the car gets to it, so
    bounds turned by it closed in on the path cycle by cycle, each plan cutting the bend less and
    turning in more sharply, the car crawling through a bend it entered at walking pace (DEU_Lohmar-26:
    rear-ended there). The footprint's exact place is checked instead: where the footprint of the eased
    path leaves the lane at a knot (by :func:`planner.validation.lane_overshoot`), that knot's bound is
    moved inside the path's own offset by the overshoot and the QP's ``qp_slack`` (the footprint is then
    that much inside at the knot, which the trajectory sampled between the knots needs: it reaches a
    millimetre or two further out on the edge) and the QP solves once more; a path whose footprint,
    turned by the path's own heading error, meets an obstacle's box is not taken (:func:`_meets_obstacle`).
    Without the repair, a bend whose bounds the eased path misses by millimetres left only the path that
    follows the reference's own change of curvature: in a tight bend one the steering rate lets the car
    drive at a crawl, the speed profile braking hard for it."""
    bounds = corridor.bounds if corridor.eased is None else corridor.eased
    for repair in (False, True):
        qp = solve_lateral(
            solver,
            lateral_problem(bounds, corridor.d_ref, start, ref, allowance, config.lateral, rate, smooth=True),
            config.lateral,
            time_left(),
            relax=False,  # only a converged answer is taken: no least-violating path for a proof
        )
        if not qp.info.converged:
            return None
        path = paths.path(bounds.s, qp)
        x, y = body_centre(path.x, path.y, path.heading, problem.vehicle)
        right, left = lane_overshoot(ref, problem, x, y, path.heading, corridor.surface)
        right_out, left_out = right > 0.0, left > 0.0
        if not (right_out.any() or left_out.any()):
            if _meets_obstacle(ref, corridor, qp, problem, config):
                return None
            return qp
        if repair:
            return None
        right, left = right + config.lateral.qp_slack, left + config.lateral.qp_slack
        lower = np.where(
            right_out, np.minimum(np.maximum(bounds.lower, qp.d + right), bounds.upper), bounds.lower
        )
        upper = np.where(left_out, np.maximum(np.minimum(bounds.upper, qp.d - left), lower), bounds.upper)
        bounds = replace(bounds, lower=lower, upper=upper)
    return None


def _box_overlaps(
    ref: ReferenceLine,
    corridor: _Corridor,
    qp: LateralQPResult,
    problem: PlanningProblem,
    config: PlannerConfig,
) -> NDArray[np.bool_]:
    """Per knot and obstacle box of ``corridor``, whether the footprint along the QP's path, turned by the
    path's own heading error, overlaps the box (the bounds keep clear of them at the candidate's
    heading); shape (knots, boxes)."""
    s = corridor.bounds.s
    one = np.clip(1.0 - ref.kappa_at(s) * qp.d, config.lateral.min_stretch, None)
    extent = footprint_extent(np.arctan(qp.dd / one), problem.vehicle, 0.0).column()
    boxes = corridor.boxes
    return boxes_overlap(
        s[:, None], qp.d[:, None], extent, boxes.s_min, boxes.s_max, boxes.d_min, boxes.d_max
    )


def _meets_obstacle(
    ref: ReferenceLine,
    corridor: _Corridor,
    qp: LateralQPResult,
    problem: PlanningProblem,
    config: PlannerConfig,
) -> bool:
    """Whether the footprint along the QP's path meets an obstacle's box of ``corridor`` at a knot
    (:func:`_box_overlaps`)."""
    return bool(np.any(_box_overlaps(ref, corridor, qp, problem, config)))


def _runs_into(
    ref: ReferenceLine,
    corridor: _Corridor,
    qp: LateralQPResult,
    path: Path,
    problem: PlanningProblem,
    config: PlannerConfig,
) -> int | None:
    """The first knot after the start where the QP's ``path`` breaks the bounds of ``corridor`` (by more
    than :data:`_BOUND_TOL`) and its footprint meets a static obstacle that it did not meet at the start
    or that begins ahead of the planned point; or None. The boxes (:func:`_box_overlaps`) pick the knots
    and obstacles, their outlines decide (the boxes of a turned obstacle reach further than it does).

    The bounds keep the footprint clear of the boxes; a relaxed QP's path that breaks them (the vehicle
    too close to an obstacle to steer round it) would drive into it, and the checks would turn the answer
    into a fallback: the plan stops before that knot instead.
    """
    bounds, boxes = corridor.bounds, corridor.boxes
    broken = (qp.d > bounds.upper + _BOUND_TOL) | (qp.d < bounds.lower - _BOUND_TOL)
    broken[0] = False
    if boxes.count == 0 or not broken.any():
        return None
    hit = _box_overlaps(ref, corridor, qp, problem, config)
    new = ~hit[0] | (boxes.s_min > bounds.s[0])  # (one beside the vehicle now: the checks decide)
    hit &= new & broken[:, None]
    knots, which = np.nonzero(hit)
    if knots.size == 0:
        return None
    shapes = dict(static_shapes(problem))  # (the boxes a decision sweeps for movers are left to the checks)
    ids = [boxes.ids[k] for k in which]
    known = np.array([i in shapes for i in ids], dtype=bool)
    if not known.any():
        return None
    knots, ids = knots[known], [i for i, ok in zip(ids, known, strict=True) if ok]
    x, y = body_centre(path.x[knots], path.y[knots], path.heading[knots], problem.vehicle)
    body = footprints(x, y, path.heading[knots], problem.vehicle)
    met = knots[shapely.intersects(body, np.array([shapes[i] for i in ids], dtype=object))]
    return int(met.min()) if met.size else None


def _leaves_from(
    paths: _Paths, s: FloatArray, qp: LateralQPResult, surface: Lane, reach: float
) -> int | None:
    """The first knot of the QP's path at knots ``s`` [m] before ``reach`` [m] (beyond it the vehicle
    never gets: the lane's end) where the footprint leaves ``surface`` (at least 1), or None; None too
    where it starts outside (a vehicle coming back into its lane from the road)."""
    path = paths.path(s, qp)
    x, y = body_centre(path.x, path.y, path.heading, paths.problem.vehicle)
    if outside_lane(paths.ref, paths.problem, x[:1], y[:1], path.heading[:1], surface)[0]:
        return None
    out = np.flatnonzero(paths.leaves(s, qp, surface) & (path.s < reach))
    return None if out.size == 0 else max(int(out[0]), 1)


def _sides(boxes: FrenetBoxes, left_of: NDArray[np.bool_], sides: Mapping[str, bool]) -> NDArray[np.bool_]:
    """``left_of`` with the sides a decision fixed (obstacle id → passed on its left) put in."""
    if not sides:
        return left_of
    fixed = [sides.get(ob_id) for ob_id in boxes.ids]
    return np.array([side if side is not None else own for side, own in zip(fixed, left_of, strict=True)])


@dataclass(frozen=True)
class LateralPlan:
    """The lateral stage's outcome.

    Attributes:
        path: the QP's path, the held offset (``held``), or None when there is neither (a failure).
        info: how the lateral QP went.
        bounds: the bounds at the knots the QP ran on (cut before a block).
        blocked: the first blocked knot of ``bounds.s`` (an obstacle on the held offset may come before
            the bounds' own block), or None.
        road_end: whether the block is the lane's end rather than something in the way.
        held: whether ``path`` holds the ego's offset because the QP left no room to steer.
        obstacle_on_hold: whether an obstacle on the held offset is the block.
        waiting: whether the block is a line to wait at before the lane's own (:meth:`stopping_at`).
        leaves: whether the block is where the QP's path leaves the lane although its bounds let it
            through (where the bounds' linearisation fails: a bend too tight for the footprint, or a
            path steeper than the bounds expect, swerving round an obstacle or from the ego's pose).
        meets: whether the block is where the QP's path, relaxed past its bounds (no room to steer
            from where the vehicle is), meets a static obstacle (:func:`_runs_into`).
    """

    path: Path | None
    info: SolveInfo
    bounds: LateralBounds
    blocked: int | None
    road_end: bool
    held: bool = False
    obstacle_on_hold: bool = False
    waiting: bool = False
    leaves: bool = False
    meets: bool = False

    @property
    def knots(self) -> int:
        """Knots of the lateral QP."""
        return int(self.bounds.s.shape[0])

    @property
    def block_at(self) -> float:
        """Where a block stops the path [m] (the bounds end before the bounds' own block)."""
        at_knot = self.obstacle_on_hold or self.waiting or self.leaves or self.meets
        return float(self.bounds.s[self.blocked]) if at_knot else float(self.bounds.s[-1])

    @property
    def stops(self) -> bool:
        """Whether the plan must stop before a block (one that is not the lane's end)."""
        return self.blocked is not None and not self.road_end

    def stop_s(self, stop_gap: float) -> float | None:
        """The farthest arc length on the reference [m] the planned point may reach before the block:
        ``stop_gap`` [m] before the last free knot (the speed stage's stop, :func:`planner.speed.
        stop_position`); None without a block."""
        if self.blocked is None:
            return None
        return float(self.bounds.s[max(self.blocked - 1, 0)]) - stop_gap

    def stopping_at(self, s: float) -> LateralPlan:
        """The plan stopping before the first knot at or beyond ``s`` [m] if that comes before its own
        block (a line to wait at: :attr:`planner.decision.Decision.wait_at`)."""
        knot = int(np.searchsorted(self.bounds.s, s))
        own = self.bounds.s.shape[0] if self.blocked is None or self.road_end else self.blocked
        if knot >= min(own, self.bounds.s.shape[0]):
            return self
        return replace(self, blocked=max(knot, 1), road_end=False, waiting=True)


def lateral_stage(
    solver: LateralQPSolver,
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    candidate: tuple[FloatArray, FloatArray],
    boxes: FrenetBoxes,
    time_left: Callable[[], float | None],
    config: PlannerConfig = DEFAULT_CONFIG,
    lane: Lane | None = None,
    braking_share: float = 0.5,
    sides: Mapping[str, bool] | None = None,
) -> LateralPlan:
    """The path along the chosen ``candidate`` (its kept ``(s, d)`` [m]) clear of the static obstacles'
    ``boxes``, within ``lane`` (default the problem's: a borrow's corridor, :mod:`planner.decision`), its
    curvature within :func:`curvature_allowance` for ``braking_share``, the obstacles in ``sides`` (id →
    passed on its left) on the side a decision fixed, the others on the candidate's; the QP gets what
    ``time_left`` [s] (None: no limit) says is left of the budget."""
    s_c, d_c = candidate
    surface = problem.lane if lane is None else lane
    at = knots(ref, start, float(s_c[-1]), config.lateral)
    d_ref = np.interp(at, s_c, d_c)
    fixed = {} if sides is None else sides
    shared = _knots(ref, problem, at, d_ref, boxes, config, surface, fixed)
    corridor = _corridor(ref, problem, start, at, d_ref, boxes, None, config, surface, shared)
    paths = _Paths(ref, problem)
    began = time.perf_counter()
    attempt = _attempt(solver, ref, problem, start, corridor, time_left, config, braking_share, paths)
    took_ms = 1e3 * (time.perf_counter() - began)
    if (
        problem.options.lateral_margin > 0.0
        and not attempt.better_than_unsolved()
        and time_for(time_left, took_ms)
    ):
        # Where the margin to the lane's edges leaves no room (a tight turn, a narrow passage), it is
        # dropped, as it is knot by knot where the lane is narrow (the margin to obstacles is kept).
        # Its QP is solved only where it could rank higher: a farther block, or a first QP unsolved.
        relaxed = _corridor(ref, problem, start, at, d_ref, boxes, 0.0, config, surface, shared)
        # (an attempt left to settle is never solved: whether it is in the lane decides nothing here)
        if (relaxed.far, True, True) > attempt.best_rank():
            retry = _attempt(solver, ref, problem, start, relaxed, time_left, config, braking_share, paths)
            retry = retry.settled()
            if retry.rank() > attempt.best_rank():
                attempt = retry  # better whatever the first's least-violating path: it is not needed
            else:
                attempt = attempt.settled()
                if retry.rank() > attempt.rank():
                    attempt = retry
    attempt = attempt.settled()
    bounds, qp, road_end = attempt.corridor.bounds, attempt.qp, attempt.corridor.road_end
    # An unfinished iterate comes integrated from the initial state, a relaxed path breaks some bounds:
    # the checks decide, but where it leaves the lane or turns more sharply than the vehicle can (a
    # relaxed curvature bound) and a block lies ahead, holding the offset is safer.
    held = bounds.blocked is not None and not (
        qp.info.converged or (attempt.in_lane and _turnable(paths.path(bounds.s, qp), problem.vehicle))
    )
    if qp.info.usable and not held:
        path = paths.path(bounds.s, qp)
        # a relaxed path that breaks its bounds into a static obstacle is trusted only up to there
        met = _runs_into(ref, attempt.corridor, qp, path, problem, config)
        if bounds.blocked is None and not attempt.in_lane:
            # the bounds let the footprint through where the path leaves the lane: that is the block
            # (stop before it; the lane decision may borrow the road round it)
            reach = ref.length - problem.vehicle.front_extent - config.stop_gap
            out = _leaves_from(paths, bounds.s, qp, attempt.corridor.surface, reach)
            if out is not None and (met is None or out <= met):
                return LateralPlan(path, qp.info, bounds, out, False, leaves=True)
        if met is not None and (bounds.blocked is None or met < bounds.blocked):
            return LateralPlan(path, qp.info, bounds, met, False, meets=True)
        return LateralPlan(path, qp.info, bounds, bounds.blocked, road_end)
    if bounds.blocked is None:
        return LateralPlan(None, qp.info, bounds, None, road_end)
    return hold_path(ref, problem, start, boxes, bounds, bounds.blocked, road_end, qp.info)


def _turnable(path: Path, vehicle: Vehicle) -> bool:
    """Whether the vehicle can turn along ``path``: its curvature within the vehicle's limit [1/m]."""
    return bool(np.max(np.abs(path.curvature), initial=0.0) <= vehicle.curvature_limit)


def hold_path(
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    boxes: FrenetBoxes,
    bounds: LateralBounds,
    blocked: int,
    road_end: bool,
    info: SolveInfo,
) -> LateralPlan:
    """Close to a block (the knot ``blocked``) the few knots left may leave the QP no room to steer: keep
    the current offset along ``bounds.s`` and stop before the block (the trajectory checks still decide).

    At that offset the footprint (aligned with the reference, as the path is) may meet a static obstacle
    before the block: the first knot where it meets one, with ``Options.lateral_margin`` along ``s`` and
    ``d``, is the block then (the moving ones bound the speed profile).
    """
    path = held_offset(ref, bounds.s, start.d)
    zero = np.zeros_like(bounds.s)
    extent = footprint_extent(zero, problem.vehicle, problem.options.lateral_margin)
    met = np.flatnonzero(box_hits(boxes, bounds.s, path.d, extent))
    if met.size and met[0] < blocked:
        return LateralPlan(path, info, bounds, int(met[0]), False, held=True, obstacle_on_hold=True)
    return LateralPlan(path, info, bounds, blocked, road_end, held=True)
