"""Why a vehicle from behind still hits the answer: a typed reason, for the answer's diagnostics.

A follower (:func:`planner.st_bounds.followers`) that hits the returned trajectory is one the plan could
not keep ahead of. :func:`unescaped` says why, from the fastest profile within the limits along the same
path (:func:`planner.speed.escape`: towards the speed cap at the vehicle's acceleration, slowing only
where the path's curvature or a car's steering rate demand it) and what that profile broke:

* it is hit by the follower too: the follower closes faster than any acceleration within the limits can
  escape. Which limit holds it back, up to the contact: the path's limit (:attr:`FollowerReason.CURVATURE`)
  where the profile drove at it below the cap or braked for it, else the speed cap
  (:attr:`FollowerReason.SPEED_LIMIT`: ``options.speed_limit``, else the target speed, within
  ``max_speed``; the ego's speed when faster) where it is at the cap at the contact, else the vehicle's
  acceleration (:attr:`FollowerReason.ACCELERATION`);
* it gets away, but something ahead ranks first (:attr:`FollowerReason.AHEAD`): getting away would hit an
  obstacle ahead or break another check (a stop before a block, a leader, the road's end).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.problem import PlanningProblem, speed_cap
from planner.speed import Profile, speed_limit
from planner.trajectory import Path
from planner.validation import Violation, ViolationKind

#: a speed within this of a limit [m/s] counts as at the limit
_AT_LIMIT = 0.05
#: an acceleration below this [m/s²] counts as braking
_BRAKING = -1e-6


class FollowerReason(StrEnum):
    """Why a vehicle from behind cannot be kept behind the answer's trajectory."""

    #: the vehicle's acceleration cannot get away in time, below every speed limit
    ACCELERATION = "acceleration"
    #: getting away needs more than the speed cap (``options.speed_limit``, else the target speed)
    SPEED_LIMIT = "speed_limit"
    #: getting away needs more than the path's curvature (or a car's steering rate) allows ahead
    CURVATURE = "curvature"
    #: it could be got away from, but that would hit something ahead or break another check
    AHEAD = "ahead"

    @property
    def description(self) -> str:
        """The reason in words, as answers say it."""
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    FollowerReason.ACCELERATION: "it closes faster than the vehicle's acceleration can escape",
    FollowerReason.SPEED_LIMIT: "it closes faster than any acceleration within the speed limit can escape",
    FollowerReason.CURVATURE: "it closes faster than any acceleration within the curvature's speed limit "
    "ahead can escape",
    FollowerReason.AHEAD: "getting away from it would hit something ahead or break another check",
}


@dataclass(frozen=True)
class UnescapedFollower:
    """A vehicle from behind that hits the answer's trajectory as predicted, and why it is not escaped.

    Attributes:
        obstacle_id: the vehicle's id.
        t: the first time its predicted footprint meets the answer's [s].
        reason: why no trajectory within the limits keeps ahead of it.
    """

    obstacle_id: str
    t: float
    reason: FollowerReason


def first_hit_from_behind(bad: list[Violation], rear: set[str]) -> Violation | None:
    """The first of ``bad`` that is a hit by one of the vehicles behind (ids ``rear``), if any."""
    return next((v for v in bad if from_behind(v, rear)), None)


def from_behind(violation: Violation, rear: set[str]) -> bool:
    """Whether ``violation`` is a hit by one of the vehicles behind (ids ``rear``)."""
    return violation.kind is ViolationKind.HITS_MOVING_OBSTACLE and violation.obstacle_id in rear


def unescaped(
    hit: Violation,
    problem: PlanningProblem,
    path: Path,
    runaway: Profile,
    runaway_bad: list[Violation],
    config: PlannerConfig = DEFAULT_CONFIG,
) -> UnescapedFollower:
    """Why the follower of ``hit`` (a hit from behind of the answer) is not escaped, given the fastest
    profile within the limits along ``path``, ``runaway`` (:func:`planner.speed.escape`), and what its
    trajectory breaks, ``runaway_bad`` (see the module docstring)."""
    ob_id = str(hit.obstacle_id)
    t_hit = 0.0 if hit.t is None else float(hit.t)
    caught = next(
        (v for v in runaway_bad if v.kind is ViolationKind.HITS_MOVING_OBSTACLE and v.obstacle_id == ob_id),
        None,
    )
    if caught is None:
        return UnescapedFollower(ob_id, t_hit, FollowerReason.AHEAD)
    t_contact = t_hit if caught.t is None else caught.t
    until = runaway.t <= t_contact + 1e-9
    v, a = runaway.v[until], runaway.a[until]
    cap = max(speed_cap(problem), problem.ego.speed)
    limit = np.interp(runaway.s[until], path.sigma, speed_limit(path, problem, config, cap=np.inf))
    if np.any(((v >= limit - _AT_LIMIT) & (limit < cap - _AT_LIMIT)) | (a < _BRAKING)):
        return UnescapedFollower(ob_id, t_hit, FollowerReason.CURVATURE)
    if v[-1] >= cap - _AT_LIMIT:
        return UnescapedFollower(ob_id, t_hit, FollowerReason.SPEED_LIMIT)
    return UnescapedFollower(ob_id, t_hit, FollowerReason.ACCELERATION)
