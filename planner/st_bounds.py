"""Which obstacles stay put, and the space-time bounds the moving ones put on the speed profile.

A static obstacle (:func:`planner.collision.is_static`) bounds the path: the candidates' choice and the
lateral bounds keep clear of it. A moving one bounds the speed profile along the chosen path, as the
arc length ``σ`` [m] of the planned point (the vehicle's centre, a car's rear axle) along it at the
profile's knot times ``t_k`` [s]:

* the obstacles ahead of the ego at the start (a car on a side road: where it joins the road,
  :func:`_behind`): ``σ(t_k) ≤ σ_max(t_k)``, short of where the footprint (``obstacle_margin`` around
  it) first meets the obstacle's Frenet box as it was a ``headway`` earlier, less ``stop_gap``
  (:func:`space_time_bound`);
* the vehicles behind it (:func:`followers`): ``σ(t_k) ≥ σ_min(t_k)``, ahead of where the footprint meets
  the box at any time in ``[t_k, t_k + follower_headway]``, plus ``stop_gap`` (:func:`follower_bound`; a
  soft bound in the speed profile);
* crossing traffic (:func:`crossings`: ahead at the start, off the path then, across it later) is one of
  the obstacles ahead, unless the speed stage passes in front of it (:func:`planner.speed.pass_first`):
  then ``σ(t_k)`` is ahead of where the footprint meets its box over ``[t_k, t_k + headway]`` instead.

Only obstacles that come near the path at some time are mapped by TransF-κ (:meth:`Along.near`): in
dense traffic mapping the others would be most of the stage's cost.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray
from scipy.spatial import cKDTree
from shapely.geometry.base import BaseGeometry

from planner.collision import (
    Extent,
    box_corners,
    boxes_overlap,
    footprint_extent,
    is_static,
    obstacle_shape,
    prediction_at,
)
from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.frenet import to_frenet
from planner.problem import DynamicObstacle, PlanningProblem
from planner.reference import FloatArray, ReferenceLine
from planner.trajectory import Path

#: the last problem asked about and its obstacles' :func:`static_flags` (a plan asks several times; the
#: problem is frozen, so its identity is the key; one tuple, replaced whole: safe across threads)
_LAST_FLAGS: tuple[PlanningProblem | None, tuple[bool, ...]] = (None, ())


def static_flags(problem: PlanningProblem) -> tuple[bool, ...]:
    """Whether each of the problem's obstacles stays put over the horizon (:func:`is_static`), in order."""
    global _LAST_FLAGS
    last, flags = _LAST_FLAGS
    if last is problem:
        return flags
    horizon = problem.options.horizon_time
    flags = tuple(is_static(ob, horizon) for ob in problem.obstacles)
    _LAST_FLAGS = (problem, flags)
    return flags


def static_shapes(problem: PlanningProblem) -> list[tuple[str, BaseGeometry]]:
    """Outlines of the obstacles that stay put over the horizon (parked cars given as predictions too)."""
    pairs = zip(problem.obstacles, static_flags(problem), strict=True)
    return [(ob.id, obstacle_shape(ob)) for ob, static in pairs if static]


def moving_obstacles(problem: PlanningProblem) -> list[DynamicObstacle]:
    """The obstacles that move over the horizon: those the speed profile keeps clear of."""
    flags = static_flags(problem)
    return [
        ob
        for ob, static in zip(problem.obstacles, flags, strict=True)
        if isinstance(ob, DynamicObstacle) and not static
    ]


@dataclass(frozen=True)
class SpaceTimeBounds:
    """Bounds on the arc length along the path [m] at the speed profile's knot times, each None when
    nothing bounds it: ``upper`` from the obstacles ahead, ``lower`` (soft) from the vehicles behind."""

    upper: FloatArray | None
    lower: FloatArray | None


def space_time_bounds(
    ref: ReferenceLine,
    path: Path,
    problem: PlanningProblem,
    t: FloatArray,
    start_s: float,
    config: PlannerConfig = DEFAULT_CONFIG,
    passing: Collection[str] = (),
) -> SpaceTimeBounds:
    """Both bounds at the knot times ``t`` [s] (evenly spaced, at least two) for an ego at ``start_s`` [m],
    with their ``stop_gap``; the obstacles whose ids are in ``passing`` (overtaken by a lane decision that
    borrows the road, :mod:`planner.decision`) are not followed."""
    movers = moving_obstacles(problem)
    if not movers:
        return SpaceTimeBounds(None, None)
    speed, gap = config.speed, config.stop_gap
    along = Along.of(ref, path, problem, config)
    # Each bound maps only its own (the same split both make themselves: :func:`_behind`): the leaders
    # ahead of the ego at the start, the followers behind it.
    behind = _behind(ref, movers, start_s)
    # where an obstacle was a headway ago, not where it is: a gap that grows with its speed
    leaders = _leaders(movers, behind, passing)
    upper = space_time_bound(along, leaders, np.maximum(t - speed.headway, 0.0), start_s) if leaders else None
    rear = [ob for ob, back in zip(movers, behind, strict=True) if back]
    lower = (
        follower_bound(along, rear, t, speed.follower_headway, start_s, problem.ego.speed) if rear else None
    )
    return SpaceTimeBounds(
        upper=None if upper is None else np.maximum(upper - gap, 0.0),
        lower=None if lower is None else lower + gap,
    )


@dataclass(frozen=True)
class Along:
    """The path as the moving obstacles' bounds see it: its knots in a k-d tree for the near-the-path
    filter, and the footprint's extent on them [m] (from the planned point, aligned with the reference,
    with ``obstacle_margin`` around it)."""

    ref: ReferenceLine
    path: Path
    tree: cKDTree
    extent: Extent
    knot_spacing: float

    @classmethod
    def of(cls, ref: ReferenceLine, path: Path, problem: PlanningProblem, config: PlannerConfig) -> Along:
        extent = footprint_extent(np.zeros_like(path.s), problem.vehicle, config.obstacle_margin)
        tree = cKDTree(np.column_stack((path.x, path.y)))
        return cls(ref, path, tree, extent, config.lateral.knot_spacing)

    def near(
        self, movers: list[DynamicObstacle], t: FloatArray
    ) -> tuple[NDArray[np.intp], list[FloatArray], NDArray[np.bool_]]:
        """Which of ``movers`` come near the path at some time of ``t`` [s], every mover's states then
        (shape (T, 3) each) and when each is near (shape (len(movers), T)). "Near": the obstacle's
        centre within twice the reach of the footprint (its half-diagonal) and of the obstacle itself
        (its diagonal, twice its half-diagonal), plus a knot spacing (generous: a Frenet box may be
        larger than the shape it bounds); a box not near cannot meet the footprint, so it need not be
        mapped (:func:`frenet_extents`' ``mapped``). Each obstacle's reach is its own: a bus among the
        movers does not make every car's reach a bus's (in dense traffic most of the mapping would
        then be of cars on other roads), and which obstacles a bound is given changes no verdict."""
        states = [prediction_at(ob, t) for ob in movers]
        ext = self.extent
        own = float(np.hypot(max(ext.front[0], ext.back[0]), max(ext.left[0], ext.right[0])))
        diagonal = np.hypot([ob.length for ob in movers], [ob.width for ob in movers])
        reach = 2.0 * (own + diagonal) + self.knot_spacing  # [m], per mover
        # one query out to the largest reach, then each mover's own
        dist, _ = self.tree.query(np.concatenate(states)[:, :2], distance_upper_bound=float(reach.max()))
        close = np.asarray(dist).reshape(len(movers), -1) <= reach[:, None]
        return np.flatnonzero(close.any(axis=1)), states, close

    def meets(self, boxes: tuple[FloatArray, FloatArray, FloatArray, FloatArray]) -> NDArray[np.bool_]:
        """Whether the footprint on each knot meets each obstacle's box at each time: ``boxes`` are
        :func:`frenet_extents` (each (K, T)); the answer has shape (K, T, knots)."""
        s_min, s_max, d_min, d_max = (b[..., None] for b in boxes)
        s, d = self.path.s[None, None, :], self.path.d[None, None, :]
        return boxes_overlap(s, d, self.extent, s_min, s_max, d_min, d_max)


def space_time_bound(
    along: Along, movers: list[DynamicObstacle], t: FloatArray, start_s: float
) -> FloatArray | None:
    """``σ_max(t_k)`` [m]: how far along the path the vehicle's centre may be at each time so that its
    footprint stays clear of every moving obstacle's box (follow or yield). Obstacles behind the ego
    at the start (:func:`_behind`) are not followed: one coming from behind is the follower's to avoid
    (braking for it as it overtakes would invite a rear-end collision)."""
    times, at = np.unique(t, return_inverse=True)  # each time once (a headway ago is 0 for the first few)
    near, states, close = along.near(movers, times)
    if near.size == 0:
        return None
    chosen = [movers[k] for k in near]
    extents = frenet_extents(along.ref, chosen, [states[k] for k in near], close[near])
    boxes = (extents[0][:, at], extents[1][:, at], extents[2][:, at], extents[3][:, at])  # (K, T) each
    ahead = ~_behind(along.ref, chosen, start_s)[:, None]
    hit = along.meets(boxes)
    sigma = along.path.sigma
    first = np.where(hit.any(axis=2), np.argmax(hit, axis=2), -1)
    limit = np.where(first > 0, sigma[np.maximum(first - 1, 0)], np.where(first == 0, 0.0, np.inf))
    limit = np.where(ahead, limit, np.inf)
    return np.asarray(limit.min(axis=0))


def frenet_extents(
    ref: ReferenceLine,
    movers: list[DynamicObstacle],
    states: list[FloatArray],
    mapped: NDArray[np.bool_] | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """``(s_min, s_max, d_min, d_max)`` [m], each shape (K, T): the Frenet boxes of the K obstacles at their
    states ``states[k]`` (shape (T, 3)), from corners and edge midpoints mapped by TransF-κ in one call;
    only where ``mapped`` (shape (K, T); None: everywhere) says so, NaN elsewhere (a NaN box meets
    nothing: :func:`planner.collision.boxes_overlap`)."""
    outlines = []
    for ob, st in zip(movers, states, strict=True):
        corners = box_corners(st[:, 0], st[:, 1], st[:, 2], ob.length, ob.width)  # (T, 4, 2)
        outlines.append(np.concatenate((corners, 0.5 * (corners + np.roll(corners, -1, axis=1))), axis=1))
    pts = np.stack(outlines)  # (K, T, 8, 2)
    if mapped is None or bool(mapped.all()):
        fr = to_frenet(ref, pts.reshape(-1, 2))
        s_box = fr.s.reshape(pts.shape[:3])
        d_box = fr.d.reshape(pts.shape[:3])
    else:
        s_box = np.full(pts.shape[:3], np.nan)
        d_box = np.full(pts.shape[:3], np.nan)
        if mapped.any():
            fr = to_frenet(ref, pts[mapped].reshape(-1, 2))
            s_box[mapped] = fr.s.reshape(-1, pts.shape[2])
            d_box[mapped] = fr.d.reshape(-1, pts.shape[2])
    return s_box.min(axis=2), s_box.max(axis=2), d_box.min(axis=2), d_box.max(axis=2)


#: how near the reference line [m] (a mover's centre to its nearest sample) a mover must be for where it
#: is then to say whether it is ahead of the ego or behind it (:func:`_behind`): about two lanes
JOIN_REACH = 8.0
#: the times [s] at which :func:`_behind` looks for where a mover that starts farther out joins the road
JOIN_TIMES = np.arange(0.0, 8.0 + 1e-9, 0.5)

#: the last reference and ego position asked about, and the verdicts of :func:`_behind` there, by
#: obstacle (its identity; the obstacle kept beside it): a plan asks for them several times (the
#: candidates' reach, both space-time bounds, the fallback). Replaced whole for another reference or
#: position; each verdict depends on its obstacle alone.
_LAST_BEHIND: tuple[ReferenceLine | None, float, dict[int, tuple[DynamicObstacle, bool]]] = (None, 0.0, {})


def _behind(ref: ReferenceLine, movers: list[DynamicObstacle], start_s: float) -> NDArray[np.bool_]:
    """Which of ``movers`` are behind the ego at the start: the middle of their Frenet box at or behind the
    ego's ``start_s`` [m] where they join the road — at ``t = 0``, or for one farther than
    :data:`JOIN_REACH` from the reference line then, the first of :data:`JOIN_TIMES` it comes that near
    (a car on a side road, whose projection says nothing of where it will be, turning in behind the ego
    is a follower; one that never comes near is judged where it is) — exactly those
    :func:`space_time_bound` does not follow."""
    global _LAST_BEHIND
    if not movers:
        return np.zeros(0, dtype=bool)
    last_ref, last_s, known = _LAST_BEHIND
    if last_ref is not ref or last_s != start_s:
        known = {}
        _LAST_BEHIND = (ref, start_s, known)
    new = [ob for ob in movers if known.get(id(ob), (None, False))[0] is not ob]
    if new:
        s_min, s_max, _, _ = frenet_extents(ref, new, _joining_poses(ref, new))
        ahead = (0.5 * (s_min[:, 0] + s_max[:, 0]) > start_s) | (s_min[:, 0] > start_s)
        known.update((id(ob), (ob, not bool(front))) for ob, front in zip(new, ahead, strict=True))
    return np.array([known[id(ob)][1] for ob in movers], dtype=bool)


def _joining_poses(ref: ReferenceLine, movers: list[DynamicObstacle]) -> list[FloatArray]:
    """Per mover, its pose (shape (1, 3)) where it joins the road: at the first of :data:`JOIN_TIMES` its
    centre is within :data:`JOIN_REACH` of a sample of the reference line (at t = 0 when it is then or
    never comes that near)."""
    poses = np.stack([prediction_at(ob, JOIN_TIMES) for ob in movers])  # (K, T, 3)
    dist, _ = ref.tree.query(poses[..., :2].reshape(-1, 2), distance_upper_bound=JOIN_REACH)
    near = np.isfinite(np.asarray(dist)).reshape(poses.shape[:2])
    first = np.where(near[:, 0] | ~near.any(axis=1), 0, np.argmax(near, axis=1))
    return [pose[k : k + 1] for pose, k in zip(poses, first, strict=True)]


def _leaders(
    movers: list[DynamicObstacle], behind: NDArray[np.bool_], passing: Collection[str]
) -> list[DynamicObstacle]:
    """The movers the space-time bound follows: those not ``behind`` the ego at the start
    (:func:`_behind`), nor overtaken (``passing``)."""
    return [ob for ob, back in zip(movers, behind, strict=True) if not back and ob.id not in passing]


def followers(ref: ReferenceLine, movers: list[DynamicObstacle], start_s: float) -> list[DynamicObstacle]:
    """The moving obstacles behind the ego at the start (see :func:`_behind`)."""
    return [ob for ob, behind in zip(movers, _behind(ref, movers, start_s), strict=True) if behind]


def follower_bound(
    along: Along,
    movers: list[DynamicObstacle],
    t: FloatArray,
    headway: float,
    start_s: float,
    ego_speed: float,
) -> FloatArray | None:
    """``σ_min(t_k)`` [m] at the knot times ``t`` (evenly spaced) [s]: how far along the path the
    vehicle's centre must be for its footprint to be ahead of the boxes of the moving obstacles behind it
    at the start (:func:`followers`) at every time in ``[t_k, t_k + headway]`` (``headway`` [s] rounded up
    to the knot spacing); ``−inf`` where free, ``None`` when free throughout.

    A vehicle bounds from the first time its box meets the footprint anywhere along the path, if it is
    then behind where the ego would be at its current speed ``ego_speed`` [m/s], and for as long as it
    keeps meeting it: one that enters the path ahead (a cut-in after overtaking) or comes back after
    leaving it is not chased. At each time the bound is the knot after the last one whose footprint it
    meets.
    """
    window = int(np.ceil(headway / float(t[1] - t[0]) - 1e-9))  # steps of the headway; t: ≥ 2 times
    t = t[0] + (t[1] - t[0]) * np.arange(t.size + window)  # the knots and the headway beyond them
    near, states, close = along.near(movers, t)
    chosen = near[_behind(along.ref, [movers[k] for k in near], start_s)]
    if chosen.size == 0:
        return None
    boxes = frenet_extents(along.ref, [movers[k] for k in chosen], [states[k] for k in chosen], close[chosen])
    s_max = boxes[1]
    hit = along.meets(boxes)  # (K, T, knots)
    meets = hit.any(axis=2)  # (K, T)
    first = np.argmax(meets, axis=1)
    rows = np.arange(meets.shape[0])
    behind_then = s_max[rows, first] <= start_s + max(ego_speed, 0.0) * t[first]
    after = np.arange(meets.shape[1])[None, :] >= first[:, None]
    active = meets & ~(np.cumsum(after & ~meets, axis=1) > 0) & behind_then[:, None]  # the first run only
    if not active.any():
        return None
    last = hit.shape[2] - 1 - np.argmax(hit[..., ::-1], axis=2)  # last knot met, (K, T)
    at = np.where(active, along.path.sigma[np.minimum(last + 1, hit.shape[2] - 1)], -np.inf).max(axis=0)
    bound = sliding_window_view(at, window + 1).max(axis=1)  # the most ahead over each [t_k, t_k + headway]
    return np.asarray(bound)


def _crosses_over(along: Along, pose: FloatArray, nearest: NDArray[np.intp], half_width: float) -> bool:
    """Whether an obstacle at ``pose`` (its centre and heading at successive times, shape (T, 3)), with
    each centre's nearest knot ``nearest``, is clear of the footprint on one side of the path and later
    clear of it on the other: its centre's signed distance from the knot, across the path's heading,
    beyond the footprint's half width on that side plus the obstacle's ``half_width`` [m] (crossing
    traffic at any angle; a car merging into the lane stays on its side)."""
    if pose.shape[0] < 2:
        return False
    heading = along.path.heading[nearest]
    dx = pose[:, 0] - along.path.x[nearest]
    dy = pose[:, 1] - along.path.y[nearest]
    across = np.cos(heading) * dy - np.sin(heading) * dx  # left of the path: positive
    left = across > float(along.extent.left[0]) + half_width
    right = -across > float(along.extent.right[0]) + half_width
    if not (left.any() and right.any()):
        return False
    first_left, first_right = int(np.argmax(left)), int(np.argmax(right))
    # on one side first, and on the other after it
    return bool(right[first_left:].any() if first_left < first_right else left[first_right:].any())


@dataclass(frozen=True)
class Crossing:
    """A moving obstacle ahead of the ego that is off the path at the start and crosses it later (at
    least ``crossing_angle`` off the path's heading where it first meets the footprint): its ``id`` and
    ``before`` [m], at the profile's knot times, how far along the path the planned point must be to pass
    in front of it — ahead of where the footprint meets its box at any time in ``[t_k, t_k + headway]``
    while it is on the path (its first run there), plus ``stop_gap``; ``−inf`` where free, ``+inf`` where
    its box reaches the path's end. ``least``: the same with ``follower_headway`` in place of
    ``headway`` (the least a profile that passes in front of it must keep)."""

    id: str
    before: FloatArray
    least: FloatArray


def crossings(
    ref: ReferenceLine,
    path: Path,
    problem: PlanningProblem,
    t: FloatArray,
    start_s: float,
    config: PlannerConfig = DEFAULT_CONFIG,
    passing: Collection[str] = (),
) -> list[Crossing]:
    """The moving obstacles the vehicle may pass in front of (:class:`Crossing`) at the knot times ``t``
    [s] (evenly spaced, at least two) for an ego at ``start_s`` [m]: those :func:`space_time_bound`
    follows (ahead at the start, not in ``passing``) whose box does not meet the footprint anywhere along
    the path at the start but does later, first at ``crossing_angle`` or more to the path's heading
    there, or at any angle if it goes from clear of the footprint on one side of the path to clear of it
    on the other (:func:`_crosses_over`) — crossing or oncoming traffic, not one merging into the lane.
    Whether passing first is possible is the speed stage's to decide (:func:`planner.speed.speed_stage`)."""
    movers = moving_obstacles(problem)
    if not movers:
        return []
    leaders = _leaders(movers, _behind(ref, movers, start_s), passing)
    if not leaders:
        return []
    speed = config.speed
    along = Along.of(ref, path, problem, config)
    window = int(np.ceil(speed.headway / float(t[1] - t[0]) - 1e-9))
    short = min(int(np.ceil(speed.follower_headway / float(t[1] - t[0]) - 1e-9)), window)
    times = t[0] + (t[1] - t[0]) * np.arange(t.size + window)  # the knots and the headway beyond them
    near, states, close = along.near(leaders, times)
    cos_limit = float(np.cos(speed.crossing_angle))
    # Only those that come within reach of the footprint at an angle to the path somewhere, or cross over
    # it, are mapped (in dense traffic along the road, or beside it the other way, mapping the others would
    # be most of the cost): their heading against the nearest knot's where their centre is within both
    # half-diagonals and a knot spacing of it (one never that close is yielded to, as any obstacle ahead).
    ext = along.extent
    own = float(np.hypot(max(ext.front[0], ext.back[0]), max(ext.left[0], ext.right[0])))
    across: list[int] = []
    over: set[int] = set()
    for k in near:
        pose = states[k][close[k]]
        dist, nearest = along.tree.query(pose[:, :2])
        reach = own + 0.5 * float(np.hypot(leaders[k].length, leaders[k].width)) + along.knot_spacing
        angled = np.cos(pose[:, 2] - along.path.heading[nearest]) <= cos_limit
        crosses = _crosses_over(along, pose, np.asarray(nearest, dtype=np.intp), 0.5 * leaders[k].width)
        if crosses or np.any(angled & (dist <= reach)):
            across.append(k)
        if crosses:
            over.add(int(k))
    if not across:
        return []
    near = np.asarray(across, dtype=np.intp)
    mapped = close[near]
    mapped[:, 0] = True  # where each is at the start: on the path or not
    chosen = [leaders[k] for k in near]
    boxes = frenet_extents(ref, chosen, [states[k] for k in near], mapped)
    hit = np.asarray(along.meets(boxes), dtype=bool)  # (K, T, knots)
    meets = np.asarray(hit.any(axis=2), dtype=bool)
    out: list[Crossing] = []
    for k, ob in enumerate(chosen):
        if meets[k, 0] or not meets[k].any():
            continue
        first = int(np.argmax(meets[k]))
        knot = int(np.argmax(hit[k, first]))
        heading = float(states[near[k]][first, 2])
        if float(np.cos(heading - along.path.heading[knot])) > cos_limit and int(near[k]) not in over:
            continue  # it runs along the path there: one merging in front is followed, not raced
        run = np.arange(meets.shape[1]) >= first
        run &= ~(np.cumsum(run & ~meets[k]) > 0)  # its first run on the path only
        last = hit.shape[2] - 1 - np.argmax(hit[k, :, ::-1], axis=1)  # the last knot met at each time
        ahead = along.path.sigma[np.minimum(last + 1, hit.shape[2] - 1)]
        at = np.where(run, np.where(last + 1 < hit.shape[2], ahead, np.inf), -np.inf)
        before = sliding_window_view(at, window + 1).max(axis=1) + config.stop_gap
        least = sliding_window_view(at[: t.size + short], short + 1).max(axis=1) + config.stop_gap
        out.append(Crossing(ob.id, np.asarray(before), np.asarray(least)))
    return out
