r"""Collisions in continuous time: the footprint between two samples of a trajectory, against static
obstacles and against moving ones between the samples of their predictions.

**The motion between samples.** A trajectory is a sequence of poses — the footprint's centre ``p_k``
[m] and yaw ``θ_k`` [rad] (continuous, not wrapped) at times ``t_k`` [s] — and between two samples the
vehicle moves as the obstacles' predictions do (:func:`planner.collision.prediction_at`): centre and
yaw linear in time, ``p(t) = p_k + u Δp_k``, ``θ(t) = θ_k + u Δθ_k`` with ``u = (t − t_k)/Δt_k``. A point
of the body at ``r`` from the centre (``|r| ≤ R``, half the footprint's diagonal) is at
``p(t) + Rot(θ(t)) r``.

**Conservative advancement.** Within one step every point of the vehicle travels at most
``Λ_e(a, b) = (|Δp_k| + |Δθ_k| R)(b − a)/Δt_k`` over ``[a, b]``, and every point of an obstacle at most
``Λ_o(a, b)``: 0 for a static one, ``∫_a^b (|ċ| + |ḣ| R_o) dt`` for a moving box of half diagonal
``R_o`` along its prediction (centre ``c``, heading ``h``: piecewise linear, so the integral is exact).
If the two touch at ``τ ∈ [a, b]`` (a common point ``z``), their distance at ``a`` is at most
``|e(a) − z| + |z − o(a)| ≤ Λ_e(a, τ) + Λ_o(a, τ)``, and at ``b`` at most ``Λ_e(τ, b) + Λ_o(τ, b)``, so
``d(a) + d(b) ≤ Λ_e(a, b) + Λ_o(a, b) =: Λ(a, b)``. An interval with ``d(a) + d(b) > Λ(a, b)`` is
therefore free of contact, its ends included. The others are halved and the distance at each midpoint
computed (zero: a contact at that time), round after round, until every interval is cleared; one whose
``Λ`` falls below :data:`TOLERANCE` brings the bodies within it of each other and counts as a contact,
and so do the intervals left when more than :data:`MAX_INTERVALS` remain. So the check never misses a
contact, and reports one only where the bodies come within :data:`TOLERANCE` [m] (or in the rare case
of too many intervals); the rounds are bounded, so the work is.

**Which pairs of a step and an obstacle to look at.** Moving obstacles: those whose bounding circles
come near, ``max(|p − c| − R − R_o, 0) ≤ d`` at both ends and the sum of these not above ``Λ``. Static
obstacles: those that meet the step's swept footprint ``S_k = hull(F_k ∪ F_{k+1}) ⊕ B(R Δθ_k²/8)``
(``F_k`` the footprint at sample ``k``, ``⊕ B(ε)`` every point within ``ε``; one query of a tree of
the steps' hulls). *Proof that the footprint stays inside* ``S_k``. For a body point ``r`` let
``D(u) = Rot(θ_k + uΔθ_k) r − (1 − u) Rot(θ_k) r − u Rot(θ_{k+1}) r``. Its position at ``u`` is
``(1 − u)(p_k + Rot(θ_k) r) + u (p_{k+1} + Rot(θ_{k+1}) r) + D(u)``, and the first two terms are a
convex combination of a point of ``F_k`` and one of ``F_{k+1}``: a point of the hull. ``D`` vanishes at
``u = 0`` and ``u = 1`` and ``|D″(u)| = Δθ_k² |r|``; the error of linear interpolation,
``D(u) = −∫₀¹ G(u, v) D″(v) dv`` with the kernel ``G ≥ 0``, ``∫₀¹ G(u, v) dv = u(1 − u)/2`` (a vector
identity, so the bound holds for the vector's length), gives ``|D(u)| ≤ Δθ_k² |r| u(1 − u)/2 ≤
R Δθ_k²/8``. ∎ (The hull alone is exact for a translation but in a turn reaches about ``L Δθ/4`` beyond
the swept footprint beside its middle, hence the advancement after it.)

A contact at a sample is reported at that sample's time; one strictly between samples at the time of
the sample before it.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry.base import BaseGeometry

from planner.collision import box_corners
from planner.problem import DynamicObstacle, Vehicle
from planner.reference import FloatArray
from planner.trajectory import Trajectory

#: an interval not cleared whose relative motion bound is below this [m] counts as a contact
TOLERANCE = 1e-3
#: most intervals the conservative advancement keeps at once; beyond, the rest count as contacts
MAX_INTERVALS = 4096

Indices = NDArray[np.intp]
Geometries = NDArray[np.object_]


@dataclass(frozen=True)
class Contact:
    """The footprint meets ``obstacle_id`` first at ``t`` [s] (at a sample, or the sample before a
    contact between two samples: ``between``)."""

    obstacle_id: str
    t: float
    between: bool


def half_diagonal(length: float, width: float) -> float:
    """Distance [m] from a ``length × width`` box's centre to its corners."""
    return 0.5 * float(np.hypot(length, width))


class _Obstacles(Protocol):
    def geometry(self, i: Indices, t: FloatArray) -> Geometries:
        """The outlines of obstacles ``i`` at times ``t`` [s] (elementwise)."""
        ...

    def travelled(self, i: Indices, a: FloatArray, b: FloatArray) -> FloatArray:
        """Bound on how far any point of obstacle ``i`` travels over ``[a, b]`` [m] (elementwise)."""
        ...


@dataclass(frozen=True)
class _Static:
    """Outlines that stay put."""

    shapes: Geometries

    def geometry(self, i: Indices, t: FloatArray) -> Geometries:
        return self.shapes[i]

    def travelled(self, i: Indices, a: FloatArray, b: FloatArray) -> FloatArray:
        return np.zeros(a.shape)


def static_contacts(
    traj: Trajectory, vehicle: Vehicle, static: Sequence[tuple[str, BaseGeometry]]
) -> list[Contact]:
    """The static obstacles (``(id, outline)``) the footprint meets at any time of the trajectory, in
    their order (see the module docstring)."""
    if not static:
        return []
    ids = [ob_id for ob_id, _ in static]
    shapes = np.array([shape for _, shape in static], dtype=object)
    if traj.size < 2:
        prints = _footprints(traj, vehicle, traj.t[:1])
        met = np.flatnonzero(np.asarray(shapely.intersects(prints[0], shapes), dtype=bool))
        return [Contact(ids[int(i)], float(traj.t[0]), False) for i in met]
    corners = box_corners(traj.x, traj.y, traj.heading, vehicle.length, vehicle.width)
    hulls = np.asarray(
        shapely.convex_hull(shapely.multipoints(np.concatenate((corners[:-1], corners[1:]), axis=1)))
    )
    bulge = half_diagonal(vehicle.length, vehicle.width) * np.diff(traj.heading) ** 2 / 8.0
    ob_i, step = shapely.STRtree(hulls).query(shapes, predicate="dwithin", distance=float(bulge.max()))
    near = np.asarray(shapely.dwithin(hulls[step], shapes[ob_i], bulge[step]), dtype=bool)
    return _contacts(traj, vehicle, ids, _Static(shapes), ob_i[near], step[near])


def moving_contacts(traj: Trajectory, vehicle: Vehicle, movers: Sequence[DynamicObstacle]) -> list[Contact]:
    """The moving obstacles the footprint meets at any time of the trajectory, in their order (see the
    module docstring)."""
    if not movers:
        return []
    t = traj.t
    ids = [ob.id for ob in movers]
    boxes = _movers_table(movers)
    radius = half_diagonal(vehicle.length, vehicle.width)
    every = np.repeat(np.arange(len(movers)), t.shape[0])
    cx, cy = boxes.centres(every, np.tile(t, len(movers)))
    centres = np.hypot(cx.reshape(len(movers), -1) - traj.x, cy.reshape(len(movers), -1) - traj.y)
    lower = np.maximum(centres - radius - boxes.radius[:, None], 0.0)  # ≤ the distance, (m, n)
    if t.shape[0] < 2:
        i = np.flatnonzero(lower[:, 0] == 0.0)
        at = np.full(i.shape, t[0])
        met = np.asarray(
            shapely.intersects(_footprints(traj, vehicle, at), boxes.geometry(i, at)), dtype=bool
        )
        return [Contact(ids[int(j)], float(t[0]), False) for j in i[met]]
    grid_m, grid_k = np.meshgrid(np.arange(len(movers)), np.arange(t.shape[0] - 1), indexing="ij")
    m, k = grid_m.ravel(), grid_k.ravel()
    reach = _ego_travel(traj, vehicle)[k] + boxes.travelled(m, t[k], t[k + 1])
    near = lower[m, k] + lower[m, k + 1] <= reach
    return _contacts(traj, vehicle, ids, boxes, m[near], k[near])


#: the moving obstacles last tabled and their table: a plan checks several trajectories against the same
#: obstacles (the fallback weighs up to seven). Reused only for the very same objects, in the same order.
_LAST_MOVERS: tuple[tuple[DynamicObstacle, ...], _Movers | None] = ((), None)


def _movers_table(movers: Sequence[DynamicObstacle]) -> _Movers:
    """:meth:`_Movers.of` ``movers``, from the last call's table where they are the same objects."""
    global _LAST_MOVERS
    last, table = _LAST_MOVERS
    if table is None or len(last) != len(movers) or not all(map(operator.is_, last, movers)):
        table = _Movers.of(movers)
        _LAST_MOVERS = (tuple(movers), table)
    return table


def _ego_travel(traj: Trajectory, vehicle: Vehicle) -> FloatArray:
    """Per step, how far any point of the footprint travels at most [m]: ``|Δp| + |Δθ| R``."""
    radius = half_diagonal(vehicle.length, vehicle.width)
    return np.asarray(np.hypot(np.diff(traj.x), np.diff(traj.y)) + np.abs(np.diff(traj.heading)) * radius)


def _footprints(traj: Trajectory, vehicle: Vehicle, t: FloatArray) -> Geometries:
    """The footprints at times ``t`` [s], centre and yaw interpolated linearly between samples."""
    x, y, heading = (np.interp(t, traj.t, v) for v in (traj.x, traj.y, traj.heading))
    return np.asarray(shapely.polygons(box_corners(x, y, heading, vehicle.length, vehicle.width)))


def _contacts(
    traj: Trajectory, vehicle: Vehicle, ids: Sequence[str], obstacles: _Obstacles, m: Indices, k: Indices
) -> list[Contact]:
    """The first contact of each obstacle among the pairs (obstacle ``m``, step ``k``) of the
    trajectory, by conservative advancement (see the module docstring)."""
    if m.size == 0:
        return []
    t = traj.t
    n = t.shape[0]
    rate = _ego_travel(traj, vehicle) / np.diff(t)
    # the distances at the samples these steps need, each (obstacle, sample) once
    key, inverse = np.unique(np.concatenate((m * n + k, m * n + k + 1)), return_inverse=True)
    ob_u, at_u = key // n, t[key % n]
    dist_u = np.asarray(shapely.distance(_footprints(traj, vehicle, at_u), obstacles.geometry(ob_u, at_u)))
    touch_u = dist_u == 0.0
    found_i, found_t, found_between = [ob_u[touch_u]], [at_u[touch_u]], [np.zeros(int(touch_u.sum()), bool)]
    earliest = np.full(len(ids), np.inf)  # each obstacle's first contact so far: later steps need no work
    np.minimum.at(earliest, ob_u[touch_u], at_u[touch_u])
    dist = dist_u[inverse]
    da, db = dist[: m.size], dist[m.size :]
    a, b = t[k], t[k + 1]
    keep = (da > 0.0) & (db > 0.0) & (t[k] < earliest[m])
    m, k = m[keep], k[keep]
    a, b, da, db = (v[keep] for v in (a, b, da, db))
    while m.size:
        reach = rate[k] * (b - a) + obstacles.travelled(m, a, b)
        keep = da + db <= reach  # not cleared
        m, k = m[keep], k[keep]
        a, b, da, db, reach = (v[keep] for v in (a, b, da, db, reach))
        give_up = reach < TOLERANCE
        if m.size > MAX_INTERVALS:
            give_up[:] = True
        mid = 0.5 * (a + b)
        go = ~give_up
        dm = np.full(m.shape, np.inf)
        dm[go] = shapely.distance(_footprints(traj, vehicle, mid[go]), obstacles.geometry(m[go], mid[go]))
        contact = give_up | (dm == 0.0)
        if np.any(contact):
            found_i.append(m[contact])
            found_t.append(t[k[contact]])
            found_between.append(np.ones(int(contact.sum()), dtype=bool))
            np.minimum.at(earliest, m[contact], t[k[contact]])
        keep = ~contact & (t[k] < earliest[m])
        m, k = m[keep], k[keep]
        a, b, da, db, mid, dm = (v[keep] for v in (a, b, da, db, mid, dm))
        m, k = np.concatenate((m, m)), np.concatenate((k, k))
        a, b = np.concatenate((a, mid)), np.concatenate((mid, b))
        da, db = np.concatenate((da, dm)), np.concatenate((dm, db))
    return _first_contacts(
        ids, np.concatenate(found_i), np.concatenate(found_t), np.concatenate(found_between)
    )


def _first_contacts(
    ids: Sequence[str], ob_i: Indices, when: FloatArray, between: NDArray[np.bool_]
) -> list[Contact]:
    """Per obstacle index in ``ob_i`` (contacts at times ``when``), its first contact, in the order of
    ``ids``."""
    out: list[Contact] = []
    for i in np.unique(ob_i):
        own = np.flatnonzero(ob_i == i)
        first = own[np.lexsort((between[own], when[own]))[0]]  # at a sample before between, on a tie
        out.append(Contact(ids[int(i)], float(when[first]), bool(between[first])))
    return out


@dataclass(frozen=True)
class _Movers:
    """The moving obstacles' predictions in one table, to interpolate all of them at once.

    Rows of every prediction one after the other, obstacle ``i``'s from ``first[i]`` to ``last[i]``; the
    times are moved onto one increasing axis, obstacle ``i``'s by ``i · span`` (``span`` longer than
    any prediction), so that one ``np.interp`` serves every obstacle (its time clipped to its own
    prediction: held at the ends, as :func:`planner.collision.prediction_at` does). ``travel`` is the
    cumulative bound ``G(t) = ∫ (|ċ| + |ḣ| R_o) dt`` at each row (0 at each prediction's start)."""

    length: FloatArray
    width: FloatArray
    radius: FloatArray
    start: FloatArray
    end: FloatArray
    span: float
    key: FloatArray
    x: FloatArray
    y: FloatArray
    heading: FloatArray
    travel: FloatArray

    @classmethod
    def of(cls, movers: Sequence[DynamicObstacle]) -> _Movers:
        preds = [np.asarray(ob.prediction, dtype=float) for ob in movers]
        sizes = np.array([p.shape[0] for p in preds])
        table = np.vstack(preds)
        owner = np.repeat(np.arange(len(preds)), sizes)
        first = np.concatenate(([0], np.cumsum(sizes)[:-1]))
        t = table[:, 0]
        start, end = t[first], t[first + sizes - 1]
        span = float(np.max(end) - np.min(start)) + 1.0
        same = np.concatenate(([False], owner[1:] == owner[:-1]))  # a row continues the one before
        heading = _unwrap_runs(table[:, 3], same)
        length = np.array([ob.length for ob in movers], dtype=float)
        width = np.array([ob.width for ob in movers], dtype=float)
        radius = 0.5 * np.hypot(length, width)
        step = (
            np.hypot(np.diff(table[:, 1]), np.diff(table[:, 2]))
            + np.abs(np.diff(heading)) * radius[owner[1:]]
        )
        travel = _cumsum_runs(np.where(same[1:], step, 0.0), same)
        return cls(
            length,
            width,
            radius,
            start,
            end,
            span,
            t + owner * span,
            table[:, 1],
            table[:, 2],
            heading,
            travel,
        )

    def _at(self, values: FloatArray, i: NDArray[np.intp], t: FloatArray) -> FloatArray:
        """``values`` of obstacles ``i`` at times ``t`` [s] (elementwise): linear in time, held at the
        ends."""
        return np.interp(np.clip(t, self.start[i], self.end[i]) + i * self.span, self.key, values)

    def travelled(self, i: NDArray[np.intp], a: FloatArray, b: FloatArray) -> FloatArray:
        """Bound on how far any point of obstacle ``i`` travels over ``[a, b]`` [m] (elementwise)."""
        return self._at(self.travel, i, b) - self._at(self.travel, i, a)

    def centres(self, i: NDArray[np.intp], t: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Centres ``(x, y)`` [m] of obstacles ``i`` at times ``t`` [s] (elementwise)."""
        return self._at(self.x, i, t), self._at(self.y, i, t)

    def geometry(self, i: Indices, t: FloatArray) -> Geometries:
        """The boxes of obstacles ``i`` at times ``t`` [s] (elementwise)."""
        x, y = self.centres(i, t)
        heading = self._at(self.heading, i, t)
        c, s = np.cos(heading), np.sin(heading)
        # as planner.collision.box_corners, each obstacle with its own length and width
        lx = np.array([-0.5, 0.5, 0.5, -0.5])[None, :] * self.length[i][:, None]
        ly = np.array([-0.5, -0.5, 0.5, 0.5])[None, :] * self.width[i][:, None]
        cx = x[:, None] + lx * c[:, None] - ly * s[:, None]
        cy = y[:, None] + lx * s[:, None] + ly * c[:, None]
        return np.asarray(shapely.polygons(np.stack((cx, cy), axis=-1)))


def _unwrap_runs(angle: FloatArray, same: NDArray[np.bool_]) -> FloatArray:
    """``np.unwrap`` of each run of rows (``same``: the row continues the one before), in one pass."""
    step = np.diff(angle)
    wrapped = np.mod(step + np.pi, 2.0 * np.pi) - np.pi
    wrapped[(wrapped == -np.pi) & (step > 0)] = np.pi
    correction = np.where(np.abs(step) < np.pi, 0.0, wrapped - step)
    return angle + _cumsum_runs(np.where(same[1:], correction, 0.0), same)


def _cumsum_runs(step: FloatArray, same: NDArray[np.bool_]) -> FloatArray:
    """The running sum of ``step`` (one per row after the first) restarting at 0 with each run."""
    total = np.concatenate(([0.0], np.cumsum(step)))
    run_start = np.maximum.accumulate(np.where(same, 0, np.arange(same.shape[0])))
    return np.asarray(total - total[run_start])
