"""Reference line: a user polyline turned into the uniformly sampled polygonal line of TransF-κ.

The paper (Sun et al., Sec. III-C) asks of the sampled reference ``U = {L_c}``:

* identical spacing between adjacent samples,
* spacing much smaller than ``1/κ``,
* at most 10° of heading change between adjacent samples,

and extends the first and last segments as rays. A user polyline satisfies none of this in general
(coarse 5 m highway points, irregular survey points, hairpins), so :func:`build_reference`

1. validates and cleans the input (finite, consecutive duplicates dropped, ≥ 2 distinct points),
2. fits an interpolating cubic spline ``r(u)`` parameterised by chord length (scipy),
3. measures its arc length ``s(u)`` on a fine grid (Simpson's rule) and its curvature ``κ(u)``,
4. resamples at uniform arc length with spacing ``Δ = min(max_spacing, angle_per_sample / κ_max)``.

Curvature comes from the spline's derivatives, ``κ = (x′y″ − y′x″) / |r′|³`` [1/m], never from the
angles of the input polyline. ``s`` of a sample is its arc length along the spline [m], so
``s_i = i·Δ`` exactly.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree

from planner.errors import InvalidInputError, InvalidReferenceError

FloatArray = NDArray[np.float64]

#: default largest sample spacing [m]
DEFAULT_MAX_SPACING = 0.5
#: default heading change allowed between adjacent samples [rad] (≈ 2.9°, well under the paper's 10°)
DEFAULT_ANGLE_PER_SAMPLE = 0.05
#: smallest spacing ever used [m]; below it a cusp in the input would explode the sample count
MIN_SPACING = 0.01
#: most samples a reference may have
MAX_SAMPLES = 200_000
#: consecutive input points closer than this are duplicates [m]
DUPLICATE_TOLERANCE = 1e-6
#: largest heading change at one input point [rad]; beyond it the line runs back on itself
MAX_VERTEX_TURN = np.radians(170.0)
#: largest heading change between adjacent samples of the fitted curve [rad] (a loop or cusp)
MAX_SAMPLE_TURN = np.radians(45.0)


def _read_only(a: FloatArray) -> FloatArray:
    """``a``, made read-only (a reference's arrays are shared by every plan on it)."""
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class ReferenceLine:
    """The resampled reference: ``M`` samples ``L_0 … L_{M-1}`` and ``M − 1`` segments.

    Attributes (all numpy arrays are read-only):
        points: sample positions, shape (M, 2) [m].
        s: arc length of each sample, ``i·spacing``, shape (M,) [m].
        heading: tangent direction of the smooth curve at each sample, shape (M,) [rad].
        kappa: signed curvature of the smooth curve at each sample (left turn > 0), shape (M,) [1/m].
        spacing: the identical arc-length spacing Δ [m].
        seg_dir: unit direction of each segment ``L_j → L_{j+1}``, shape (M−1, 2).
        seg_len: chord length of each segment, shape (M−1,) [m].
        k_start, k_end: slope of the angular bisector at the segment's start / end vertex in the
            segment's own frame (the bisector line is ``u = k·v`` resp. ``u = ℓ + k·v`` where ``u``
            runs along the segment and ``v`` to its left); zero where the vertex is an end point.
        input_s: arc length of each (cleaned) input point, shape (n,) [m].
        input_index: index of each cleaned input point in the caller's original array, shape (n,).
        tree: k-d tree over ``points`` for the nearest-sample queries of TransF-κ.
        segment_table: per segment ``[x_j, y_j, e_x, e_y, ℓ, k_start, k_end]``, shape (M−1, 7):
            what TransF-κ gathers per point, packed so that one gather fetches it.
        sample_table: per sample ``[x_m, y_m, b_x, b_y]``, shape (M, 4), with ``b = e₊ − e₋`` the
            sum of the unit directions of the adjacent segments (Alg. 1's bisector test).
    """

    points: FloatArray
    s: FloatArray
    heading: FloatArray
    kappa: FloatArray
    spacing: float
    seg_dir: FloatArray
    seg_len: FloatArray
    k_start: FloatArray
    k_end: FloatArray
    input_s: FloatArray
    input_index: NDArray[np.intp]
    tree: cKDTree = field(repr=False)
    segment_table: FloatArray = field(repr=False)
    sample_table: FloatArray = field(repr=False)

    @property
    def length(self) -> float:
        """Arc length of the reference [m]."""
        return float(self.s[-1])

    @property
    def size(self) -> int:
        """Number of samples M."""
        return int(self.points.shape[0])

    @property
    def max_turn_per_sample(self) -> float:
        """Largest heading change between adjacent segments [rad] (paper: ≤ 10°)."""
        if self.seg_dir.shape[0] < 2:
            return 0.0
        a, b = self.seg_dir[:-1], self.seg_dir[1:]
        cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
        dot = np.einsum("ij,ij->i", a, b)
        return float(np.max(np.abs(np.arctan2(cross, dot))))

    @cached_property
    def unwrapped_heading(self) -> FloatArray:
        """``heading`` without its 2π jumps [rad], shape (M,) (computed once: every path asks for it)."""
        return _read_only(np.unwrap(self.heading))

    @cached_property
    def kappa_slope(self) -> FloatArray:
        """``dκ/ds`` at each sample by central differences (``np.gradient``) [1/m²], shape (M,)
        (computed once: every path asks for it)."""
        return _read_only(np.gradient(self.kappa, self.s))

    def kappa_at(self, s: ArrayLike) -> FloatArray:
        """Curvature κ(s) [1/m], linear between samples, held constant beyond the ends."""
        return np.interp(np.asarray(s, dtype=float), self.s, self.kappa)

    def heading_at(self, s: ArrayLike) -> FloatArray:
        """Heading θ(s) of the smooth reference [rad], interpolated between samples."""
        return np.interp(np.asarray(s, dtype=float), self.s, self.unwrapped_heading)


def clean_polyline(
    points: ArrayLike, *, field_name: str = "reference_line"
) -> tuple[FloatArray, NDArray[np.intp]]:
    """Validate a polyline and drop consecutive duplicate points.

    Returns the cleaned ``(n, 2)`` array and the index of each kept point in the input.
    Raises :class:`InvalidReferenceError` naming ``field_name`` for a wrong shape, non-finite values
    or fewer than two distinct points.
    """
    try:
        arr = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidReferenceError("must be a list of [x, y] pairs of numbers", field=field_name) from exc
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InvalidReferenceError("must be a list of [x, y] pairs", field=field_name)
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise InvalidReferenceError(
            f"point {int(np.argmax(bad))} is not finite", field=f"{field_name}.{int(np.argmax(bad))}"
        )
    if arr.shape[0] == 0:
        raise InvalidReferenceError("needs at least two distinct points", field=field_name)
    step = np.linalg.norm(np.diff(arr, axis=0), axis=1)
    keep = np.concatenate(([True], step > DUPLICATE_TOLERANCE))
    index = np.flatnonzero(keep)
    cleaned = arr[keep]
    if cleaned.shape[0] < 2:
        raise InvalidReferenceError("needs at least two distinct points", field=field_name)
    # A vertex where the line runs (nearly) straight back has no driving direction.
    e = np.diff(cleaned, axis=0)
    e /= np.linalg.norm(e, axis=1)[:, None]
    turn = np.arctan2(e[:-1, 0] * e[1:, 1] - e[:-1, 1] * e[1:, 0], np.einsum("ij,ij->i", e[:-1], e[1:]))
    back = np.flatnonzero(np.abs(turn) > MAX_VERTEX_TURN)
    if back.size:
        vertex = int(index[back[0] + 1])
        raise InvalidReferenceError(
            f"turns back on itself at point {vertex} ({np.degrees(abs(turn[back[0]])):.0f}° at one point)",
            field=f"{field_name}.{vertex}",
        )
    return cleaned, index


def _fine_grid(u_knots: FloatArray, resolution: float) -> FloatArray:
    """Parameter grid containing every knot, each interval split into pieces ≤ ``resolution``."""
    pieces = np.maximum(np.ceil(np.diff(u_knots) / resolution).astype(int), 4)
    total = int(pieces.sum())
    owner = np.repeat(np.arange(pieces.size), pieces)
    offset = np.arange(total) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    frac = offset / pieces[owner]
    u = u_knots[owner] + frac * np.diff(u_knots)[owner]
    return np.append(u, u_knots[-1])


def build_reference(
    points: ArrayLike,
    *,
    max_spacing: float = DEFAULT_MAX_SPACING,
    angle_per_sample: float = DEFAULT_ANGLE_PER_SAMPLE,
    field_name: str = "reference_line",
) -> ReferenceLine:
    """Fit, measure and uniformly resample a user polyline (driving order) into a :class:`ReferenceLine`.

    The last few references built are kept, keyed by the polyline's exact values and the arguments: a
    closed loop sends the same polyline every cycle. A reference is a pure function of them, its arrays
    read-only, so the kept one is the one that would be built (errors are raised every time).

    Args:
        points: the polyline, shape (n, 2) [m], n ≥ 2 distinct points.
        max_spacing: largest sample spacing Δ [m].
        angle_per_sample: largest heading change per sample [rad]; Δ ≤ angle_per_sample / κ_max.
        field_name: name of the input field, used in error messages.
    """
    try:
        arr = np.ascontiguousarray(points, dtype=np.float64)
    except (TypeError, ValueError):  # not numbers: the uncached path names the field
        arr = None
    if arr is None or arr.ndim != 2 or arr.size > _CACHED_POINTS:
        return _build_reference(
            points, max_spacing=max_spacing, angle_per_sample=angle_per_sample, field_name=field_name
        )
    return _kept_reference(arr.tobytes(), arr.shape, float(max_spacing), float(angle_per_sample), field_name)


#: polylines of at most this many numbers are kept by :func:`build_reference`
_CACHED_POINTS = 200_000


@functools.lru_cache(maxsize=4)
def _kept_reference(
    values: bytes, shape: tuple[int, ...], max_spacing: float, angle_per_sample: float, field_name: str
) -> ReferenceLine:
    """:func:`_build_reference` of the polyline whose float64 values are ``values`` in ``shape``."""
    points = np.frombuffer(values, dtype=np.float64).reshape(shape)
    return _build_reference(
        points, max_spacing=max_spacing, angle_per_sample=angle_per_sample, field_name=field_name
    )


def _build_reference(
    points: ArrayLike, *, max_spacing: float, angle_per_sample: float, field_name: str
) -> ReferenceLine:
    """:func:`build_reference`, built."""
    if not (np.isfinite(max_spacing) and max_spacing > 0):
        raise ValueError("max_spacing must be positive")
    pts, index = clean_polyline(points, field_name=field_name)
    chord = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    u_knots = np.concatenate(([0.0], np.cumsum(chord)))
    total_chord = float(u_knots[-1])

    # Two points: the exact curve is the segment itself.
    spline = None if pts.shape[0] == 2 else CubicSpline(u_knots, pts, axis=0, bc_type="not-a-knot")

    # Arc length s(u) and curvature κ(u) on a fine grid (Simpson per grid interval).
    resolution = max(float(np.clip(total_chord / 40_000, 0.02, 0.1)), total_chord / MAX_SAMPLES)
    u_fine = _fine_grid(u_knots, resolution)
    if spline is None:
        direction = (pts[1] - pts[0]) / total_chord
        s_fine = u_fine.copy()
        kappa_max = 0.0
    else:
        d1 = spline(u_fine, 1)
        mid = 0.5 * (u_fine[:-1] + u_fine[1:])
        speed = np.linalg.norm(d1, axis=1)
        speed_mid = np.linalg.norm(spline(mid, 1), axis=1)
        if np.any(speed < 1e-9):
            raise InvalidReferenceError("the fitted curve has a cusp; the points fold back", field=field_name)
        ds = np.diff(u_fine) / 6.0 * (speed[:-1] + 4.0 * speed_mid + speed[1:])
        s_fine = np.concatenate(([0.0], np.cumsum(ds)))
        d2 = spline(u_fine, 2)
        kappa_fine = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / speed**3
        kappa_max = float(np.max(np.abs(kappa_fine)))

    length = float(s_fine[-1])
    spacing = max_spacing
    if kappa_max > 0:
        spacing = min(spacing, angle_per_sample / kappa_max)
    spacing = max(spacing, MIN_SPACING, length / (MAX_SAMPLES - 1))
    n_seg = max(1, int(np.ceil(length / spacing - 1e-9)))
    spacing = length / n_seg
    s = np.linspace(0.0, length, n_seg + 1)
    s[-1] = length

    if spline is None:
        samples = pts[0] + np.outer(s, direction)
        heading = np.full(s.shape, np.arctan2(direction[1], direction[0]))
        kappa = np.zeros_like(s)
    else:
        u = np.interp(s, s_fine, u_fine)
        samples = spline(u)
        d1 = spline(u, 1)
        d2 = spline(u, 2)
        sp = np.linalg.norm(d1, axis=1)
        heading = np.arctan2(d1[:, 1], d1[:, 0])
        kappa = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / sp**3

    input_s = np.interp(u_knots, u_fine, s_fine)
    return _assemble(samples, s, heading, kappa, spacing, input_s, index, field_name=field_name)


def _assemble(
    samples: FloatArray,
    s: FloatArray,
    heading: FloatArray,
    kappa: FloatArray,
    spacing: float,
    input_s: FloatArray,
    input_index: NDArray[np.intp],
    *,
    field_name: str = "reference_line",
) -> ReferenceLine:
    """Derive segment directions and bisector slopes, freeze the arrays, build the k-d tree."""
    seg = np.diff(samples, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    if not np.all(np.isfinite(samples)) or np.any(seg_len <= 0):
        raise InvalidReferenceError("the fitted curve has coincident samples", field=field_name)
    seg_dir = seg / seg_len[:, None]
    if seg_dir.shape[0] > 1:
        a, b = seg_dir[:-1], seg_dir[1:]
        turn = np.abs(np.arctan2(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0], np.einsum("ij,ij->i", a, b)))
        if np.max(turn) > MAX_SAMPLE_TURN:
            where = float(s[int(np.argmax(turn)) + 1])
            raise InvalidReferenceError(
                f"the smooth curve through the points loops or folds back near s = {where:.1f} m; "
                "add points or smooth the line there",
                field=field_name,
            )
    m = samples.shape[0]
    k_start = np.zeros(m - 1)
    k_end = np.zeros(m - 1)
    if m > 2:
        # Angular bisector at inner vertex i is normal to the mean tangent t_i = e_{i-1} + e_i.
        tangent = seg_dir[:-1] + seg_dir[1:]
        tangent /= np.linalg.norm(tangent, axis=1)[:, None]
        bis = np.column_stack((-tangent[:, 1], tangent[:, 0]))  # left normal of the mean tangent

        def slope(b: FloatArray, e: FloatArray) -> FloatArray:
            n = np.column_stack((-e[:, 1], e[:, 0]))
            return np.einsum("ij,ij->i", b, e) / np.einsum("ij,ij->i", b, n)

        k_end[:-1] = slope(bis, seg_dir[:-1])  # vertex i+1 seen from segment i
        k_start[1:] = slope(bis, seg_dir[1:])  # vertex i+1 seen from segment i+1
    table = np.column_stack((samples[:-1], seg_dir, seg_len, k_start, k_end))
    ahead = np.vstack((seg_dir[:1], seg_dir[:-1] + seg_dir[1:], seg_dir[-1:]))
    sample_table = np.column_stack((samples, ahead))
    arrays: tuple[np.ndarray, ...] = (samples, s, heading, kappa, seg_dir, seg_len, k_start, k_end)
    for a in (*arrays, input_s, input_index, table, sample_table):
        a.setflags(write=False)
    return ReferenceLine(
        points=samples,
        s=s,
        heading=heading,
        kappa=kappa,
        spacing=float(spacing),
        seg_dir=seg_dir,
        seg_len=seg_len,
        k_start=k_start,
        k_end=k_end,
        input_s=input_s,
        input_index=input_index,
        tree=cKDTree(samples),
        segment_table=table,
        sample_table=sample_table,
    )


def widths_at(width: float | ArrayLike, ref: ReferenceLine, s: ArrayLike, *, field_name: str) -> FloatArray:
    """Lane width [m] at arc lengths ``s``: a scalar, or one value per input point interpolated by s.

    ``width`` given per point has one value per point of the user's original polyline (duplicates
    included); values of dropped duplicates are ignored. Too few of them (or not a 1-D array) raise
    :class:`InvalidInputError` naming ``field_name``.
    """
    s_arr = np.asarray(s, dtype=float)
    w = np.asarray(width, dtype=float)
    if w.ndim == 0:
        return np.full(s_arr.shape, float(w))
    if w.ndim != 1 or w.shape[0] <= ref.input_index[-1]:
        raise InvalidInputError(
            f"has shape {w.shape}: give one width per reference point or a single number", field=field_name
        )
    return np.interp(s_arr, ref.input_s, w[ref.input_index])
