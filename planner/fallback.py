"""The fallback: when a stage fails or its trajectory breaks a check, brake safely along the best path known.

Full braking within the emergency jerk is tried along the optimised path, then along the chosen
candidate, then straight on at the ego's offset (no steering while it stops); the first braking
trajectory that passes every check is taken, else the one that breaks the fewest.

Braking into a vehicle coming from behind is never better than keeping the speed: when a braking
trajectory is hit from behind (a :attr:`~planner.validation.ViolationKind.HITS_MOVING_OBSTACLE` of one
of :func:`planner.st_bounds.followers`), the planned profile (which may have slowed for a leader's
headway only) and keeping the speed are weighed too. The first that passes every check is taken; else
the least severe (:func:`severity`), on a tie these before braking (a harder stop gives the follower
less time).
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

from shapely.geometry.base import BaseGeometry

from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.ego import EgoFrenet
from planner.lateral import held_offset, knots
from planner.problem import PlanningProblem
from planner.reference import ReferenceLine
from planner.speed import Profile, ProfileKind, braking, profile_grid
from planner.st_bounds import followers, moving_obstacles
from planner.trajectory import Path, Trajectory
from planner.validation import HITS, Violation, ViolationKind, trajectory_violations
from solvers.speed_problem import SpeedResult


@dataclass(frozen=True)
class Fallback:
    """The fallback's answer: the trajectory, what it still breaks, why (the message) and its profile."""

    trajectory: Trajectory
    violations: tuple[Violation, ...]
    message: str
    profile: ProfileKind


def severity(bad: Collection[Violation], rear: Collection[str]) -> tuple[int, int, int]:
    """How bad a trajectory's violations ``bad`` are, to compare fallbacks: hits of obstacles other than
    the vehicles behind (ids ``rear``), then hits from behind, then the other checks (curvature, lane, …,
    which do not hit anything by themselves)."""
    hits = [v for v in bad if v.kind in HITS]
    from_behind = sum(_from_behind(v, rear) for v in hits)
    return len(hits) - from_behind, from_behind, len(bad) - len(hits)


def _from_behind(violation: Violation, rear: Collection[str]) -> bool:
    return violation.kind is ViolationKind.HITS_MOVING_OBSTACLE and violation.obstacle_id in rear


def fallback(
    reason: str,
    path: Path,
    candidate: Path,
    ref: ReferenceLine,
    problem: PlanningProblem,
    start: EgoFrenet,
    static: list[tuple[str, BaseGeometry]],
    planned: SpeedResult | None = None,
    config: PlannerConfig = DEFAULT_CONFIG,
    borrowing: bool = False,
) -> Fallback:
    """The fallback for ``reason``, along ``path`` (the best path known), the chosen ``candidate`` and
    the ego's offset; ``planned`` is the SQP's profile along ``path``, weighed when braking is hit from
    behind (if it is a solution). ``static`` are the static obstacles' outlines; ``borrowing``: the lane
    decision borrows the road (the checks then keep the footprint in the road, not the lane)."""
    options = problem.options
    steps, dt = profile_grid(options, config.speed)
    hold = held_offset(ref, knots(ref, start, float(candidate.s[-1]), config.lateral), start.d)
    tried: list[tuple[Trajectory, list[Violation]]] = []
    for option in _distinct(path, candidate, hold):
        profile = braking(option, problem, steps, dt, config.speed)
        traj = profile.sample(option, options.dt, ref, problem.vehicle)
        bad = trajectory_violations(ref, problem, traj, static, borrowing=borrowing)
        tried.append((traj, bad))
        if not bad:
            break
    traj, bad = min(tried, key=lambda tb: len(tb[1]))
    if not bad:
        return Fallback(traj, (), reason, ProfileKind.BRAKING)
    message = f"{reason}; the braking trajectory still breaks: {bad[0]}"
    rear = {ob.id for ob in followers(ref, moving_obstacles(problem), start.s)}
    hit_from_behind = [v for _, b in tried for v in b if _from_behind(v, rear)]
    if not hit_from_behind:
        return Fallback(traj, tuple(bad), message, ProfileKind.BRAKING)
    others: list[tuple[str, Profile]] = []
    if planned is not None and planned.info.usable:
        others.append(("the planned profile", Profile.optimised(planned)))
    others.append(("keeping the speed", braking(path, problem, steps, dt, config.speed, keep_speed=True)))
    weighed: list[tuple[str, Profile | None, Trajectory, list[Violation]]] = []
    for label, profile in others:
        alt = profile.sample(path, options.dt, ref, problem.vehicle)
        alt_bad = trajectory_violations(ref, problem, alt, static, borrowing=borrowing)
        weighed.append((label, profile, alt, alt_bad))
        if not alt_bad:
            break
    weighed += [("braking", None, tr, b) for tr, b in tried]
    label, chosen, traj, bad = min(weighed, key=lambda c: severity(c[3], rear))
    if chosen is None:
        return Fallback(traj, tuple(bad), message, ProfileKind.BRAKING)
    message = f"{reason}; braking is hit from behind ({hit_from_behind[0]}): {label} instead"
    if bad:
        message += f", which still breaks: {bad[0]}"
    return Fallback(traj, tuple(bad), message, chosen.kind)


def _distinct(*paths: Path) -> list[Path]:
    """``paths`` without repeats of the same object (the best path known may be the candidate)."""
    out: list[Path] = []
    for p in paths:
        if not any(p is q for q in out):
            out.append(p)
    return out
