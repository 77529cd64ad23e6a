"""Tests of :func:`planner.reference.build_reference`: the uniformly sampled reference of TransF-κ.

The paper (Sun et al., Sec. III-C) asks of the sampled polygonal line: identical spacing between
adjacent samples, spacing much smaller than ``1/κ`` and at most 10° of heading change between
adjacent samples. These must hold whatever the user sent (exact 0.5 m samples, irregular survey
points, coarse 5 m highway points, hairpins), and the curvature of the fitted curve must match the
analytic curvature of the road the points came from.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import fresnel

from planner import roads
from planner.errors import InvalidReferenceError
from planner.reference import DEFAULT_ANGLE_PER_SAMPLE, DEFAULT_MAX_SPACING, build_reference

TEN_DEGREES = math.radians(10.0)


# --------------------------------------------------------------------------- exact curves


def arc_xy(radius: float, sign: float, s: np.ndarray) -> np.ndarray:
    """Points at arc length ``s`` of the arc of ``roads.arc`` (left turn for sign > 0)."""
    phi = np.asarray(s, dtype=float) / radius
    return np.column_stack((radius * np.sin(phi), sign * radius * (1.0 - np.cos(phi))))


def clothoid_xy(rate: float, s: np.ndarray) -> np.ndarray:
    """Points at arc length ``s`` of the clothoid ``κ(s) = rate·s`` of ``roads.clothoid``."""
    scale = math.sqrt(math.pi / abs(rate))
    fs, fc = fresnel(np.asarray(s, dtype=float) / scale)
    return np.column_stack((scale * fc, math.copysign(1.0, rate) * scale * fs))


def irregular_s(length: float, rng: np.random.Generator, lo: float = 0.1, hi: float = 3.0):
    """Arc lengths 0 … length with random gaps in [lo, hi] (the last gap may be shorter)."""
    s = [0.0]
    while s[-1] + hi < length:
        s.append(s[-1] + rng.uniform(lo, hi))
    if length - s[-1] < lo:
        s.pop()
    s.append(length)
    return np.asarray(s)


def chord_turns(points: np.ndarray) -> np.ndarray:
    """Heading change between consecutive chords of a polyline [rad], computed from scratch."""
    seg = np.diff(points, axis=0)
    a, b = seg[:-1], seg[1:]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    dot = np.einsum("ij,ij->i", a, b)
    return np.abs(np.arctan2(cross, dot))


def _irregular_arc(radius: float, angle: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return arc_xy(radius, math.copysign(1.0, angle), irregular_s(radius * abs(angle), rng))


def _irregular_clothoid(length: float, rate: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return clothoid_xy(rate, irregular_s(length, rng))


#: name -> polyline, covering exact, irregular, coarse and hairpin inputs
ROADS = {
    "straight": roads.straight(60.0, heading=0.7),
    "arc_left_r20": roads.arc(20.0, 2.0),
    "arc_right_r20": roads.arc(20.0, -2.0),
    "arc_left_r6_half": roads.arc(6.0, math.pi),
    "clothoid_left": roads.clothoid(60.0, 0.002),
    "clothoid_right": roads.clothoid(60.0, -0.002),
    "u_turn": roads.u_turn(),
    "u_turn_coarse_2m": roads.u_turn(8.0, 40.0, step=2.0),
    "hairpin_r3_coarse": roads.u_turn(3.0, 10.0, step=3.0),
    "arc_r60_coarse_5m": roads.arc(60.0, 1.2, step=5.0),
    "arc_r50_right_coarse_5m": roads.arc(50.0, -1.5, step=5.0),
    "clothoid_coarse_5m": roads.clothoid(120.0, 0.00015, step=5.0),
    "arc_r20_irregular": _irregular_arc(20.0, 2.0, seed=1),
    "arc_r10_right_irregular": _irregular_arc(10.0, -2.5, seed=2),
    "clothoid_irregular": _irregular_clothoid(80.0, -0.0015, seed=3),
}


@pytest.fixture(scope="module", params=sorted(ROADS))
def road(request):
    pts = ROADS[request.param]
    return request.param, pts, build_reference(pts)


# --------------------------------------------------------------------------- sampling conditions


def test_arc_length_steps_are_identical(road):
    name, _, ref = road
    steps = np.diff(ref.s)
    assert ref.s[0] == 0.0
    assert ref.s[-1] == pytest.approx(ref.length, abs=0.0)
    np.testing.assert_allclose(steps, ref.spacing, rtol=1e-12, atol=0.0, err_msg=name)
    np.testing.assert_allclose(ref.s, np.arange(ref.size) * ref.spacing, rtol=1e-12, atol=1e-12)
    assert ref.spacing * (ref.size - 1) == pytest.approx(ref.length, rel=1e-12)


def test_chord_lengths_equal_the_spacing(road):
    name, _, ref = road
    # chord = arc · (1 − (Δκ)²/24 + …) with Δκ ≤ 0.05: the chords are equal to ~1e-4
    chords = np.linalg.norm(np.diff(ref.points, axis=0), axis=1)
    np.testing.assert_allclose(ref.seg_len, chords, rtol=1e-12)
    assert np.all(chords <= ref.spacing * (1.0 + 1e-6)), name
    assert np.all(chords >= ref.spacing * (1.0 - 2e-4)), name
    assert chords.max() - chords.min() <= 2e-4 * ref.spacing, name


def test_spacing_is_much_smaller_than_the_radius(road):
    name, _, ref = road
    kappa_max = float(np.max(np.abs(ref.kappa)))
    assert 0.0 < ref.spacing <= DEFAULT_MAX_SPACING + 1e-12, name
    assert ref.spacing * kappa_max <= DEFAULT_ANGLE_PER_SAMPLE * 1.01, name


def test_heading_change_per_sample_is_at_most_ten_degrees(road):
    name, pts, ref = road
    turns = chord_turns(ref.points)
    assert turns.max() <= TEN_DEGREES, name
    assert ref.max_turn_per_sample == pytest.approx(turns.max(), abs=1e-12)
    # well under the paper's 10°: about angle_per_sample
    assert ref.max_turn_per_sample <= 1.2 * DEFAULT_ANGLE_PER_SAMPLE, name
    # the smooth headings of adjacent samples differ by little as well
    assert np.abs(np.diff(np.unwrap(ref.heading))).max() <= TEN_DEGREES, name
    # the coarse inputs really needed repairing
    if pts.shape[0] > 2 and "coarse" in name:
        assert ref.size > pts.shape[0]


def test_samples_lie_on_the_input_curve_and_keep_its_ends(road):
    name, pts, ref = road
    np.testing.assert_allclose(ref.points[0], pts[0], atol=1e-9)
    np.testing.assert_allclose(ref.points[-1], pts[-1], atol=1e-9)
    np.testing.assert_allclose(ref.input_s[[0, -1]], [0.0, ref.length], atol=1e-9)
    assert np.all(np.diff(ref.input_s) > 0.0), name


def test_heading_is_tangent_to_the_samples(road):
    name, _, ref = road
    # the chord L_{i-1} → L_{i+1} is parallel to the tangent at L_i up to O(Δ²κ'), a small
    # fraction of the heading change per sample even where κ jumps (line → arc of the U-turn)
    chord = ref.points[2:] - ref.points[:-2]
    chord_heading = np.arctan2(chord[:, 1], chord[:, 0])
    diff = np.angle(np.exp(1j * (chord_heading - ref.heading[1:-1])))
    assert np.abs(diff).max() <= 0.1 * DEFAULT_ANGLE_PER_SAMPLE, name


def test_arrays_are_read_only():
    ref = build_reference(ROADS["arc_left_r20"])
    with pytest.raises(ValueError):
        ref.points[0, 0] = 1.0
    with pytest.raises(ValueError):
        ref.kappa[0] = 1.0
    with pytest.raises(ValueError):
        ref.unwrapped_heading[0] = 1.0
    with pytest.raises(ValueError):
        ref.kappa_slope[0] = 1.0


def test_cached_heading_and_curvature_slope_are_what_they_stand_for():
    ref = build_reference(ROADS["u_turn"])  # the heading passes ±π: unwrapped, it must not jump
    assert np.array_equal(ref.unwrapped_heading, np.unwrap(ref.heading))
    assert np.max(np.abs(np.diff(ref.unwrapped_heading))) < 0.2
    assert ref.unwrapped_heading is ref.unwrapped_heading  # computed once
    assert np.array_equal(ref.kappa_slope, np.gradient(ref.kappa, ref.s))
    s = np.linspace(0.0, ref.length, 57)
    assert np.array_equal(ref.heading_at(s), np.interp(s, ref.s, np.unwrap(ref.heading)))


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(3, 25),
    max_turn_deg=st.floats(0.0, 60.0),
    lo=st.floats(0.2, 2.0),
    hi_extra=st.floats(0.0, 5.0),
)
def test_random_polylines_satisfy_the_sampling_conditions(seed, n, max_turn_deg, lo, hi_extra):
    rng = np.random.default_rng(seed)
    steps = rng.uniform(lo, lo + hi_extra, n - 1)
    turns = np.radians(rng.uniform(-max_turn_deg, max_turn_deg, n - 1))
    heading = rng.uniform(-math.pi, math.pi) + np.cumsum(turns)
    pts = np.vstack(
        ([0.0, 0.0], np.cumsum(steps[:, None] * np.column_stack((np.cos(heading), np.sin(heading))), axis=0))
    )
    ref = build_reference(pts)
    np.testing.assert_allclose(np.diff(ref.s), ref.spacing, rtol=1e-12)
    assert chord_turns(ref.points).max(initial=0.0) <= TEN_DEGREES
    kappa_max = float(np.max(np.abs(ref.kappa)))
    assert ref.spacing * kappa_max <= DEFAULT_ANGLE_PER_SAMPLE * 1.01 or ref.spacing <= 0.01 + 1e-12
    # interpolating: every input point is on the reference at its input_s (the arc-length table is
    # accurate to well under a millimetre, which matters only at the 1 cm spacing of sharp turns)
    idx = np.clip(np.round(ref.input_s / ref.spacing).astype(int), 0, ref.size - 1)
    assert np.all(np.linalg.norm(ref.points[idx] - pts, axis=1) <= 0.5 * ref.spacing + 1e-3)
    assert ref.length >= np.sum(steps) * (1.0 - 1e-9)


# --------------------------------------------------------------------------- curvature


@pytest.mark.parametrize("radius", [6.0, 20.0, 100.0])
@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_arc_curvature_is_one_over_radius(radius, sign):
    angle = sign * min(2.0, 150.0 / radius)
    ref = build_reference(roads.arc(radius, angle))
    assert ref.length == pytest.approx(radius * abs(angle), rel=1e-6)
    away = (ref.s > 3.0) & (ref.s < ref.length - 3.0)
    assert away.sum() > 10
    np.testing.assert_allclose(ref.kappa[away], sign / radius, rtol=1e-3)
    np.testing.assert_allclose(ref.kappa_at(ref.s[away]), sign / radius, rtol=1e-3)
    # everywhere (ends included) the sign and rough size are right
    np.testing.assert_allclose(ref.kappa, sign / radius, rtol=2e-2)
    # heading θ(s) = θ₀ + s/R
    np.testing.assert_allclose(
        np.unwrap(ref.heading), sign * ref.s / radius, atol=1e-3 / radius * ref.length + 1e-6
    )
    np.testing.assert_allclose(ref.heading_at(ref.s), np.unwrap(ref.heading), atol=1e-12)
    # samples on the circle, at their own arc length
    np.testing.assert_allclose(ref.points, arc_xy(radius, sign, ref.s), atol=1e-4)


@pytest.mark.parametrize(
    ("name", "radius", "sign", "rtol"),
    [
        ("arc_r60_coarse_5m", 60.0, 1.0, 2e-3),
        ("arc_r50_right_coarse_5m", 50.0, -1.0, 3e-3),
        ("arc_r20_irregular", 20.0, 1.0, 1e-2),
        ("arc_r10_right_irregular", 10.0, -1.0, 2e-2),
    ],
)
def test_curvature_of_coarse_and_irregular_arcs(name, radius, sign, rtol):
    pts = ROADS[name]
    ref = build_reference(pts)
    away = (ref.s > 3.0) & (ref.s < ref.length - 3.0)
    np.testing.assert_allclose(ref.kappa[away], sign / radius, rtol=rtol)
    np.testing.assert_allclose(ref.points, arc_xy(radius, sign, ref.s), atol=0.02)
    # input points keep their arc length
    exact_s = radius * np.abs(np.arctan2(pts[:, 0], radius - sign * pts[:, 1]))
    np.testing.assert_allclose(ref.input_s, exact_s, atol=0.01)


@pytest.mark.parametrize(
    ("length", "rate", "step", "atol"),
    [
        (60.0, 0.002, 0.5, 1e-4),
        (60.0, -0.002, 0.5, 1e-4),
        (40.0, 0.01, 0.5, 2e-3),
        (120.0, 0.00015, 5.0, 1e-4),
        (120.0, -0.00015, 5.0, 1e-4),
    ],
)
def test_clothoid_curvature_is_linear(length, rate, step, atol):
    ref = build_reference(roads.clothoid(length, rate, step=step))
    assert ref.length == pytest.approx(length, abs=1e-4)
    away = (ref.s > 3.0) & (ref.s < ref.length - 3.0)
    np.testing.assert_allclose(ref.kappa[away], rate * ref.s[away], atol=atol)
    slope, _ = np.polyfit(ref.s[away], ref.kappa[away], 1)
    assert slope == pytest.approx(rate, rel=1e-2)
    np.testing.assert_allclose(ref.points, clothoid_xy(rate, ref.s), atol=1e-3)


def test_clothoid_from_irregular_points_is_repaired():
    ref = build_reference(ROADS["clothoid_irregular"])
    away = (ref.s > 3.0) & (ref.s < ref.length - 3.0)
    np.testing.assert_allclose(ref.kappa[away], -0.0015 * ref.s[away], atol=2e-3)
    np.testing.assert_allclose(ref.points, clothoid_xy(-0.0015, ref.s), atol=0.02)


def test_kappa_at_interpolates_and_holds_beyond_the_ends():
    ref = build_reference(ROADS["clothoid_left"])
    mid = 0.5 * (ref.s[10] + ref.s[11])
    assert ref.kappa_at(mid) == pytest.approx(0.5 * (ref.kappa[10] + ref.kappa[11]))
    assert ref.kappa_at(-5.0) == ref.kappa[0]
    assert ref.kappa_at(ref.length + 5.0) == ref.kappa[-1]


# --------------------------------------------------------------------------- spacing options


@pytest.mark.parametrize(("max_spacing", "angle"), [(0.25, 0.05), (1.0, 0.02), (2.0, 0.1)])
def test_spacing_follows_the_options(max_spacing, angle):
    ref = build_reference(roads.arc(15.0, 2.5), max_spacing=max_spacing, angle_per_sample=angle)
    assert ref.spacing <= max_spacing + 1e-12
    assert ref.spacing * np.abs(ref.kappa).max() <= angle * 1.01
    assert ref.max_turn_per_sample <= 1.2 * angle
    # Δ is the largest spacing that divides the length and satisfies both limits
    limit = min(max_spacing, angle * 15.0)
    assert ref.spacing >= limit * (ref.size - 2) / (ref.size - 1) * 0.99


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf])
def test_bad_max_spacing_is_rejected(bad):
    with pytest.raises(ValueError):
        build_reference(roads.straight(10.0), max_spacing=bad)


# --------------------------------------------------------------------------- special inputs


@pytest.mark.parametrize(
    "pts",
    [
        [[0.0, 0.0], [30.0, 40.0]],
        [[5.0, -2.0], [-7.0, 3.0]],
        [[0.0, 0.0], [0.3, 0.0]],  # shorter than one spacing: a single segment
        [[1.0, 1.0], [1.0, 1.0], [4.0, 5.0], [4.0, 5.0]],  # two distinct points after cleaning
    ],
)
def test_two_points_give_a_straight_line(pts):
    arr = np.asarray(pts, dtype=float)
    a, b = arr[0], arr[-1]
    ref = build_reference(pts)
    direction = (b - a) / np.linalg.norm(b - a)
    assert ref.length == pytest.approx(np.linalg.norm(b - a), rel=1e-12)
    np.testing.assert_allclose(ref.points[0], a, atol=1e-12)
    np.testing.assert_allclose(ref.points[-1], b, atol=1e-12)
    np.testing.assert_allclose(ref.points, a + np.outer(ref.s, direction), atol=1e-12)
    np.testing.assert_array_equal(ref.kappa, 0.0)
    np.testing.assert_allclose(ref.heading, math.atan2(direction[1], direction[0]), atol=1e-12)
    np.testing.assert_allclose(ref.seg_dir, np.broadcast_to(direction, ref.seg_dir.shape))
    np.testing.assert_allclose(ref.k_start, 0.0, atol=1e-12)
    np.testing.assert_allclose(ref.k_end, 0.0, atol=1e-12)
    assert ref.max_turn_per_sample == pytest.approx(0.0, abs=1e-12)
    assert ref.spacing <= DEFAULT_MAX_SPACING


def test_collinear_points_give_a_straight_line():
    x = np.array([0.0, 0.7, 3.0, 3.5, 9.0, 20.0])
    pts = np.column_stack((x, 0.5 * x + 1.0))
    ref = build_reference(pts)
    np.testing.assert_allclose(ref.kappa, 0.0, atol=1e-9)
    np.testing.assert_allclose(ref.points[:, 1], 0.5 * ref.points[:, 0] + 1.0, atol=1e-9)
    assert ref.length == pytest.approx(20.0 * math.hypot(1.0, 0.5), rel=1e-9)


def test_consecutive_duplicates_are_dropped():
    clean = roads.arc(20.0, 1.0, step=2.0)
    dup_rows = [0, 0, 1, 2, 2, 2, *range(3, clean.shape[0]), clean.shape[0] - 1]
    noisy = clean[dup_rows]
    a = build_reference(clean)
    b = build_reference(noisy)
    assert a.size == b.size
    np.testing.assert_allclose(b.points, a.points, atol=1e-12)
    np.testing.assert_allclose(b.kappa, a.kappa, atol=1e-12)
    np.testing.assert_allclose(b.input_s, a.input_s, atol=1e-12)
    # input_index points back into the caller's array, one entry per distinct point
    assert b.input_index.shape[0] == clean.shape[0]
    np.testing.assert_array_equal(noisy[b.input_index], clean)
    assert b.input_index[0] == 0 and b.input_index[1] == 2


def test_non_consecutive_repeats_are_kept():
    # a loop passes through its start again: only *consecutive* duplicates are dropped
    theta = np.linspace(0.0, 2.0 * math.pi, 41)
    pts = np.column_stack((10.0 * np.cos(theta), 10.0 * np.sin(theta)))
    ref = build_reference(pts)
    assert ref.input_index.shape[0] == 41
    assert ref.length == pytest.approx(2.0 * math.pi * 10.0, rel=1e-3)


@pytest.mark.parametrize(
    ("pts", "field"),
    [
        (np.empty((0, 2)), "reference_line"),
        ([], "reference_line"),
        ([[1.0, 2.0]], "reference_line"),
        ([[1.0, 2.0], [1.0, 2.0], [1.0, 2.0]], "reference_line"),
        ([[1.0, 2.0], [1.0, 2.0 + 1e-8]], "reference_line"),
        ([[0.0, 0.0], [1.0, 0.0], [math.nan, 1.0], [3.0, 0.0]], "reference_line.2"),
        ([[0.0, 0.0], [1.0, math.inf], [2.0, 0.0]], "reference_line.1"),
        ([[-math.inf, 0.0], [1.0, 0.0]], "reference_line.0"),
        ([0.0, 1.0, 2.0], "reference_line"),
        ([[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]], "reference_line"),
        (np.zeros((2, 2, 2)), "reference_line"),
        ([[0.0, 0.0], [1.0]], "reference_line"),
        ([["a", "b"], ["c", "d"]], "reference_line"),
        (None, "reference_line"),
        (3.0, "reference_line"),
    ],
)
def test_invalid_inputs_are_rejected_naming_the_field(pts, field):
    with pytest.raises(InvalidReferenceError) as info:
        build_reference(pts)
    assert info.value.field == field
    assert str(info.value).startswith(field + ": ")


def test_invalid_input_names_the_callers_field():
    with pytest.raises(InvalidReferenceError) as info:
        build_reference([[0.0, 0.0], [math.nan, 0.0]], field_name="lane.center")
    assert info.value.field == "lane.center.1"
    with pytest.raises(InvalidReferenceError) as info:
        build_reference([[0.0, 0.0]], field_name="lane.center")
    assert info.value.field == "lane.center"


def test_the_same_polyline_again_gets_the_reference_built_for_it() -> None:
    """A closed loop sends the same polyline every cycle: the reference built for it is kept (read-only),
    whatever container holds the values; other values or arguments get their own, and a bad polyline is
    an error every time."""
    points = [[0.0, 0.0], [10.0, 1.0], [20.0, 4.0], [30.0, 9.0]]
    first = build_reference(points)
    assert build_reference(np.array(points)) is first
    assert not first.points.flags.writeable
    moved = build_reference([[0.0, 0.0], [10.0, 1.0], [20.0, 4.0], [30.0, 9.5]])
    assert moved is not first and moved.length != first.length
    assert build_reference(points, max_spacing=0.25) is not first
    for _ in range(2):
        with pytest.raises(InvalidReferenceError):
            build_reference([[0.0, 0.0], [float("nan"), 1.0]])
