"""Analytic speed profiles: a full stop, keeping the speed, and a speed within the path's limit, within
the jerk limit."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from solvers.speed_problem import SpeedProblem, integrate_jerk, steer_jerk
from solvers.speed_profiles import _brakes_within, _Envelope, braking_profile, cruise_profile, limited_profile
from tests.solvers.speed_cases import make_problem


@pytest.mark.parametrize(
    ("v0", "a0", "jerk_max", "dt"),
    [
        (20.0, 0.0, 2.0, 0.1),
        (30.0, 1.5, 1.0, 0.2),
        (3.0, -4.5, 6.0, 0.05),
        (0.4, -3.6, 1.0, 0.1),
        (0.0, 0.0, 2.0, 0.1),
    ],
)
def test_braking_profile_stops_within_the_jerk_limit(
    v0: float, a0: float, jerk_max: float, dt: float
) -> None:
    problem = make_problem(v0=v0, a0=a0, jerk_max=jerk_max, dt=dt, steps=400)
    jerk = braking_profile(problem)
    _, v, a = integrate_jerk(dt, 0.0, v0, a0, jerk)
    assert np.max(np.abs(jerk)) <= jerk_max * (1 + 1e-9)
    assert abs(v[-1]) < 1e-9 and abs(a[-1]) < 1e-9
    floor, _ = problem.speed_floor()
    assert np.all(v >= floor - 1e-9)
    if a0 >= 0:
        assert np.all(v >= -1e-9)
    if v0 >= 20:
        assert np.min(a) == pytest.approx(problem.a_min)  # full braking


def test_cruise_profile_releases_the_acceleration_and_keeps_the_speed() -> None:
    problem = make_problem(a0=-3.0, jerk_max=10.0)
    jerk = cruise_profile(problem)
    _, v, a = integrate_jerk(problem.dt, 0.0, problem.v0, problem.a0, jerk)
    assert np.max(np.abs(jerk)) <= problem.jerk_max * (1 + 1e-12)
    assert np.all(a[:3] < 0) and np.all(np.abs(a[3:]) < 1e-12)  # released in 0.3 s at the jerk limit
    assert np.allclose(v[3:], 10.0 - 0.45)
    # releasing the brake would end below standstill: it stops instead
    slow = make_problem(v0=0.3, a0=-3.0, jerk_max=10.0)
    assert np.array_equal(cruise_profile(slow), braking_profile(slow))


def _dip(v_high: float, v_low: float, start: float, end: float) -> tuple[list[float], list[float]]:
    """A limit of ``v_high`` with ``v_low`` on ``[start, end]`` [m] (steps 1 m wide)."""
    return [0.0, start - 1.0, start, end, end + 1.0, 1000.0], [v_high, v_high, v_low, v_low, v_high, v_high]


def _within(problem: SpeedProblem, s: np.ndarray, v: np.ndarray) -> np.ndarray:
    limit = np.interp(s, problem.limit_s, problem.limit_v)
    return np.asarray(v <= limit + 1e-6)


def test_limited_profile_slows_for_a_dip_as_late_as_it_must_and_speeds_up_after_it() -> None:
    limit_s, limit_v = _dip(30.0, 6.0, 60.0, 75.0)
    problem = make_problem(
        v0=15.0, limit_s=limit_s, limit_v=limit_v, jerk_max=30.0, a_min=-6.0, a_max=2.5, steps=160
    )
    jerk = limited_profile(problem, 15.0)
    s, v, a = integrate_jerk(problem.dt, 0.0, problem.v0, problem.a0, jerk)
    assert np.all(_within(problem, s, v))
    assert np.max(np.abs(jerk)) <= 30.0 * (1 + 1e-12)
    assert np.all((a >= -6.0 - 1e-9) & (a <= 2.5 + 1e-9)) and np.all(v >= 0.0)
    assert np.all(v[s < 20.0] == pytest.approx(15.0))  # far before the dip: the speed kept
    inside = (s >= 60.0) & (s <= 75.0)
    assert inside.any() and v[inside].max() > 5.5  # braked only as far as the dip needs
    assert v[-1] == pytest.approx(15.0, abs=1e-3) and s[-1] > 76.0  # back at the speed after it


def test_the_steer_towards_an_extreme_speed_takes_the_jerk_limit() -> None:
    """A ``v_keep`` no release on the grid reaches (an extreme vehicle's cap, ±∞) steers as hard as the
    jerk allows, not into an overflow."""

    # up to a_max = 2.5 within the step (j = 25); down, the jerk limit (30) binds before a_min = −6
    for v_keep, jerk in ((np.inf, 25.0), (1e308, 25.0), (-np.inf, -30.0), (-1e308, -30.0)):
        assert steer_jerk(10.0, 0.0, v_keep, 0.1, 30.0, -6.0, 2.5) == pytest.approx(jerk)


def test_limited_profile_from_a_state_that_cannot_keep_the_limit_brakes_fully() -> None:
    limit_s, limit_v = _dip(30.0, 5.0, 10.0, 40.0)  # 20 m/s, 10 m before 5 m/s: out of reach
    problem = make_problem(v0=20.0, limit_s=limit_s, limit_v=limit_v, jerk_max=30.0, a_min=-6.0)
    jerk = limited_profile(problem, 20.0)
    np.testing.assert_allclose(jerk[:10], braking_profile(problem)[:10])


@pytest.mark.parametrize(("v0", "limit"), [(10.0, 12.0), (20.03, 20.0), (20.0, 20.0), (3.0, 2.5)])
def test_limited_profile_settles_at_a_kept_speed_the_limit_allows(v0: float, limit: float) -> None:
    """Towards ``v_keep`` at the limit the speed settles on it, the acceleration at 0 (the steer's release
    taken as continuous overshot it on the grid; the braking that undid that swung the acceleration by a
    few m/s² every few steps for the rest of the horizon)."""
    problem = make_problem(
        v0=v0, limit_s=[0.0, 1000.0], limit_v=[limit, limit], jerk_max=30.0, a_min=-6.0, a_max=2.5
    )
    _, v, a = integrate_jerk(problem.dt, 0.0, v0, 0.0, limited_profile(problem, limit))
    assert np.all(v <= max(v0, limit) + 1e-6)  # a start above the limit brakes down to it
    np.testing.assert_allclose(v[20:], limit, atol=1e-6)
    np.testing.assert_allclose(a[20:], 0.0, atol=1e-6)


@settings(max_examples=200, deadline=None)
@given(
    v=st.floats(0.0, 30.0), a=st.floats(-6.0, 6.0), share=st.floats(-0.999, 0.999), dt=st.floats(0.02, 0.3)
)
def test_the_steer_lands_on_the_kept_speed_on_the_grid(v: float, a: float, share: float, dt: float) -> None:
    """The steer inverts the grid's release: for the speed where a step of jerk ``j`` (within the limit)
    and then the fastest release of the acceleration on the grid (full-jerk steps and a partial one) end,
    it steers with that ``j``."""

    jmax = 30.0
    j = share * jmax
    u = a + j * dt
    full = int(abs(u) // (jmax * dt))
    release = [-np.sign(u) * jmax] * full + [-(u - np.sign(u) * jmax * dt * full) / dt]
    _, speed, accel = integrate_jerk(dt, 0.0, v + (a + u) * dt / 2, u, np.array(release))
    assert accel[-1] == pytest.approx(0.0, abs=1e-9)
    assert steer_jerk(v, a, float(speed[-1]), dt, jmax, -1e9, 1e9) == pytest.approx(j, abs=1e-6)


@settings(max_examples=40, deadline=None)
@given(
    v0=st.floats(0.0, 30.0),
    a0=st.floats(-6.0, 2.5),
    v_keep=st.floats(0.0, 35.0),
    low=st.floats(1.0, 30.0),
    start=st.floats(0.0, 150.0),
    width=st.floats(1.0, 50.0),
)
def test_limited_profile_keeps_the_limit_wherever_full_braking_can(
    v0: float, a0: float, v_keep: float, low: float, start: float, width: float
) -> None:
    """Wherever full braking from the start keeps the limit, so does the profile; it never goes faster
    than the faster of ``v_keep`` and the start, and keeps the jerk, the acceleration and ``v ≥ 0``."""
    limit_s, limit_v = _dip(40.0, low, start + 2.0, start + 2.0 + width)
    problem = make_problem(
        v0=v0, a0=a0, limit_s=limit_s, limit_v=limit_v, jerk_max=30.0, a_min=-6.0, a_max=2.5
    )
    assume(problem.speed_floor()[0].min() == 0.0)  # no backward motion forced by a0 (braking mirrors it)
    s_b, v_b, _ = integrate_jerk(problem.dt, 0.0, v0, a0, braking_profile(replace(problem, steps=1000)))
    jerk = limited_profile(problem, v_keep)
    s, v, a = integrate_jerk(problem.dt, 0.0, v0, a0, jerk)
    assert np.max(np.abs(jerk)) <= 30.0 * (1 + 1e-12)
    assert np.all(a >= min(a0, -6.0) - 1e-9) and np.all(a <= max(a0, 2.5) + 1e-9)
    assert np.all(v >= -1e-9)
    assert np.all(v <= max(v_keep, v0 + max(a0, 0.0) ** 2 / 60.0) + 0.05)
    if np.all(_within(problem, s_b, v_b)):
        assert np.all(_within(problem, s, v))


@settings(max_examples=200, deadline=None)
@given(
    limit_v=st.lists(st.floats(0.5, 30.0), min_size=2, max_size=12),
    spacing=st.floats(0.5, 20.0),
    s=st.floats(0.0, 200.0),
    v=st.floats(0.0, 30.0),
    a=st.floats(-6.0, 2.5),
)
def test_the_quick_braking_test_never_passes_a_state_whose_braking_breaks_the_limit(
    limit_v: list[float], spacing: float, s: float, v: float, a: float
) -> None:
    problem = make_problem(
        limit_s=spacing * np.arange(len(limit_v)), limit_v=limit_v, jerk_max=30.0, a_min=-6.0, a_max=2.5
    )
    if _Envelope.of(problem).keeps(s, v, a):
        assert _brakes_within(problem, s, v, a)


def _limited_reference(problem: SpeedProblem, v_keep: float) -> np.ndarray:
    """:func:`limited_profile` as first written: each full stop computed whole (the reference for the
    one that computes only the steps it follows)."""
    from solvers.speed_profiles import _spare_speed

    dt, n, jmax = problem.dt, problem.steps, problem.jerk_max
    jerk = np.zeros(n)
    s, v, a = problem.s0, problem.v0, problem.a0
    brake: list[float] = []
    envelope = _Envelope.of(problem)

    def after(s: float, v: float, a: float, j: float) -> tuple[float, float, float]:
        return s + v * dt + a * dt**2 / 2 + j * dt**3 / 6, v + a * dt + j * dt**2 / 2, a + j * dt

    for k in range(n):
        j = steer_jerk(v, a, v_keep, dt, jmax, min(problem.a_min, a), max(problem.a_max, a))
        nxt = after(s, v, a, j)
        releasable = nxt[1] >= 0.0 and _spare_speed(nxt[1], nxt[2], dt, jmax) >= 0.0
        if releasable and (envelope.keeps(*nxt) or _brakes_within(problem, *nxt)):
            brake = []
        else:
            if not brake:
                brake = braking_profile(replace(problem, s0=s, v0=max(v, 0.0), a0=a, steps=n - k)).tolist()
            j = brake.pop(0)
            nxt = after(s, v, a, j)
        jerk[k] = j
        s, v, a = nxt
    return jerk


@settings(max_examples=60, deadline=None)
@given(
    v0=st.floats(0.0, 30.0),
    a0=st.floats(-6.0, 2.5),
    v_keep=st.floats(0.0, 35.0),
    limit_v=st.lists(st.floats(0.5, 30.0), min_size=2, max_size=8),
    spacing=st.floats(1.0, 30.0),
)
def test_limited_profile_equals_its_reference_exactly(
    v0: float, a0: float, v_keep: float, limit_v: list[float], spacing: float
) -> None:
    problem = make_problem(
        v0=v0,
        a0=a0,
        limit_s=spacing * np.arange(len(limit_v)),
        limit_v=limit_v,
        jerk_max=30.0,
        a_min=-6.0,
        a_max=2.5,
    )
    assert np.array_equal(limited_profile(problem, v_keep), _limited_reference(problem, v_keep))


@settings(max_examples=60, deadline=None)
@given(v0=st.floats(0.0, 30.0), a0=st.floats(-6.0, 2.5), steps=st.integers(1, 120))
def test_braking_profile_is_its_own_prefix(v0: float, a0: float, steps: int) -> None:
    """The full stop on a shorter grid is the first steps of the one on a longer grid (what lets
    :func:`limited_profile` follow a stop step by step)."""
    problem = make_problem(v0=v0, a0=a0, jerk_max=30.0, a_min=-6.0, a_max=2.5, steps=120)
    assert np.array_equal(braking_profile(replace(problem, steps=steps)), braking_profile(problem)[:steps])


def _keeps_reference(problem: SpeedProblem, s: float, v: float, a: float) -> bool:
    """:meth:`_Envelope.keeps` as first written, on numpy arrays (the reference for the scalar one)."""
    lowest = np.minimum(problem.limit_v, np.append(problem.limit_v[1:], problem.limit_v[-1]))
    b = -problem.a_min
    energy = np.minimum.accumulate((lowest**2 + 2.0 * b * problem.limit_s)[::-1])[::-1]
    ramp = max(a - problem.a_min, 0.0) / problem.jerk_max + problem.dt
    peak = v + max(a, 0.0) * ramp
    reach = s + max(peak, 0.0) * ramp
    limit_s, limit_v = problem.limit_s, problem.limit_v
    lo, hi = np.searchsorted(limit_s, (s, reach), side="right")
    ends = np.interp((s, reach), limit_s, limit_v)
    least = min(float(ends.min()), float(limit_v[lo:hi].min()) if hi > lo else np.inf)
    if peak > least + 1e-6:
        return False
    ahead = min(float(ends[1]), float(limit_v[min(hi, limit_v.size - 1)])) ** 2 + 2.0 * b * reach
    beyond = float(energy[hi]) if hi < energy.size else np.inf
    return bool(peak**2 + 2.0 * b * reach <= min(ahead, beyond) + 1e-6)


@settings(max_examples=300, deadline=None)
@given(
    limit_v=st.lists(st.floats(0.5, 30.0), min_size=2, max_size=12),
    spacing=st.floats(0.5, 20.0),
    s=st.floats(-10.0, 250.0),
    v=st.floats(0.0, 30.0),
    a=st.floats(-6.0, 2.5),
)
def test_the_quick_braking_test_equals_its_reference(
    limit_v: list[float], spacing: float, s: float, v: float, a: float
) -> None:
    problem = make_problem(
        limit_s=spacing * np.arange(len(limit_v)), limit_v=limit_v, jerk_max=30.0, a_min=-6.0, a_max=2.5
    )
    assert _Envelope.of(problem).keeps(s, v, a) == _keeps_reference(problem, s, v, a)


@settings(max_examples=300, deadline=None)
@given(
    v=st.floats(-30.0, 30.0),
    a=st.floats(-8.0, 8.0) | st.just(0.0),
    dt=st.floats(0.01, 0.5),
    jmax=st.floats(0.5, 50.0),
)
def test_the_spare_speed_is_the_release_s_exactly(v: float, a: float, dt: float, jmax: float) -> None:
    from solvers.speed_profiles import _release, _spare_speed

    assert _spare_speed(v, a, dt, jmax) == v + _release(a, dt, jmax)[1]
