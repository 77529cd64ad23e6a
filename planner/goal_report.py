"""The judgement of a returned trajectory against the request's goal (:class:`planner.goal.GoalReport`).

At each sample of the trajectory the goal holds when every part given holds (:mod:`planner.goal`): the
centre ``(x, y)`` inside the region, ``t`` in the window, ``v`` in the speed range. The first sample where
it holds makes the goal ``reached``. Otherwise:

* what the plan knew before planning (:class:`planner.goal_plan.GoalBlock`: the window ended, the speed
  range above the limit, the region behind, off the lane, or too far to reach in the window) makes it
  ``unreachable`` for that reason;
* a ``fallback`` answer's trajectory does not meet it: ``fallback``;
* inside the region, but only before the window opens: ``too_early``; only after it closes: ``too_far``;
  in the window but never at a speed in the range: ``speed_range`` — unless the vehicle is still inside
  at the horizon's end and the window is still open (``on_the_way``);
* never inside: past the region beside it, ``missed``; standing before it at the horizon's end, or stopping
  before a block that comes before the region's entry (a block beyond it leaves the region on the way),
  ``blocked``; a window that closes within the horizon, ``missed`` when the centre is
  along the region (its ``s`` at least the region's ``s_in``) but beside it then, else ``too_far``; else
  ``on_the_way``.

Without a region: a window that closes within the horizon and a speed range never met in it,
``speed_range``; no sample in a window within the horizon, ``missed``; else ``on_the_way``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from planner.goal import SPEED_TOLERANCE, GoalReason, GoalReport, GoalStatus
from planner.goal_plan import GoalSetup
from planner.goal_region import inside
from planner.trajectory import Trajectory

#: sample times within this of a window's end are in it [s]
TIME_TOLERANCE = 1e-9
#: a vehicle slower than this at the horizon's end stands [m/s]
STANDING = 0.05


def goal_holds(
    setup: GoalSetup, traj: Trajectory
) -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
    """Per sample of ``traj``: whether the centre is inside the region, ``t`` in the window and ``v`` in the
    speed range (each all True when that part is not given)."""
    goal = setup.goal
    yes = np.ones(traj.size, dtype=bool)
    place = yes if goal.position is None else inside(goal.position, traj.x, traj.y)
    when = yes
    if goal.time is not None:
        when = (traj.t >= goal.time[0] - TIME_TOLERANCE) & (traj.t <= goal.time[1] + TIME_TOLERANCE)
    pace = yes
    if goal.speed is not None:
        pace = (traj.v >= goal.speed[0] - SPEED_TOLERANCE) & (traj.v <= goal.speed[1] + SPEED_TOLERANCE)
    return np.asarray(place), np.asarray(when), np.asarray(pace)


def judge(setup: GoalSetup, traj: Trajectory, *, fallback: bool, stop_s: float | None = None) -> GoalReport:
    """What ``traj`` does with the goal (see the module docstring); ``fallback``: the answer is one,
    ``stop_s``: the plan stops before a block, its centre at this arc length on the reference at most [m]
    (None: no block)."""
    place, when, pace = goal_holds(setup, traj)
    met = np.flatnonzero(place & when & pace)
    if met.size:
        t = float(traj.t[met[0]])
        return GoalReport(GoalStatus.REACHED, f"reached at t = {t:.2f} s", t=t)
    if setup.block is not None:
        return _unreachable(setup.block.reason, setup.block.message)
    if fallback:
        return _unreachable(
            GoalReason.FALLBACK, "the plan fell back: its braking trajectory does not meet the goal"
        )
    goal, horizon = setup.goal, float(traj.t[-1])
    open_after = goal.time is None or goal.time[1] > horizon + TIME_TOLERANCE
    if goal.position is None:
        if open_after:
            return _on_the_way(f"the window ends after the horizon ({horizon:.1f} s)")
        if not when.any():
            return _unreachable(GoalReason.MISSED, "no sample of the trajectory lies in the window")
        return _unreachable(GoalReason.SPEED_RANGE, "the speed is never in the range during the window")
    if place.any():
        return _inside_but(setup, traj, place, when, open_after)
    region = setup.region
    if region is not None and float(np.max(traj.s)) > region.s_max:
        return _unreachable(GoalReason.MISSED, "the trajectory passes beside the region")
    # a block beyond the region's entry stops the vehicle only after it has been inside
    before = stop_s is not None and (region is None or not stop_s >= region.s_in)
    if before or traj.v[-1] < STANDING:
        where = stop_s if stop_s is not None and before else float(traj.s[-1])
        gap = "" if region is None else f", {region.s_in - where:.1f} m before the region"
        return _unreachable(GoalReason.BLOCKED, f"the vehicle stops before the region{gap}")
    if not open_after:
        assert goal.time is not None  # for mypy: a window closes
        closes = int(np.searchsorted(traj.t, goal.time[1] + TIME_TOLERANCE, side="right")) - 1
        if region is not None and region.reachable and closes >= 0 and float(traj.s[closes]) >= region.s_in:
            # far enough along when the window closes, but beside the region: the lateral plan's miss
            return _unreachable(
                GoalReason.MISSED, f"beside the region when the window closes (t = {goal.time[1]:.1f} s)"
            )
        return _unreachable(GoalReason.TOO_FAR, f"not inside the region by t = {goal.time[1]:.1f} s")
    return _on_the_way("the horizon ends before the region")


def _inside_but(
    setup: GoalSetup,
    traj: Trajectory,
    place: NDArray[np.bool_],
    when: NDArray[np.bool_],
    open_after: bool,
) -> GoalReport:
    """The report of a trajectory that is inside the region at some sample, never meeting the goal."""
    goal = setup.goal
    still = bool(place[-1]) and open_after
    times = traj.t[place]
    if goal.time is not None and not (place & when).any():
        if still:
            return _on_the_way(f"inside the region, the window opens at t = {goal.time[0]:.1f} s")
        if times[-1] < goal.time[0]:
            return _unreachable(
                GoalReason.TOO_EARLY,
                f"inside the region from t = {times[0]:.2f} to {times[-1]:.2f} s, before the window opens",
            )
        return _unreachable(
            GoalReason.TOO_FAR, f"inside the region from t = {times[0]:.2f} s, after the window closes"
        )
    if still:
        return _on_the_way("inside the region, not yet at a speed in the range")
    speeds = traj.v[place & when]
    return _unreachable(
        GoalReason.SPEED_RANGE,
        f"inside the region at {speeds.min():.2f}–{speeds.max():.2f} m/s, outside the speed range",
    )


def _unreachable(reason: GoalReason, message: str) -> GoalReport:
    return GoalReport(GoalStatus.UNREACHABLE, message, reason=reason)


def _on_the_way(message: str) -> GoalReport:
    return GoalReport(GoalStatus.ON_THE_WAY, message)
