"""Candidate lateral profiles: Algorithm 4 (naive offsets) and Algorithm 5 (TransF-κ repair).

Each candidate is a smooth lateral profile ``d(s)`` over the path ahead of the ego. With
``τ = clip((s − s₀)/L, 0, 1)`` for a transition length ``L`` [m]::

    d(s) = h(τ)·d_end(s) + d₀·H₀(τ) + d₀′L·H₁(τ) + d₀″L²·H₂(τ)

where ``h(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` and ``H₀ = 1 − h``, ``H₁``, ``H₂`` are the quintic Hermite basis
functions, so the profile starts at the ego's ``(d, d′, d″)`` and settles, with zero slope and zero
curvature, onto ``d_end(s) = α·w(s)``: a fixed fraction ``α ∈ [−1, 1]`` of the usable half-width on
that side (lane width less half the vehicle width and a margin). ``α`` and ``L`` are drawn from
``seed`` (stratified in ``α``); the profile is then kept inside the lane bounds.

* ``naive`` (Algorithm 4) maps every ``(s, d)`` to Cartesian with ``x = r(s) + d·n(s)`` as is. Where
  ``κ·d ≥ 1`` the offset curve folds back: it runs backwards and may self-intersect.
* ``transf_kappa`` (Algorithm 5) takes each point where ``κ·d ≥ 1`` — and, more generally, each point
  whose Cartesian position TransF-κ attributes to another part of the reference (a wide inner side of
  a U-turn overlapping the opposite leg) — to Cartesian and back through TransF-κ, which lands it,
  by the biggest-index rule, beyond the high-curvature stretch. The candidate then keeps only points
  whose ``s`` exceeds every ``s`` before it: the stretch folded behind the repaired point is jumped
  and ``s`` strictly increases along the candidate. A point is kept only if ``κ(s)·d < 1``.

Everything is vectorised over candidates × points; the only loops run over a fixed small number of
walk steps inside TransF-κ.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from planner.ego import EgoFrenet, check_ego_on_road, ego_frenet
from planner.errors import InvalidInputError
from planner.frenet import offset_basis, to_frenet
from planner.lane import LaneBounds, lane_bounds
from planner.problem import Ego, Generator, Lane, Options, Vehicle
from planner.reference import FloatArray, ReferenceLine

#: fraction of the largest empty tangent disc trusted to round-trip without checking
_LIMIT_SAFETY = 0.97
#: an empty disc smaller than this fraction of 1/κ is bounded by another stretch of the reference
_BRANCH_RATIO = 0.9
#: samples nearer than this many spacings along the reference are the column's own stretch of curve
_OWN_STRETCH = 1.5
#: time before full deceleration is reached when braking from cruise (jerk-limited ramp) [s]
BRAKE_DELAY = 1.5
#: longest path the candidates cover [m]: a longer braking distance (``v²/a`` of a weak brake: 10³⁰¹ m
#: for 10⁻³⁰⁰ m/s²) or minimum length is capped here, and the speed profile keeps within the path
MAX_PATH_LENGTH = 20_000.0
#: round-trip tolerance separating consistent points from those TransF-κ attributes elsewhere [m]
_CONSISTENCY_TOLERANCE = 1e-6


@dataclass(frozen=True)
class CandidateSet:
    """``N`` candidates of ``P`` points each.

    Attributes:
        s, d: Frenet coordinates [m], shape (N, P); repaired values where a point was repaired.
        xy: Cartesian points [m], shape (N, P, 2).
        kappa: reference curvature at ``s`` [1/m], shape (N, P).
        valid: whether each point belongs to the candidate (False where Algorithm 5 jumped it),
            shape (N, P); always all True for ``naive``.
        repaired: whether any point of the candidate was repaired or jumped, shape (N,).
        end_fraction: α, the end offset as a fraction of the usable half-width, shape (N,).
        transition: L, the transition length [m], shape (N,).
        generator: ``naive`` or ``transf_kappa``.
    """

    s: FloatArray
    d: FloatArray
    xy: FloatArray
    kappa: FloatArray
    valid: NDArray[np.bool_]
    repaired: NDArray[np.bool_]
    end_fraction: FloatArray
    transition: FloatArray
    generator: Generator

    @property
    def count(self) -> int:
        """Number of candidates N."""
        return int(self.s.shape[0])

    def points(self, i: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``(s, d, xy)`` of the points kept in candidate ``i``."""
        keep = self.valid[i]
        return self.s[i, keep], self.d[i, keep], self.xy[i, keep]


def path_length(ego: Ego, vehicle: Vehicle, options: Options, reach_speed: float | None = None) -> float:
    """Arc length the candidates cover [m]: the distance at the faster of the current speed and the
    target speed (``reach_speed`` [m/s] instead, when given: a plan that may drive faster) over the
    horizon and then a gentle braking distance from it, at least ``min_path_length``."""
    target = vehicle.max_speed if options.target_speed is None else options.target_speed
    fastest = max(ego.speed, target if reach_speed is None else reach_speed)
    # the speed profile keeps room to stop at half the vehicle's deceleration beyond its horizon
    braking = braking_distance(fastest, 0.5 * vehicle.max_deceleration) + fastest * BRAKE_DELAY
    return min(max(options.min_path_length, options.horizon_time * fastest + braking), MAX_PATH_LENGTH)


def horizon_reach(ego: Ego, vehicle: Vehicle, options: Options) -> float:
    """The farthest the vehicle can drive within the horizon [m]: at full acceleration from the ego's
    speed, never faster than the faster of that speed and ``max_speed``."""
    horizon, speed = options.horizon_time, max(ego.speed, 0.0)
    accelerating = speed * horizon + 0.5 * vehicle.max_acceleration * horizon**2
    return min(accelerating, max(speed, vehicle.max_speed) * horizon, MAX_PATH_LENGTH)


def braking_distance(speed: float, deceleration: float) -> float:
    """``v²/(2a)`` [m] from ``speed`` [m/s] at ``deceleration`` [m/s²] > 0, at most :data:`MAX_PATH_LENGTH`
    (never an overflow: ``v·(v/a)`` is at worst ``inf`` before the cap)."""
    return min(0.5 * speed * (speed / deceleration), MAX_PATH_LENGTH)


def _profiles(tau: FloatArray, d0: float, slope: FloatArray, bend: FloatArray, end: FloatArray) -> FloatArray:
    """``d = d₀ + h(τ)·(end − d₀) + slope·H₁(τ) + bend·H₂(τ)`` in Horner form, shape of ``tau``.

    ``h = 10τ³ − 15τ⁴ + 6τ⁵``, ``H₁ = τ − 6τ³ + 8τ⁴ − 3τ⁵``, ``H₂ = ½τ² − 3⁄2τ³ + 3⁄2τ⁴ − ½τ⁵``
    (``slope = d₀′L``, ``bend = d₀″L²``, per row).
    """
    t2 = tau * tau
    d = (6.0 * tau - 15.0) * tau
    d += 10.0
    d *= t2 * tau
    d *= end - d0
    d += d0
    if np.any(slope):
        h1 = ((-3.0 * tau + 8.0) * tau - 6.0) * t2
        h1 += 1.0
        h1 *= tau
        d += slope[:, None] * h1
    if np.any(bend):
        h2 = ((-0.5 * tau + 1.5) * tau - 1.5) * tau
        h2 += 0.5
        h2 *= t2
        d += bend[:, None] * h2
    return d


def generate_candidates(
    ref: ReferenceLine,
    lane: Lane,
    ego: Ego,
    vehicle: Vehicle,
    options: Options,
    *,
    start: EgoFrenet | None = None,
    reach_speed: float | None = None,
) -> CandidateSet:
    """Generate ``options.num_candidates`` candidates of ``options.num_points`` points from ``start``,
    as long as :func:`path_length` (``reach_speed``: see there; a plan passes
    :func:`planner.speed.reach_speed`).

    A plan starts them from :func:`planner.ego.start_state`; without ``start``, the ego's state is
    :func:`planner.ego.ego_frenet`'s, without the plan's curvature clip. Raises
    :class:`InvalidInputError` when the ego is off the road (:func:`planner.ego.check_ego_on_road`) or
    at or past the end of the reference line.
    """
    start = ego_frenet(ref, ego) if start is None else start
    check_ego_on_road(ref, lane, start)
    # Up to the reference's end, or past it along the end ray by the braking distance (a vehicle
    # too fast to stop before the end still needs a path to brake on), as far as the horizon can reach
    # (a weak brake's distance would spread the candidates' points thin across the road's curves).
    braking = braking_distance(ego.speed, vehicle.max_deceleration) + ego.speed * BRAKE_DELAY
    ahead = min(braking, horizon_reach(ego, vehicle, options)) + vehicle.length
    s_end = min(start.s + path_length(ego, vehicle, options, reach_speed), max(ref.length, start.s + ahead))
    if ref.length - start.s < 1e-3:
        raise InvalidInputError("the ego is at or past the end of the reference line", field="ego")
    n, p = options.num_candidates, options.num_points
    rng = np.random.default_rng(options.seed)
    span = s_end - start.s
    alpha = -1.0 + 2.0 * (np.arange(n) + rng.uniform(size=n)) / n
    # Transition lengths log-uniform from a quick swerve (about 1.5 s of driving, at least two vehicle
    # lengths) to the whole path: an obstacle close ahead needs the short ones, comfort the long ones.
    shortest = float(np.clip(1.5 * ego.speed, 2.0 * vehicle.length, span))
    transition = shortest * (span / shortest) ** rng.uniform(size=n)

    # Everything that depends on s alone is computed once per column, not per candidate.
    s_row = np.linspace(start.s, s_end, p)
    bounds = lane_bounds(ref, lane, s_row, half_width=0.5 * vehicle.width, margin=options.lateral_margin)
    origin, normal = offset_basis(ref, s_row)
    kappa_row = ref.kappa_at(s_row)

    limits = None
    lower_row, upper_row = bounds.lower, bounds.upper
    if options.generator == "transf_kappa":
        limits = _consistent_offsets(ref, s_row, bounds, separation=0.5 * vehicle.width)
        lower_row, upper_row = limits.lower_own, limits.upper_own

    tau = (s_row[None, :] - start.s) / transition[:, None]
    np.clip(tau, 0.0, 1.0, out=tau)
    end = np.where(alpha >= 0, alpha, 0.0)[:, None] * bounds.upper[None, :]
    end -= np.where(alpha < 0, alpha, 0.0)[:, None] * bounds.lower[None, :]
    d = _profiles(tau, start.d, start.dd * transition, start.ddd * transition**2, end)
    # Keep inside the bounds; near the start they widen to take in an ego outside them.
    if lower_row[0] <= start.d <= upper_row[0]:
        np.clip(d, lower_row, upper_row, out=d)
    else:
        ramp = 1.0 - tau**3 * ((6.0 * tau - 15.0) * tau + 10.0)
        lower = lower_row + np.minimum(0.0, start.d - lower_row) * ramp
        upper = upper_row + np.maximum(0.0, start.d - upper_row) * ramp
        np.clip(d, lower, upper, out=d)
    s = np.broadcast_to(s_row, d.shape)
    xy = origin[None, :, :] + d[:, :, None] * normal[None, :, :]
    if limits is None:
        return CandidateSet(
            s=s,
            d=d,
            xy=xy,
            kappa=np.broadcast_to(kappa_row, d.shape),
            valid=np.ones(d.shape, dtype=bool),
            repaired=np.zeros(n, dtype=bool),
            end_fraction=alpha,
            transition=transition,
            generator="naive",
        )
    return _repair(ref, s_row, d, xy, kappa_row, limits, alpha, transition)


@dataclass(frozen=True)
class OffsetLimits:
    """Per column, offsets [m] that TransF-κ maps back to themselves, and the candidates' own bounds.

    ``[lower_ok, upper_ok] ∋ 0`` round-trips through TransF-κ (conservatively). Where the round trip
    fails because another stretch of the reference is nearer (the lane overlaps the opposite
    leg of a U-turn, κ·d < 1 still), the lane is cut at that medial axis less ``separation``:
    ``[lower_own, upper_own]``; where it fails because κ·d reaches 1, the lane bound stays and
    Algorithm 5 repairs the points beyond.
    """

    lower_ok: FloatArray
    upper_ok: FloatArray
    lower_own: FloatArray
    upper_own: FloatArray


def _consistent_offsets(
    ref: ReferenceLine, s_row: FloatArray, bounds: LaneBounds, *, separation: float
) -> OffsetLimits:
    """Find the :class:`OffsetLimits` of each column from the largest empty tangent discs.

    ``x = r + d·n`` keeps ``r`` as its nearest reference point as long as the disc of radius ``d``
    around it holds no sample. A sample ``L_j`` with ``w = L_j − r`` enters that disc once
    ``d > ρ_j = |w|² / (2·w·n)`` (for ``w·n > 0``; ``−n`` on the right side), so the offsets that
    round-trip are ``d < min_j ρ_j`` — ``1/κ`` where the nearest ``L_j`` are the neighbours on the
    curve, less where another stretch of the reference comes nearer (then the lane is cut there, less
    ``separation``). Only samples within twice the bound matter. The trusted offsets also stay short of
    the polygon's wedge apexes nearby (where TransF-κ folds) and of 1/κ, with a safety factor for
    the tie tolerance; points beyond are simply checked. Cost: one ball query per column.
    """
    origin, direction = offset_basis(ref, s_row)  # the Frenet line of each column: origin + d·direction
    stretch = np.linalg.norm(direction, axis=1)  # metres along the line per metre of d
    normal = direction / stretch[:, None]
    reach = 2.0 * np.maximum(np.abs(bounds.upper), np.abs(bounds.lower)) + ref.spacing
    near = ref.tree.query_ball_point(origin, reach)
    owner = np.repeat(np.arange(s_row.shape[0]), [len(n) for n in near])
    j = np.fromiter(itertools.chain.from_iterable(near), dtype=np.intp, count=owner.shape[0])
    w = ref.points[j] - origin[owner]
    across = np.einsum("ij,ij->i", w, normal[owner])
    sq = np.einsum("ij,ij->i", w, w)
    # The samples of the column's own stretch of curve (within 1.5 spacings along it) are left out:
    # their limit is 1/κ and the wedge apexes (below), and where the Frenet line is not exactly
    # normal to the curve a sample a millimetre away gave a spurious ρ ≈ 0.
    own_stretch = np.abs(ref.s[j] - s_row[owner]) < _OWN_STRETCH * ref.spacing
    kappa = ref.kappa_at(s_row)
    apex = _wedge_apex(ref, s_row)
    out = {}
    for side, sign, bound in (("upper", 1.0, bounds.upper), ("lower", -1.0, bounds.lower)):
        a = sign * across
        with np.errstate(divide="ignore", invalid="ignore"):
            rho_j = np.where(a > 0, sq / (2.0 * a), np.inf)
        rho = _per_column(rho_j, owner, s_row.shape[0], own_stretch) / stretch
        with np.errstate(divide="ignore"):
            curl = np.where(sign * kappa > 0, 1.0 / np.abs(kappa), np.inf)  # centre of curvature
        ok = sign * np.minimum(_LIMIT_SAFETY * np.minimum(np.minimum(rho, curl), apex[side]), sign * bound)
        # The disc is bounded by another stretch of the reference, not by the curve bending round.
        other_branch = rho < _BRANCH_RATIO * curl
        cut = _LIMIT_SAFETY * rho
        own = np.where(other_branch & (sign * bound > cut), sign * np.maximum(cut - separation, 0.0), bound)
        out[side] = (np.where(sign * ok > 0, ok, 0.0), own)
    (upper_ok, upper_own), (lower_ok, lower_own) = out["upper"], out["lower"]
    return OffsetLimits(lower_ok=lower_ok, upper_ok=upper_ok, lower_own=lower_own, upper_own=upper_own)


def _wedge_apex(ref: ReferenceLine, s_row: FloatArray, *, around: int = 8) -> dict[str, FloatArray]:
    """Per column and side, the nearest apex [m] of the bisector wedges within ``around`` segments.

    Beyond a wedge's apex (where its two bisectors meet, ``ℓ + (k₁ − k₀)·v = 0``) TransF-κ folds; the
    polygon's apexes may come nearer than the smooth curve's 1/κ where curvature changes fast.
    """
    n_seg = ref.seg_len.shape[0]
    slope = ref.k_end - ref.k_start
    inner = np.zeros(n_seg, dtype=bool)
    inner[1:-1] = True
    with np.errstate(divide="ignore"):
        left = np.where(inner & (slope < 0), -ref.seg_len / slope, np.inf)
        right = np.where(inner & (slope > 0), ref.seg_len / slope, np.inf)
    seg = np.clip(np.floor(s_row / ref.spacing), 0, n_seg - 1).astype(np.intp)
    window = np.clip(seg[:, None] + np.arange(-around, around + 1), 0, n_seg - 1)
    return {"upper": left[window].min(axis=1), "lower": right[window].min(axis=1)}


def _per_column(
    values: FloatArray, owner: NDArray[np.intp], columns: int, skip: NDArray[np.bool_]
) -> FloatArray:
    """Smallest of ``values`` per column (``inf`` where a column has none), ``skip`` left out."""
    out = np.full(columns, np.inf)
    np.minimum.at(out, owner, np.where(skip, np.inf, values))
    return out


def _repair(
    ref: ReferenceLine,
    s_row: FloatArray,
    d: FloatArray,
    xy: FloatArray,
    kappa_row: FloatArray,
    limits: OffsetLimits,
    alpha: FloatArray,
    transition: FloatArray,
) -> CandidateSet:
    """Algorithm 5 over all candidates at once (see the module docstring).

    Points outside ``[lower_ok, upper_ok]`` (which excludes every κ·d ≥ 1 point) go to Cartesian
    and back through TransF-κ; the others are TransF-κ's own answer already.
    """
    shape = d.shape
    bad = (d > limits.upper_ok) | (d < limits.lower_ok)
    s_new = np.array(np.broadcast_to(s_row, shape))
    d_new = d.copy()
    kappa = np.array(np.broadcast_to(kappa_row, shape))
    valid = np.ones(shape, dtype=bool)
    changed = np.zeros(shape, dtype=bool)
    if bad.any():
        fr = to_frenet(ref, xy[bad])
        changed[bad] = (np.abs(fr.s - s_new[bad]) > _CONSISTENCY_TOLERANCE) | (
            np.abs(fr.d - d[bad]) > _CONSISTENCY_TOLERANCE
        )
        s_new[bad] = fr.s
        d_new[bad] = fr.d
        kappa[bad] = ref.kappa_at(fr.s)
        valid[bad] = kappa[bad] * fr.d < 1.0
        # Keep the strict running records of s: the stretch folded behind a repaired point is jumped.
        before = np.empty(shape)
        before[:, 0] = -np.inf
        np.maximum.accumulate(s_new[:, :-1], axis=1, out=before[:, 1:])
        valid &= s_new > before
    valid[:, 0] = True
    repaired: NDArray[np.bool_] = np.any(changed | ~valid, axis=1)
    return CandidateSet(
        s=s_new,
        d=d_new,
        xy=xy,
        kappa=kappa,
        valid=valid,
        repaired=repaired,
        end_fraction=alpha,
        transition=transition,
        generator="transf_kappa",
    )
