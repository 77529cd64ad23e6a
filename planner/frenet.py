"""TransF-κ: Cartesian ⇄ Frenet on the sampled reference (Sun et al., Algorithms 1–3), vectorised.

Cartesian → Frenet (:func:`to_frenet`) for a batch of points ``A``:

1. *Nearest sample, biggest index* (Alg. 1, lines 1–3): the nearest sample ``L_m``; among samples
   whose distance is within ``tie_abs + tie_rel·distance`` of the nearest, the biggest index.
2. *Bisector choice* (Alg. 1, lines 4–9): of the two segments at ``L_m`` take the one on ``A``'s side
   of the angular bisector at ``L_m``. A walk along the segments follows while ``A`` lies beyond the
   chosen segment's other bisector, one way only, until a wedge between two bisectors holds it
   (needed where the Voronoi cell of a sample and the bisector wedges differ: far from the curve,
   where curvature changes, or where the tie tolerance let a later sample of a flat stretch of the
   distance function win). Near-ties between distinct stretches stay on the later stretch.
3. *Transform*. In the frame of segment ``j`` (from ``a = L_j`` with unit direction ``e``, left
   normal ``n``, chord ``ℓ``), ``u = (A − a)·e`` and ``v = (A − a)·n``. The bisectors at the
   segment's ends are the lines ``u = k₀·v`` and ``u = ℓ + k₁·v``.

   * Inner segment, bisector affine transform (Alg. 2): the line through the bisectors' intersection
     ``O`` and ``A`` meets the segment at the fraction

         f = (u − k₀·v) / (ℓ + (k₁ − k₀)·v)

     (a central projection from ``O`` keeps ratios along lines parallel to the segment, so this is
     the paper's ``|L_{m−1}P|`` without computing ``O``; it stays finite when the bisectors are
     parallel). ``s = s_j + f·Δ``, ``d = v``.
   * End segments extended as rays, parallel transform (Alg. 3): the level lines of ``s`` are
     parallel to the one bisector bounding the piece, ``s = s_j + (u − k₀·v)·Δ/ℓ`` on the last piece
     and ``s = s_1 + (u − ℓ − k₁·v)·Δ/ℓ`` on the first, so ``s`` is continuous across that bisector
     and defined on the whole plane (``s < 0`` behind the start, ``s > length`` beyond the end).

``d`` is signed, positive to the left of the reference. :func:`to_cartesian` is the exact inverse
of each piece: a Cartesian → Frenet → Cartesian round trip returns the same point up to rounding
everywhere except in the fold region just beyond a segment's centre of curvature (where ``f`` had to
be clipped). It is also the discretised ``x = r(s) + d·n(s)`` that Algorithm 4 maps candidates with:
for ``κ·d ≥ 1`` it folds back exactly as the smooth formula does.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from planner.reference import FloatArray, ReferenceLine

#: ties: samples within ``TIE_ABS + TIE_REL·distance`` of the nearest distance count as nearest [m]
TIE_ABS = 1e-6
TIE_REL = 1e-4
#: samples measured either side of the later of the two nearest where more than two tie: a straight
#: seen from 100 m off ties about ±0.014·100 m / Δ samples (±6 at Δ = 0.25 m); longer runs (an arc seen
#: from its centre) the tree lists
_CROWD = 16
#: wedge positions within this of [0, 1] are inside (rounding on a bisector)
_WEDGE_TOLERANCE = 1e-9


@dataclass(frozen=True)
class FrenetPoints:
    """Result of :func:`to_frenet` for ``N`` points.

    Attributes:
        s: arc length of the projection [m], shape (N,).
        d: signed lateral offset, positive to the left [m], shape (N,).
        segment: index j of the segment (``L_j → L_{j+1}``) used for each point, shape (N,).
        nearest: index m of the nearest sample chosen by the biggest-index rule, shape (N,).
        folded: True where the point lies beyond its segment's centre of curvature and ``f`` was
            clipped (κ·d ≥ 1 region); the round trip is exact wherever this is False.
    """

    s: FloatArray
    d: FloatArray
    segment: NDArray[np.intp]
    nearest: NDArray[np.intp]
    folded: NDArray[np.bool_]


def _as_points(points: ArrayLike) -> FloatArray:
    arr = np.asarray(points, dtype=float)
    if arr.ndim == 1 and arr.shape[0] == 2:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise ValueError("points must have shape (N, 2)")
    return arr


def nearest_sample(
    ref: ReferenceLine, points: FloatArray, *, tie_abs: float = TIE_ABS, tie_rel: float = TIE_REL
) -> NDArray[np.intp]:
    """Index of the nearest sample to each point, the biggest index among (near-)ties (Alg. 1, 1–3)."""
    # the three nearest: where the third is no tie, the two are all the ties there are
    k = min(3, ref.size)
    found = ref.tree.query(points, k=k, workers=-1 if points.shape[0] > 20_000 else 1)
    dist: FloatArray = np.asarray(found[0], dtype=float)
    idx: NDArray[np.intp] = np.asarray(found[1], dtype=np.intp)
    far = np.flatnonzero(~np.isfinite(dist[:, 1]))
    if far.size:
        # The tree squares distances: beyond ~10¹⁵⁴ m they overflow and it reports no neighbour
        # (index M). Such a point is measured to every sample with hypot (no squares); the samples
        # within the tie limit of the nearest (at that distance, all of them) tie, the last wins.
        gap = ref.points[None, :, :] - points[far, None, :]
        measured = np.hypot(gap[..., 0], gap[..., 1])
        nearest = measured.min(axis=1, keepdims=True)
        ties = measured <= nearest * (1.0 + tie_rel) + tie_abs
        idx[far] = np.max(np.where(ties, np.arange(ref.size), -1), axis=1)[:, None]
        dist[far] = np.inf
        dist[far, 0] = nearest[:, 0]
    limit = dist[:, 0] * (1.0 + tie_rel) + tie_abs
    tie = dist[:, 1] <= limit
    chosen = np.where(tie, np.maximum(idx[:, 0], idx[:, 1]), idx[:, 0])
    if k == 3 and bool(np.any(dist[:, 2] <= limit)):
        # More than two samples tie: along an arc seen from its centre, along a straight seen from far
        # off (the relative tolerance), on two stretches that pass at the same distance. A window of
        # samples either side of the later of the two is measured (such ties are mostly contiguous);
        # where it does not hold as many as the tree counts, the tree lists them.
        more = np.flatnonzero(dist[:, 2] <= limit)
        count = np.asarray(ref.tree.query_ball_point(points[more], limit[more], return_length=True))
        window = chosen[more, None] + np.arange(-_CROWD, _CROWD + 1)
        valid = (window >= 0) & (window < ref.size)
        gap = ref.points[np.clip(window, 0, ref.size - 1)] - points[more, None, :]
        within = valid & (np.hypot(gap[..., 0], gap[..., 1]) <= limit[more, None])
        chosen[more] = np.max(np.where(within, window, -1), axis=1)
        full = more[within.sum(axis=1) != count]
        if full.size:
            balls = ref.tree.query_ball_point(points[full], limit[full])
            chosen[full] = [max(b) for b in balls]
    return chosen.astype(np.intp)


def _wedge(
    ref: ReferenceLine, seg: NDArray[np.intp], pts: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Local coordinates ``(u, v)`` of points in their segment's frame and their wedge position ``t``.

    ``t < 0`` before the start bisector, ``0 ≤ t ≤ 1`` between the bisectors (then ``t`` is the
    fraction ``f`` of Algorithm 2), ``t > 1`` beyond the end bisector, NaN beyond the segment's centre
    of curvature. The first piece is open before its end bisector, the last after its start.
    """
    table = ref.segment_table[seg]
    dx = pts[:, 0] - table[:, 0]
    dy = pts[:, 1] - table[:, 1]
    u = dx * table[:, 2] + dy * table[:, 3]
    v = dy * table[:, 2] - dx * table[:, 3]
    ell, k0, k1 = table[:, 4], table[:, 5], table[:, 6]
    num = u - k0 * v
    den = ell + (k1 - k0) * v
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num / den
    t[den <= 1e-12 * ell] = np.nan
    last_seg = ref.seg_len.shape[0] - 1
    if last_seg == 0:
        t[:] = 0.5
    else:
        first = np.flatnonzero(seg == 0)
        t[first] = np.maximum(1.0 + (u[first] - ell[first] - k1[first] * v[first]) / ell[first], 0.0)
        last = np.flatnonzero(seg == last_seg)
        t[last] = np.minimum(num[last] / ell[last], 1.0)
    return u, v, t


def to_frenet(
    ref: ReferenceLine, points: ArrayLike, *, tie_abs: float = TIE_ABS, tie_rel: float = TIE_REL
) -> FrenetPoints:
    """TransF-κ: Frenet coordinates of Cartesian points (vectorised Algorithms 1–3).

    Args:
        ref: the sampled reference.
        points: Cartesian points, shape (N, 2) [m].
        tie_abs, tie_rel: distances within ``tie_abs + tie_rel·nearest`` [m] of the nearest count as
            ties for the biggest-index rule.
    """
    pts = _as_points(points)
    n_seg = ref.seg_len.shape[0]
    m = nearest_sample(ref, pts, tie_abs=tie_abs, tie_rel=tie_rel)

    # Alg. 1 lines 4-9: v± = ⟨L_m A, L_m L_{m±1}⟩; the side of the angular bisector at L_m decides.
    # With e_± the unit directions to L_{m±1}, v₋ < v₊ ⟺ ⟨L_m A, e₊ − e₋⟩ > 0.
    table = ref.sample_table[m]
    ahead = (pts[:, 0] - table[:, 0]) * table[:, 2] + (pts[:, 1] - table[:, 1]) * table[:, 3]
    seg = np.where(ahead > 0.0, m, m - 1)
    seg = np.clip(seg, 0, n_seg - 1)  # end samples: the end pieces (Alg. 3)

    # Walk to the neighbour where the point lies beyond the chosen segment's other bisector.
    u, v, t = _wedge(ref, seg, pts)
    rows = np.flatnonzero((t < 0.0) | (t > 1.0))
    for _ in range(ref.size):  # each point walks one way only, so this ends within M steps
        if rows.size == 0:
            break
        step = np.where(t[rows] > 1.0, 1, -1)
        cand = np.clip(seg[rows] + step, 0, n_seg - 1)
        u2, v2, t2 = _wedge(ref, cand, pts[rows])
        ok = (cand != seg[rows]) & ~np.isnan(t2)
        ok &= ~(((step > 0) & (t2 < 0.0)) | ((step < 0) & (t2 > 1.0)))  # no ping-pong
        moved = rows[ok]
        seg[moved], u[moved], v[moved], t[moved] = cand[ok], u2[ok], v2[ok], t2[ok]
        rows = moved[(t2[ok] < 0.0) | (t2[ok] > 1.0)]

    s, folded = _forward(ref, seg, u, v, t)
    return FrenetPoints(s=s, d=v, segment=seg, nearest=m, folded=folded)


def _forward(
    ref: ReferenceLine, seg: NDArray[np.intp], u: FloatArray, v: FloatArray, t: FloatArray
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Algorithms 2 and 3: ``s`` from the wedge position; ``folded`` where ``t`` had to be clipped."""
    delta = ref.spacing
    folded = ~((t >= -_WEDGE_TOLERANCE) & (t <= 1.0 + _WEDGE_TOLERANCE))  # NaN included
    s = np.asarray((seg + np.clip(np.nan_to_num(t, nan=0.5), 0.0, 1.0)) * delta, dtype=np.float64)
    last_seg = ref.seg_len.shape[0] - 1
    ends = np.flatnonzero((seg == 0) | (seg == last_seg))
    if ends.size:
        table = ref.segment_table[seg[ends]]
        ell, k0, k1 = table[:, 4], table[:, 5], table[:, 6]
        ue, ve, se = u[ends], v[ends], seg[ends]
        s_end = np.where(
            se == 0,
            delta + (ue - ell - k1 * ve) * delta / ell,  # first piece: parallel to the bisector at L_1
            se * delta + (ue - k0 * ve) * delta / ell,  # last piece: parallel to its start bisector
        )
        if last_seg == 0:
            s_end = ue * delta / ell
        s[ends] = s_end
        folded[ends] = False
    return s, folded


def offset_basis(ref: ReferenceLine, s: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """The inverse of TransF-κ is affine in ``d`` at fixed ``s``: ``x(s, d) = r(s) + d·ñ(s)``.

    Returns ``r(s)`` and ``ñ(s)`` [m, -], each of shape ``(*s.shape, 2)``. ``ñ`` is the bisector
    direction interpolated along the segment, scaled so that its component along the segment's
    left normal is 1; on a straight reference it is the unit normal.
    """
    s_arr = np.asarray(s, dtype=float)
    s_flat = s_arr.reshape(-1)
    n_seg = ref.seg_len.shape[0]
    delta = ref.spacing
    seg = np.clip(np.floor(s_flat / delta), 0, n_seg - 1).astype(np.intp)
    ell = ref.seg_len[seg]
    k0 = ref.k_start[seg]
    k1 = ref.k_end[seg]
    along = (s_flat - ref.s[seg]) * ell / delta  # arc length → chord length
    f = along / ell
    c0 = along
    c1 = k0 + f * (k1 - k0)
    first = seg == 0
    last = seg == n_seg - 1
    c0 = np.where(first & ~last, ell + (s_flat - ref.s[1]) * ell / delta, c0)
    c1 = np.where(first & ~last, k1, np.where(last & ~first, k0, c1))
    c1 = np.where(first & last, 0.0, c1)
    e = ref.seg_dir[seg]
    normal = np.column_stack((-e[:, 1], e[:, 0]))
    origin = ref.points[seg] + c0[:, None] * e
    direction = normal + c1[:, None] * e
    return origin.reshape((*s_arr.shape, 2)), direction.reshape((*s_arr.shape, 2))


def to_cartesian(ref: ReferenceLine, s: ArrayLike, d: ArrayLike) -> FloatArray:
    """Inverse of TransF-κ: Cartesian points [m] of Frenet coordinates ``(s, d)`` [m], shape (…, 2).

    This is also the discretised ``x = r(s) + d·n(s)`` of Algorithm 4; for ``κ·d ≥ 1`` it folds back
    like the smooth formula.
    """
    s_arr, d_arr = np.broadcast_arrays(np.asarray(s, dtype=float), np.asarray(d, dtype=float))
    origin, direction = offset_basis(ref, s_arr)
    return origin + d_arr[..., None] * direction
