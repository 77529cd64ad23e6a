"""Tests of TransF-κ (:mod:`planner.frenet`): Cartesian ⇄ Frenet on the sampled reference.

Properties checked (Sun et al., Algorithms 1–3):

* round trips Cartesian → Frenet → Cartesian and Frenet → Cartesian → Frenet;
* continuity of ``(s, d)`` for small moves away from the ``κ·d ≥ 1`` region;
* the biggest-index rule on ties of the nearest sample (U-turn centre, equidistant points);
* strictly increasing ``s`` along offset lines with ``κ·d < 1``;
* agreement with the exact Frenet coordinates of lines, arcs and clothoids, also when the input
  polyline is irregular or coarse;
* end segments extended as rays.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
import shapely
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq
from scipy.special import fresnel

from planner import roads
from planner.frenet import TIE_ABS, TIE_REL, to_cartesian, to_frenet
from planner.reference import ReferenceLine, build_reference

# --------------------------------------------------------------------------- exact curves


def irregular_s(length: float, rng: np.random.Generator, lo: float = 0.1, hi: float = 3.0):
    """Arc lengths 0 … length with random gaps in [lo, hi] (the last gap may be shorter)."""
    s = [0.0]
    while s[-1] + hi < length:
        s.append(s[-1] + rng.uniform(lo, hi))
    if length - s[-1] < lo:
        s.pop()
    s.append(length)
    return np.asarray(s)


def sample_s(length: float, mode: str, seed: int = 0) -> np.ndarray:
    """Arc lengths at which the input polyline samples the exact curve."""
    if mode == "exact":
        return np.linspace(0.0, length, math.ceil(length / 0.5) + 1)
    if mode == "coarse":
        return np.linspace(0.0, length, math.ceil(length / 5.0) + 1)
    if mode == "irregular":
        return irregular_s(length, np.random.default_rng(seed))
    raise ValueError(mode)


class Line:
    def __init__(self, heading: float, origin=(0.0, 0.0)):
        self.e = np.array([math.cos(heading), math.sin(heading)])
        self.n = np.array([-self.e[1], self.e[0]])
        self.o = np.asarray(origin, dtype=float)

    def xy(self, s, d=0.0):
        s, d = np.broadcast_arrays(np.asarray(s, float), np.asarray(d, float))
        return self.o + s[:, None] * self.e + d[:, None] * self.n

    def frenet(self, p):
        rel = np.asarray(p, float) - self.o
        return rel @ self.e, rel @ self.n


class Arc:
    """The arc of ``roads.arc``: from the origin heading +x, centre ``(0, sign·R)``."""

    def __init__(self, radius: float, sign: float):
        self.r = radius
        self.sign = sign
        self.c = np.array([0.0, sign * radius])

    def xy(self, s, d=0.0):
        s, d = np.broadcast_arrays(np.asarray(s, float), np.asarray(d, float))
        phi = s / self.r
        rho = self.r - self.sign * d
        return self.c + rho[:, None] * np.column_stack((np.sin(phi), -self.sign * np.cos(phi)))

    def frenet(self, p):
        """Exact Frenet coordinates: polar angle about the centre, distance to the circle."""
        rel = np.asarray(p, float) - self.c
        phi = np.arctan2(rel[:, 0], -self.sign * rel[:, 1])
        phi = np.mod(phi + 0.5 * math.pi, 2.0 * math.pi) - 0.5 * math.pi  # in [−π/2, 3π/2)
        rho = np.hypot(rel[:, 0], rel[:, 1])
        return self.r * phi, self.sign * (self.r - rho)


class Clothoid:
    """The clothoid of ``roads.clothoid``: ``κ(s) = rate·s`` from the origin heading +x."""

    def __init__(self, rate: float):
        self.rate = rate
        self.scale = math.sqrt(math.pi / abs(rate))
        self.sgn = math.copysign(1.0, rate)

    def r(self, s):
        fs, fc = fresnel(np.asarray(s, float) / self.scale)
        return np.stack((self.scale * fc, self.sgn * self.scale * fs), axis=-1)

    def tangent(self, s):
        theta = 0.5 * self.rate * np.asarray(s, float) ** 2
        return np.stack((np.cos(theta), np.sin(theta)), axis=-1)

    def normal(self, s):
        t = self.tangent(s)
        return np.stack((-t[..., 1], t[..., 0]), axis=-1)

    def xy(self, s, d=0.0):
        s, d = np.broadcast_arrays(np.asarray(s, float), np.asarray(d, float))
        return self.r(s) + d[:, None] * self.normal(s)

    def frenet_one(self, p, length: float):
        """Nearest point of the exact curve on [0, length], solved to ~1e-12 m; None if not unique."""
        grid = np.linspace(0.0, length, math.ceil(length / 0.02) + 1)
        dist = np.linalg.norm(self.r(grid) - p, axis=1)
        i = int(np.argmin(dist))
        if i == 0 or i == grid.size - 1:
            return None
        # any other local minimum nearly as close makes the nearest point ambiguous
        inner = np.flatnonzero((dist[1:-1] <= dist[:-2]) & (dist[1:-1] <= dist[2:])) + 1
        others = inner[np.abs(grid[inner] - grid[i]) > 1.0]
        if others.size and dist[others].min() < dist[i] + 0.05:
            return None

        def g(t):
            return float(np.dot(p - self.r(t), self.tangent(t)))

        t = brentq(g, grid[i - 1], grid[i + 1], xtol=1e-13, rtol=1e-15)
        return t, float(np.dot(p - self.r(t), self.normal(t)))


def kappa_max(ref: ReferenceLine) -> float:
    return float(np.max(np.abs(ref.kappa)))


def tube(ref: ReferenceLine, cap: float = 50.0) -> float:
    """Half width 0.5/κ_max of the region where the nearest point of the curve is unique."""
    k = kappa_max(ref)
    return min(0.5 / k, cap) if k > 0 else cap


# --------------------------------------------------------------------------- road catalogue


ROAD_POINTS = {
    "straight": lambda: roads.straight(60.0, heading=-0.4),
    "arc_left": lambda: roads.arc(20.0, 2.0),
    "arc_right": lambda: roads.arc(20.0, -2.0),
    "half_circle_r10": lambda: roads.arc(10.0, math.pi),
    "clothoid_left": lambda: roads.clothoid(60.0, 0.002),
    "clothoid_right": lambda: roads.clothoid(60.0, -0.002),
    "u_turn": lambda: roads.u_turn(),
    "u_turn_demo": lambda: roads.u_turn(8.0, 40.0, step=2.0),
    "hairpin_r3": lambda: roads.u_turn(3.0, 10.0, step=0.25),
    "arc_coarse_5m": lambda: roads.arc(60.0, 1.2, step=5.0),
    "arc_irregular": lambda: Arc(15.0, -1.0).xy(sample_s(15.0 * 2.2, "irregular", 7)),
}
ROAD_NAMES = sorted(ROAD_POINTS)


@functools.cache
def road_ref(name: str) -> ReferenceLine:
    return build_reference(ROAD_POINTS[name]())


@functools.cache
def arc_ref(radius: float, angle: float, mode: str = "exact", seed: int = 0) -> ReferenceLine:
    arc = Arc(radius, math.copysign(1.0, angle))
    return build_reference(arc.xy(sample_s(radius * abs(angle), mode, seed)))


def box(ref: ReferenceLine, margin: float = 30.0) -> tuple[np.ndarray, np.ndarray]:
    return ref.points.min(axis=0) - margin, ref.points.max(axis=0) + margin


def local_kappa(ref: ReferenceLine, seg: np.ndarray) -> np.ndarray:
    """Signed curvature of a segment: the larger in size of its two end samples."""
    a, b = ref.kappa[seg], ref.kappa[seg + 1]
    return np.where(np.abs(a) >= np.abs(b), a, b)


def distance_to_polyline(ref: ReferenceLine, pts: np.ndarray) -> np.ndarray:
    line = shapely.LineString(ref.points)
    return shapely.distance(line, shapely.points(np.asarray(pts)))


unit = st.floats(0.0, 1.0)


# --------------------------------------------------------------------------- round trips


@settings(max_examples=150, deadline=None)
@given(
    name=st.sampled_from(ROAD_NAMES),
    fractions=st.lists(st.tuples(unit, unit), min_size=1, max_size=40),
)
def test_cartesian_frenet_cartesian_round_trip(name, fractions):
    ref = road_ref(name)
    lo, hi = box(ref)
    pts = lo + np.asarray(fractions) * (hi - lo)
    fp = to_frenet(ref, pts)
    assert fp.s.shape == fp.d.shape == fp.folded.shape == (pts.shape[0],)
    back = to_cartesian(ref, fp.s, fp.d)
    err = np.linalg.norm(back - pts, axis=1)
    assert np.all(err[~fp.folded] <= 1e-9), err[~fp.folded].max()
    # folded points only just beyond a centre of curvature: κ·d ≥ ~1 on the turn's inner side
    kd = local_kappa(ref, fp.segment) * fp.d
    assert np.all(kd[fp.folded] >= 0.9)


@pytest.mark.parametrize("name", ROAD_NAMES)
def test_folded_points_are_rare_and_near_centres_of_curvature(name):
    ref = road_ref(name)
    rng = np.random.default_rng(11)
    lo, hi = box(ref)
    pts = rng.uniform(lo, hi, size=(20_000, 2))
    fp = to_frenet(ref, pts)
    assert fp.folded.mean() <= 0.01
    kd = local_kappa(ref, fp.segment) * fp.d
    assert np.all(kd[fp.folded] >= 0.9)
    err = np.linalg.norm(to_cartesian(ref, fp.s, fp.d) - pts, axis=1)
    assert np.all(err[~fp.folded] <= 1e-9)
    # every point of the tube |d| < 0.5/κ_max comes back, and there is no fold at all
    in_tube = distance_to_polyline(ref, pts) < tube(ref)
    assert in_tube.sum() > 100
    assert not fp.folded[in_tube].any()


def test_folds_happen_only_beyond_the_centre_of_a_u_turn():
    ref = road_ref("u_turn")
    centre = np.array([0.0, 6.0])
    rng = np.random.default_rng(5)
    pts = centre + rng.uniform(-1.5, 1.5, size=(20_000, 2))
    fp = to_frenet(ref, pts)
    assert fp.folded.any()  # the fold region exists …
    near = np.linalg.norm(pts[fp.folded] - centre, axis=1)
    assert near.max() <= 0.5  # … and is a small neighbourhood of the centre
    err = np.linalg.norm(to_cartesian(ref, fp.s, fp.d) - pts, axis=1)
    assert np.all(err[~fp.folded] <= 1e-9)


@pytest.mark.parametrize("name", ROAD_NAMES)
def test_points_of_the_tube_on_bisectors_are_not_folded(name):
    # s = s_i puts the point on the angular bisector at L_i; |d| < 0.5/κ_max is far from any
    # centre of curvature, so nothing there may be reported as folded
    ref = road_ref(name)
    half = tube(ref)
    s = np.concatenate([ref.s, 0.5 * (ref.s[1:] + ref.s[:-1])])
    for frac in (0.0, 0.1, -0.1, 0.45, -0.45, 0.99, -0.99):
        d = np.full_like(s, frac * half)
        fp = to_frenet(ref, to_cartesian(ref, s, d))
        np.testing.assert_allclose(fp.s, s, atol=1e-9)
        np.testing.assert_allclose(fp.d, d, atol=1e-9)
        assert not fp.folded.any(), (frac, s[fp.folded][:5], fp.segment[fp.folded][:5])


def _s_strategy(draw, ref: ReferenceLine) -> float:
    """Arc length in [0, length]; often exactly a sample or a segment midpoint (bisectors)."""
    kind = draw(st.sampled_from(["uniform", "sample", "mid", "end"]))
    if kind == "uniform":
        return draw(unit) * ref.length
    i = draw(st.integers(0, ref.size - 2))
    if kind == "sample":
        return float(ref.s[i])
    if kind == "mid":
        return float(0.5 * (ref.s[i] + ref.s[i + 1]))
    return draw(st.sampled_from([0.0, float(ref.length), float(ref.s[1]), float(ref.s[-2])]))


@st.composite
def tube_frenet(draw, names=tuple(ROAD_NAMES)):
    name = draw(st.sampled_from(names))
    ref = road_ref(name)
    s = _s_strategy(draw, ref)
    d = draw(st.floats(-0.999, 0.999)) * tube(ref, cap=100.0)
    return name, s, d


@settings(max_examples=200, deadline=None)
@given(sample=tube_frenet())
def test_frenet_cartesian_frenet_round_trip(sample):
    name, s, d = sample
    ref = road_ref(name)
    p = to_cartesian(ref, [s], [d])
    assert p.shape == (1, 2)
    fp = to_frenet(ref, p)
    assert abs(fp.s[0] - s) <= 1e-9
    assert abs(fp.d[0] - d) <= 1e-9


@pytest.mark.parametrize("name", ROAD_NAMES)
def test_samples_map_to_their_arc_length(name):
    ref = road_ref(name)
    fp = to_frenet(ref, ref.points)
    np.testing.assert_allclose(fp.s, ref.s, atol=1e-9)
    np.testing.assert_allclose(fp.d, 0.0, atol=1e-9)
    np.testing.assert_allclose(to_cartesian(ref, ref.s, 0.0), ref.points, atol=1e-9)


def test_shapes_and_single_points():
    ref = road_ref("arc_left")
    fp = to_frenet(ref, np.array([3.0, 1.0]))
    assert fp.s.shape == (1,)
    grid = to_cartesian(ref, np.full((3, 4), 5.0), np.linspace(-1, 1, 4))
    assert grid.shape == (3, 4, 2)
    np.testing.assert_allclose(grid[0], grid[2])
    with pytest.raises(ValueError):
        to_frenet(ref, np.zeros((3, 3)))


# --------------------------------------------------------------------------- continuity


@settings(max_examples=200, deadline=None)
@given(sample=tube_frenet(), angle=st.floats(0.0, 2.0 * math.pi), k=st.floats(0.0, 0.98))
def test_small_moves_change_s_and_d_little(sample, angle, k):
    name, s, d = sample
    ref = road_ref(name)
    half = tube(ref)
    d = float(np.clip(d, -half, half)) * k
    h = 1e-4
    p = to_cartesian(ref, [s], [d])
    q = p + h * np.array([[math.cos(angle), math.sin(angle)]])
    assume(distance_to_polyline(ref, np.vstack((p, q))).max() < half)
    a, b = to_frenet(ref, p), to_frenet(ref, q)
    # |∂s/∂x| ≈ 1/(1 − κd) ≤ 2 and |∂d/∂x| ≈ 1 where κ·d < 1/2
    assert abs(b.s[0] - a.s[0]) <= 3.0 * h
    assert abs(b.d[0] - a.d[0]) <= 1.5 * h


@pytest.mark.parametrize("name", ROAD_NAMES)
def test_s_and_d_are_continuous_along_cartesian_sweeps(name):
    # straight Cartesian lines in many directions crossing the road, walked in 1e-3 m steps:
    # they cross bisectors and nearest-sample cells at all angles
    ref = road_ref(name)
    half = tube(ref, cap=15.0)
    h = 1e-3
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 2.2 * half, h)
    for _ in range(12):
        s0 = rng.uniform(0.0, ref.length)
        centre = to_cartesian(ref, [s0], [0.0])[0]
        ang = rng.uniform(0.0, math.pi)
        direction = np.array([math.cos(ang), math.sin(ang)])
        pts = centre + np.outer(t - 1.1 * half, direction)
        pts = pts[distance_to_polyline(ref, pts) < half]
        fp = to_frenet(ref, pts)
        step = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        jump = step > 1.5 * h  # the sweep may leave the tube and come back
        ds = np.abs(np.diff(fp.s))[~jump]
        dd = np.abs(np.diff(fp.d))[~jump]
        assert ds.max() <= 3.0 * h, (s0, ang, ds.max())
        assert dd.max() <= 1.5 * h, (s0, ang, dd.max())


# --------------------------------------------------------------------------- biggest index


def _u_turn_arc_end(radius: float, leg: float, step: float, ref: ReferenceLine):
    n_leg = np.arange(-leg, 0.0, step).size
    n_arc = roads.arc(radius, math.pi, step=step).shape[0]
    return ref.input_s[n_leg], ref.input_s[n_leg + n_arc - 1]


@pytest.mark.parametrize(("radius", "leg", "step"), [(6.0, 30.0, 0.5), (8.0, 40.0, 2.0), (3.0, 10.0, 0.25)])
def test_u_turn_centre_maps_to_the_arc_end(radius, leg, step):
    ref = build_reference(roads.u_turn(radius, leg, step=step))
    s_start, s_end = _u_turn_arc_end(radius, leg, step, ref)
    fp = to_frenet(ref, [[0.0, radius]])
    # all arc samples are (almost) equidistant from the centre: the last one wins
    assert abs(fp.s[0] - s_end) <= 2.5 * ref.spacing, (fp.s[0], s_start, s_end)
    assert abs(fp.nearest[0] - s_end / ref.spacing) <= 3
    assert fp.d[0] == pytest.approx(radius, rel=5e-3)


def test_half_circle_centre_maps_to_the_end():
    ref = road_ref("half_circle_r10")
    fp = to_frenet(ref, [[0.0, 10.0]])
    assert fp.nearest[0] == ref.size - 1
    assert abs(fp.s[0] - ref.length) <= 2.5 * ref.spacing
    # and the start centre-side neighbourhood is not mapped near the start
    assert fp.s[0] > 0.9 * ref.length


@settings(max_examples=100, deadline=None)
@given(
    road=st.sampled_from(["straight", "arc_left", "arc_right", "clothoid_right", "u_turn"]),
    frac=unit,
    t=st.floats(-1.0, 0.9),
)
def test_equidistant_points_pick_the_later_sample(road, frac, t):
    ref = road_ref(road)
    i = int(frac * (ref.size - 2))
    a, b = ref.points[i], ref.points[i + 1]
    normal = np.array([-ref.seg_dir[i, 1], ref.seg_dir[i, 0]])
    k = float(np.max(np.abs(ref.kappa[max(i - 3, 0) : i + 5])))
    reach = 0.9 / k if k > 0 else 40.0
    if ref.kappa[i] < 0:
        t = -t  # the inner side of a right turn is on the right
    p = 0.5 * (a + b) + t * reach * normal  # on the perpendicular bisector of L_i L_{i+1}
    dist = np.linalg.norm(ref.points - p, axis=1)
    others = np.delete(dist, [i, i + 1])
    assume(others.min() > dist[i] * (1.0 + TIE_REL) + TIE_ABS)  # exactly two nearest samples
    fp = to_frenet(ref, p[None, :])
    assert fp.nearest[0] == i + 1
    assert ref.s[i] - 1e-9 <= fp.s[0] <= ref.s[i + 1] + 1e-9


def test_u_turn_legs_tie_goes_to_the_return_leg():
    radius, leg, step = 6.0, 30.0, 0.5
    ref = road_ref("u_turn")
    _, s_end = _u_turn_arc_end(radius, leg, step, ref)
    first_leg = np.flatnonzero((ref.s < 20.0) & (ref.s > 5.0))
    last_leg = np.flatnonzero(ref.s > s_end + 5.0)
    checked = 0
    for a in first_leg[::7]:
        b = last_leg[np.argmin(np.abs(ref.points[last_leg, 0] - ref.points[a, 0]))]
        p = 0.5 * (ref.points[a] + ref.points[b])  # equidistant from L_a and L_b
        dist = np.linalg.norm(ref.points - p, axis=1)
        if np.delete(dist, [a, b]).min() <= dist[a] * (1.0 + TIE_REL) + TIE_ABS:
            continue
        fp = to_frenet(ref, p[None, :])
        assert fp.nearest[0] == b
        assert fp.s[0] > s_end
        assert fp.d[0] == pytest.approx(radius, abs=0.05)  # left of the return leg (heading −x)
        checked += 1
    assert checked >= 5


@settings(max_examples=100, deadline=None)
@given(frac=unit, shift=st.floats(-1e-3, 1e-3), t=st.floats(-40.0, 40.0))
def test_tie_tolerance_of_the_biggest_index_rule(frac, shift, t):
    ref = road_ref("straight")
    i = int(frac * (ref.size - 2))
    e = ref.seg_dir[i]
    normal = np.array([-e[1], e[0]])
    p = 0.5 * (ref.points[i] + ref.points[i + 1]) + shift * e + t * normal
    d_i, d_j = np.linalg.norm(ref.points[[i, i + 1]] - p, axis=1)
    nearest = min(d_i, d_j)
    limit = nearest * (1.0 + TIE_REL) + TIE_ABS
    assume(abs(d_i - limit) > 1e-12 and abs(d_j - limit) > 1e-12)
    expected = i + 1 if d_j <= limit else i
    fp = to_frenet(ref, p[None, :])
    assert fp.nearest[0] == expected


def _tie_distances(ref: ReferenceLine, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every point's distance to every sample, shape (N, M), and its tie limit, shape (N, 1)."""
    dist = np.hypot(*(ref.points[None, :, :] - pts[:, None, :]).transpose(2, 0, 1))
    return dist, dist.min(axis=1, keepdims=True) * (1.0 + TIE_REL) + TIE_ABS


def _biggest_nearest(ref: ReferenceLine, pts: np.ndarray) -> np.ndarray:
    """The biggest-index rule by brute force: the last sample within the tie limit of the nearest."""
    dist, limit = _tie_distances(ref, pts)
    return np.max(np.where(dist <= limit, np.arange(ref.size), -1), axis=1)


@functools.cache
def twice_round_ref(span: float) -> ReferenceLine:
    """A road that runs along a circle of radius 10 about the origin (angles ±``span``), leaves it,
    and comes back along the opposite stretch of the same circle: two stretches, far apart in index,
    equidistant from the origin."""
    radius = 10.0

    def arc(a0: float, a1: float) -> np.ndarray:
        a = np.linspace(a0, a1, 50)
        return radius * np.column_stack((np.cos(a), np.sin(a)))

    def tangent(a: float) -> np.ndarray:
        return np.array([-math.sin(a), math.cos(a)])

    steps = np.arange(1.0, 30.0)[:, None]
    first, second = arc(-span, span), arc(math.pi - span, math.pi + span)
    away = first[-1] + steps * tangent(span)
    back = second[0] - steps[::-1] * tangent(math.pi - span)
    on = second[-1] + steps * tangent(math.pi + span)
    return build_reference(np.vstack((first, away, back, second, on)))


@settings(max_examples=60, deadline=None)
@given(
    span=st.sampled_from([0.05, 0.2]),
    scale=st.sampled_from([1e-7, 1e-5, 1e-3, 1e-2, 1.0]),
    seed=st.integers(0, 2**16),
)
def test_ties_on_two_stretches_about_one_centre_go_to_the_later(span, scale, seed):
    """Points near the centre both stretches circle: every sample of both within the tie limit ties
    (more than the two a nearest-two query finds, and far apart in index): the biggest index wins."""
    ref = twice_round_ref(span)
    pts = np.random.default_rng(seed).normal(scale=scale, size=(200, 2))
    np.testing.assert_array_equal(to_frenet(ref, pts).nearest, _biggest_nearest(ref, pts))


@settings(max_examples=60, deadline=None)
@given(
    name=st.sampled_from(ROAD_NAMES),
    frac=unit,
    reach=st.floats(0.0, 200.0),
    seed=st.integers(0, 2**16),
)
def test_nearest_sample_is_the_biggest_index_among_ties(name, frac, reach, seed):
    """Anywhere (on the road, inside its bends, far off, where a straight's neighbouring samples
    fall within the relative tolerance of each other): the biggest index among the ties, as brute
    force finds it."""
    ref = road_ref(name)
    rng = np.random.default_rng(seed)
    centre = ref.points[int(frac * (ref.size - 1))]
    pts = centre + rng.normal(scale=max(reach, 1e-9), size=(200, 2))
    dist, limit = _tie_distances(ref, pts)
    clear = np.all(np.abs(dist - limit) > 1e-9 * (1.0 + limit), axis=1)  # none at the limit's rounding
    np.testing.assert_array_equal(to_frenet(ref, pts[clear]).nearest, _biggest_nearest(ref, pts[clear]))


def test_tie_rule_examples():
    ref = road_ref("straight")
    i = 40
    e = ref.seg_dir[i]
    mid = 0.5 * (ref.points[i] + ref.points[i + 1])
    # 1e-8 m nearer to L_i: a tie within TIE_ABS, the later sample wins
    assert to_frenet(ref, (mid - 0.5e-8 * e)[None, :]).nearest[0] == i + 1
    # 2 mm nearer to L_i: no tie, the nearer sample wins
    assert to_frenet(ref, (mid - 1e-3 * e)[None, :]).nearest[0] == i
    # 10 m off the road the relative part of the tolerance (1e-4·distance = 1 mm) makes it a tie
    normal = np.array([-e[1], e[0]])
    p = mid - 1e-2 * e + 10.0 * normal
    d_i, d_j = np.linalg.norm(ref.points[[i, i + 1]] - p, axis=1)
    assert 0.0 < d_j - d_i < TIE_REL * d_i
    assert to_frenet(ref, p[None, :]).nearest[0] == i + 1
    # the later sample was chosen, yet s is the orthogonal projection: the bisector step fixes it
    assert to_frenet(ref, p[None, :]).s[0] == pytest.approx(ref.s[i] + 0.5 * ref.spacing - 1e-2)


# --------------------------------------------------------------------------- offset lines


def _offset_arc_points(radius: float, sign: float, kd: float, angle: float) -> np.ndarray:
    arc = Arc(radius, sign)
    s = np.linspace(0.0, radius * angle, 4001)
    return arc.xy(s, sign * kd * radius)  # κ·d = kd (κ = sign/R)


@pytest.mark.parametrize("radius", [3.0, 6.0, 20.0, 60.0])
@pytest.mark.parametrize("sign", [1.0, -1.0])
@pytest.mark.parametrize("kd", [0.8, 0.5, -0.8, -3.0])
def test_offset_line_of_an_arc_has_strictly_increasing_s(radius, sign, kd):
    angle = min(2.5, 120.0 / radius)
    ref = arc_ref(radius, sign * angle)
    pts = _offset_arc_points(radius, sign, kd, angle)
    fp = to_frenet(ref, pts)
    assert np.all(np.diff(fp.s) > 0.0)
    assert not fp.folded.any()
    np.testing.assert_allclose(fp.d, sign * kd * radius, rtol=0.02)


@pytest.mark.parametrize(("radius", "kd"), [(60.0, 0.95), (120.0, 0.9), (200.0, 0.8), (500.0, 0.8)])
def test_offset_line_deep_inside_large_arcs_has_strictly_increasing_s(radius, kd):
    ref = arc_ref(radius, 1.0)
    pts = _offset_arc_points(radius, 1.0, kd, 1.0)
    fp = to_frenet(ref, pts)
    assert not fp.folded.any()
    assert np.all(np.diff(fp.s) > 0.0)


@settings(max_examples=60, deadline=None)
@given(
    radius=st.floats(3.0, 60.0),
    sign=st.sampled_from([1.0, -1.0]),
    kd=st.floats(-3.0, 0.9),
    angle=st.floats(0.5, 3.0),
)
def test_offset_lines_of_arcs_have_increasing_s(radius, sign, kd, angle):
    ref = arc_ref(round(radius, 3), sign * angle)
    pts = _offset_arc_points(round(radius, 3), sign, kd, angle)
    fp = to_frenet(ref, pts)
    assert np.all(np.diff(fp.s) > 0.0)


def test_offset_line_inside_a_u_turn_has_strictly_increasing_s():
    radius = 6.0
    ref = road_ref("u_turn")
    d = 0.8 * radius
    x = np.linspace(-28.0, 0.0, 2000)
    phi = np.linspace(0.0, math.pi, 3000)[1:-1]
    inner = radius - d
    pts = np.vstack(
        (
            np.column_stack((x, np.full_like(x, d))),
            np.column_stack((inner * np.sin(phi), radius - inner * np.cos(phi))),
            np.column_stack((x[::-1], np.full_like(x, 2.0 * radius - d))),
        )
    )
    fp = to_frenet(ref, pts)
    assert np.all(np.diff(fp.s) > 0.0)
    assert not fp.folded.any()
    np.testing.assert_allclose(fp.d, d, atol=0.05 * d)


@pytest.mark.parametrize("rate", [0.002, -0.002])
@pytest.mark.parametrize("kd", [0.8, -0.8])
def test_offset_line_of_a_clothoid_has_strictly_increasing_s(rate, kd):
    length = 60.0
    clothoid = Clothoid(rate)
    ref = road_ref("clothoid_left" if rate > 0 else "clothoid_right")
    d = math.copysign(1.0, rate) * kd / abs(rate * length)  # |κ·d| ≤ 0.8 everywhere
    s = np.linspace(0.0, length, 5001)
    fp = to_frenet(ref, clothoid.xy(s, d))
    assert np.all(np.diff(fp.s) > 0.0)
    assert not fp.folded.any()


# --------------------------------------------------------------------------- analytic answers


@settings(max_examples=80, deadline=None)
@given(
    heading=st.floats(-math.pi, math.pi),
    length=st.floats(1.0, 200.0),
    mode=st.sampled_from(["exact", "coarse", "irregular", "two_points"]),
    seed=st.integers(0, 2**16),
    s_frac=st.floats(-0.5, 1.5),
    d=st.floats(-100.0, 100.0),
)
def test_line_agrees_with_orthogonal_projection(heading, length, mode, seed, s_frac, d):
    line = Line(heading, origin=(3.0, -2.0))
    s_in = np.array([0.0, length]) if mode == "two_points" else sample_s(length, mode, seed)
    ref = build_reference(line.xy(s_in))
    s_true = s_frac * length
    fp = to_frenet(ref, line.xy([s_true], [d]))
    assert fp.s[0] == pytest.approx(s_true, abs=1e-6)
    assert fp.d[0] == pytest.approx(d, abs=1e-6)
    assert not fp.folded[0]


@pytest.mark.parametrize("d", [150.0, -300.0, 1000.0])
def test_line_agrees_with_projection_far_from_the_road(d):
    line = Line(0.3)
    ref = build_reference(line.xy(np.linspace(0.0, 200.0, 401)))
    s_true = np.linspace(20.0, 180.0, 801)
    fp = to_frenet(ref, line.xy(s_true, d))
    np.testing.assert_allclose(fp.s, s_true, atol=1e-6)
    np.testing.assert_allclose(fp.d, d, atol=1e-6)
    assert not fp.folded.any()


@st.composite
def arc_cases(draw):
    mode = draw(st.sampled_from(["exact", "irregular", "coarse"]))
    lowest = {"exact": 4.0, "irregular": 5.0, "coarse": 50.0}[mode]
    radius = round(draw(st.floats(lowest, 150.0)), 2)
    sign = draw(st.sampled_from([1.0, -1.0]))
    angle = round(draw(st.floats(0.3, 3.5)), 2)
    assume(20.0 <= radius * angle <= 400.0)
    seed = draw(st.integers(0, 50))
    return mode, radius, sign, angle, seed


@settings(max_examples=120, deadline=None)
@given(case=arc_cases(), s_frac=unit, d_frac=st.floats(-0.499, 0.499))
def test_arc_agrees_with_polar_angle(case, s_frac, d_frac):
    mode, radius, sign, angle, seed = case
    arc = Arc(radius, sign)
    ref = arc_ref(radius, sign * angle, mode, seed)
    length = radius * angle
    margin = 3.0 if mode == "exact" else 6.0
    s_true = margin + s_frac * (length - 2.0 * margin)
    d_true = d_frac * radius
    p = arc.xy([s_true], [d_true])
    s_exact, d_exact = arc.frenet(p)  # polar angle about the centre
    assert s_exact[0] == pytest.approx(s_true, abs=1e-9)
    fp = to_frenet(ref, p)
    assert abs(fp.s[0] - s_exact[0]) <= 0.05
    assert abs(fp.d[0] - d_exact[0]) <= 0.02
    assert not fp.folded[0]


@pytest.mark.parametrize("radius", [300.0, 500.0, 1000.0])
@pytest.mark.parametrize("d_frac", [0.45, -0.45])
def test_arc_agrees_with_polar_angle_far_from_large_radius_arcs(radius, d_frac):
    arc = Arc(radius, 1.0)
    angle = 100.0 / radius
    ref = arc_ref(radius, angle)
    s_true = np.linspace(10.0, 90.0, 161)
    pts = arc.xy(s_true, d_frac * radius)
    s_exact, d_exact = arc.frenet(pts)
    fp = to_frenet(ref, pts)
    assert np.abs(fp.s - s_exact).max() <= 0.05
    assert np.abs(fp.d - d_exact).max() <= 0.02


@st.composite
def clothoid_cases(draw):
    mode = draw(st.sampled_from(["exact", "irregular", "coarse"]))
    length = round(draw(st.floats(30.0, 200.0)), 1)
    # κ_end = rate·length: ≤ 1/50 for 5 m input, ≤ 1/10 for irregular input; total turn ≤ 2.5 rad
    top = {"exact": 0.2, "irregular": 0.1, "coarse": 0.02}[mode]
    kappa_end = draw(st.floats(0.005, min(top, 5.0 / length)))
    sign = draw(st.sampled_from([1.0, -1.0]))
    seed = draw(st.integers(0, 50))
    return mode, length, round(sign * kappa_end / length, 7), seed


@functools.cache
def clothoid_ref(length: float, rate: float, mode: str, seed: int) -> ReferenceLine:
    return build_reference(Clothoid(rate).xy(sample_s(length, mode, seed)))


@settings(max_examples=100, deadline=None)
@given(case=clothoid_cases(), s_frac=unit, d_frac=st.floats(-0.499, 0.499))
def test_clothoid_agrees_with_the_numerical_nearest_point(case, s_frac, d_frac):
    mode, length, rate, seed = case
    clothoid = Clothoid(rate)
    ref = clothoid_ref(length, rate, mode, seed)
    margin = 3.0 if mode == "exact" else 6.0
    s_true = margin + s_frac * (length - 2.0 * margin)
    d_true = d_frac / abs(rate * length)  # |d| < 0.5/κ_max
    p = clothoid.xy([s_true], [d_true])[0]
    exact = clothoid.frenet_one(p, length)
    assume(exact is not None)  # a unique nearest point only
    s_exact, d_exact = exact
    assert s_exact == pytest.approx(s_true, abs=1e-8)  # the foot of the normal is the nearest
    assert d_exact == pytest.approx(d_true, abs=1e-8)
    fp = to_frenet(ref, p[None, :])
    assert abs(fp.s[0] - s_exact) <= 0.05
    assert abs(fp.d[0] - d_exact) <= 0.02
    assert not fp.folded[0]


@pytest.mark.parametrize("mode", ["exact", "irregular", "coarse"])
def test_clothoid_grid_agrees_with_the_numerical_nearest_point(mode):
    # a deterministic companion to the property above: a grid of Cartesian points
    length, rate = 120.0, 0.00015  # κ_end = 0.018: gentle enough for 5 m input
    clothoid = Clothoid(rate)
    ref = clothoid_ref(length, rate, mode, 4)
    half = 0.5 / (rate * length)
    rng = np.random.default_rng(8)
    lo, hi = ref.points.min(axis=0) - half, ref.points.max(axis=0) + half
    pts = rng.uniform(lo, hi, size=(400, 2))
    fp = to_frenet(ref, pts)
    checked = 0
    for p, s, d in zip(pts, fp.s, fp.d, strict=True):
        exact = clothoid.frenet_one(p, length)
        if exact is None or not (6.0 < exact[0] < length - 6.0) or abs(exact[1]) >= 0.499 * 2 * half:
            continue
        assert abs(s - exact[0]) <= 0.05
        assert abs(d - exact[1]) <= 0.02
        checked += 1
    assert checked >= 100


# --------------------------------------------------------------------------- rays at the ends


@settings(max_examples=100, deadline=None)
@given(
    name=st.sampled_from(ROAD_NAMES),
    t=st.floats(1.0, 60.0),
    d_frac=st.floats(-0.99, 0.99),
    at_end=st.booleans(),
)
def test_end_segments_extend_as_rays(name, t, d_frac, at_end):
    ref = road_ref(name)
    d = d_frac * tube(ref, cap=20.0)  # the hairpins' legs are only 2R apart
    if at_end:
        e, base = ref.seg_dir[-1], ref.points[-1]
    else:
        e, base = -ref.seg_dir[0], ref.points[0]
    normal = np.array([-e[1], e[0]]) * (1.0 if at_end else -1.0)  # left of the driving direction
    p = base + t * e + d * normal
    # only where the end sample is the nearest (a curling road may come back towards its ray)
    dist = np.linalg.norm(ref.points - p, axis=1)
    assume(int(np.argmin(dist)) == (ref.size - 1 if at_end else 0))
    fp = to_frenet(ref, p[None, :])
    if at_end:
        assert fp.s[0] > ref.length
        assert fp.segment[0] == ref.size - 2
    else:
        assert fp.s[0] < 0.0
        assert fp.segment[0] == 0
    assert not fp.folded[0]
    assert fp.d[0] == pytest.approx(d, abs=1e-9)  # d is the offset from the ray's line
    np.testing.assert_allclose(to_cartesian(ref, fp.s, fp.d)[0], p, atol=1e-9)
    # on the ray itself s grows like the arc length along it (where the end sample is nearest too: a
    # curling road can come closer to the ray than to the offset point)
    q = base + t * e
    if int(np.argmin(np.linalg.norm(ref.points - q, axis=1))) != (ref.size - 1 if at_end else 0):
        return
    on_ray = to_frenet(ref, q[None, :])
    expected = ref.length + t if at_end else -t
    assert on_ray.s[0] == pytest.approx(expected, abs=1e-3 * t)
    assert on_ray.d[0] == pytest.approx(0.0, abs=1e-9)


def test_straight_extension_is_exact():
    line = Line(1.0)
    ref = build_reference(line.xy(np.linspace(0.0, 30.0, 7)))
    s_true = np.array([-50.0, -1.0, -1e-6, 30.0 + 1e-6, 31.0, 80.0])
    for d in (-12.0, 0.0, 7.5):
        fp = to_frenet(ref, line.xy(s_true, d))
        np.testing.assert_allclose(fp.s, s_true, atol=1e-9)
        np.testing.assert_allclose(fp.d, d, atol=1e-9)
