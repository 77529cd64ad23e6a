"""The end of one plan along a lateral plan: the speed profile, the trajectory and its checks, the answer —
or, where a stage fails or the trajectory breaks a check, the fallback (:mod:`planner.fallback`).

:class:`Run` is what a plan has gathered for its answer (the reference, the start, the candidates, the
timer, the lane decision); :func:`drive` runs the last stages along one lateral plan and says what
became of it (:class:`Driven`); :mod:`planner.pipeline` drives the lane's plan, or a borrow's, and
takes the first that passes.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from shapely.geometry.base import BaseGeometry

from planner.candidates import CandidateSet
from planner.config import PlannerConfig
from planner.decision import KEEP_LANE, Decision
from planner.ego import EgoFrenet
from planner.fallback import fallback
from planner.follower import UnescapedFollower
from planner.goal_plan import GoalSetup, speed_aim
from planner.goal_report import judge
from planner.lateral import LateralPlan
from planner.problem import PlanningProblem
from planner.reference import ReferenceLine
from planner.result import NOT_RUN, CandidateStats, PlanDiagnostics, PlanResult, Status
from planner.speed import Profile, ProfileKind, SpeedPlan, speed_stage
from planner.thread_solvers import Solvers
from planner.timing import StageTimer
from planner.trajectory import Path, Trajectory
from planner.validation import Violation, trajectory_violations
from solvers.result import SolveInfo
from solvers.speed_problem import SpeedResult

__all__ = ["Driven", "Run", "drive"]


@dataclass(frozen=True)
class Run:
    """What a plan has gathered for its answer: the inputs the fallback needs and the diagnostics so far."""

    ref: ReferenceLine
    problem: PlanningProblem
    start: EgoFrenet
    static: list[tuple[str, BaseGeometry]]
    cands: CandidateSet
    best: int
    stats: CandidateStats
    timer: StageTimer
    config: PlannerConfig
    goal: GoalSetup | None = None
    knots: int = 0
    decision: Decision = KEEP_LANE

    def fallback(
        self,
        reason: str,
        path: Path,
        candidate: Path,
        lateral: SolveInfo = NOT_RUN,
        speed: SolveInfo = NOT_RUN,
        planned: SpeedResult | None = None,
    ) -> PlanResult:
        """The fallback answer for ``reason`` (see :func:`planner.fallback.fallback`)."""
        with self.timer.stage("fallback"):
            out = fallback(
                reason,
                path,
                candidate,
                self.ref,
                self.problem,
                self.start,
                self.static,
                planned,
                self.config,
                self.decision.borrows,
            )
        return self.result(
            "fallback",
            out.message,
            out.trajectory,
            lateral,
            speed,
            out.profile,
            out.violations,
            follower=out.follower,
        )

    def result(
        self,
        status: Status,
        message: str,
        traj: Trajectory,
        lateral: SolveInfo,
        speed: SolveInfo,
        profile: ProfileKind,
        violations: tuple[Violation, ...] = (),
        stop_s: float | None = None,
        follower: UnescapedFollower | None = None,
    ) -> PlanResult:
        """The answer, what it does with the goal (``stop_s``: it stops before a block, the footprint's
        centre at this arc length [m] at most), its diagnostics timed up to now."""
        report = None
        if self.goal is not None:
            report = judge(self.goal, traj, fallback=status == "fallback", stop_s=stop_s)
        timing = self.timer.timing_ms()
        diag = PlanDiagnostics(
            self.stats,
            lateral,
            speed,
            timing,
            self.ref.size,
            self.knots,
            self.best,
            profile,
            report,
            follower,
            self.decision,
        )
        cands = self.cands if self.problem.options.return_candidates else None
        return PlanResult(status, message, traj, cands, diag, violations)


@dataclass(frozen=True)
class Driven:
    """The end of a plan along a lateral plan: its answer (``result``), or why it fails and what its
    fallback needs (``fallback``, the arguments of :meth:`Run.fallback` after the reason); ``overrun``
    when the time budget ended it."""

    result: PlanResult | None
    reason: str = ""
    fallback: tuple[Path, Path, SolveInfo, SolveInfo, SpeedResult | None] | None = None
    overrun: bool = False

    def answer(self, run: Run) -> PlanResult:
        """The answer: the plan's, or ``run``'s fallback for it."""
        if self.result is not None:
            return self.result
        if self.fallback is None:
            raise ValueError("a failed plan without what its fallback needs")  # a bug of drive
        path, candidate, lateral, speed, planned = self.fallback
        return run.fallback(self.reason, path, candidate, lateral, speed, planned)


def drive(run: Run, solvers: Solvers, lateral: LateralPlan, candidate: Path) -> Driven:
    """The speed profile along ``lateral``'s path, the trajectory and its checks (the decision of ``run``:
    the overtaken vehicles, the road or the lane to keep to): the answer, or why it fails."""
    timer, decision, start = run.timer, run.decision, run.start
    run = replace(run, knots=lateral.knots)
    if lateral.path is None:
        failed = f"lateral QP failed: {lateral.info.status}"
        return Driven(None, failed, (candidate, candidate, lateral.info, NOT_RUN, None))
    path = lateral.path
    if reason := timer.overrun("lateral"):
        return Driven(None, reason, (path, candidate, lateral.info, NOT_RUN, None), overrun=True)

    with timer.stage("speed"):
        aim = speed_aim(run.goal, path, run.problem, run.config)

    def profile_along(go_first: bool) -> SpeedPlan:
        with timer.stage("speed"):
            return speed_stage(
                solvers.speed,
                run.ref,
                lateral,
                path,
                run.problem,
                start,
                run.config,
                aim,
                decision.passing,
                go_first=go_first,
                time_left=timer.remaining_s,
                spare=solvers.spare,
            )

    speed = profile_along(go_first=True)
    sqp = speed.solved
    if not sqp.info.usable:
        failed = f"speed profile failed: {sqp.info.status}"
        return Driven(None, failed, (path, candidate, lateral.info, sqp.info, None))
    if reason := timer.overrun("speed"):
        return Driven(None, reason, (path, candidate, lateral.info, sqp.info, None), overrun=True)

    with timer.stage("trajectory"):
        profile, traj, bad, note = _trajectory(
            run.ref, run.problem, path, speed, run.static, decision.borrows
        )
    if bad and speed.first and timer.overrun("trajectory") is None:
        # passing in front of crossing traffic breaks a check: yield to it as to everything ahead
        speed = profile_along(go_first=False)
        sqp = speed.solved
        if not sqp.info.usable:
            failed = f"speed profile failed: {sqp.info.status}"
            return Driven(None, failed, (path, candidate, lateral.info, sqp.info, None))
        with timer.stage("trajectory"):
            profile, traj, bad, note = _trajectory(
                run.ref, run.problem, path, speed, run.static, decision.borrows
            )
    if reason := timer.overrun("trajectory"):
        return Driven(None, reason, (path, candidate, lateral.info, sqp.info, None), overrun=True)
    if bad:
        # A follower's bound may have given way to a stop or a leader: the fallback then also weighs
        # keeping speed and this profile against braking into the follower.
        failed = f"the optimised trajectory breaks a check: {bad[0]}"
        return Driven(None, failed, (path, candidate, lateral.info, sqp.info, sqp))
    status: Status = "stopped" if lateral.stops else "ok"
    message = _message(lateral, start) + note
    if decision.borrows or lateral.stops:
        # why it leaves the lane, or why it stops in it: what blocks (an obstacle's id, or the bend)
        message += f"; {decision.reason.message}"
    stop_s = lateral.stop_s(run.config.stop_gap) if lateral.stops else None
    if stop_s is not None:  # the planned point's stop; the centre is rear_offset ahead of a car's
        stop_s += run.problem.vehicle.rear_offset
    return Driven(run.result(status, message, traj, lateral.info, sqp.info, profile.kind, stop_s=stop_s))


def _trajectory(
    ref: ReferenceLine,
    problem: PlanningProblem,
    path: Path,
    speed: SpeedPlan,
    static: list[tuple[str, BaseGeometry]],
    borrowing: bool,
) -> tuple[Profile, Trajectory, list[Violation], str]:
    """The trajectory of the speed stage's profile along ``path`` and what it breaks (``borrowing``: the
    footprint in the road, not the lane); where full braking replaced the SQP's profile and breaks a check
    (it is hit from behind), the SQP's profile if it passes every check, with a note saying so."""
    dt = problem.options.dt
    profile = speed.profile
    traj = profile.sample(path, dt, ref, problem.vehicle)
    bad = trajectory_violations(ref, problem, traj, static, borrowing=borrowing)
    if bad and profile.kind is not ProfileKind.OPTIMISED:
        planned = Profile.optimised(speed.solved)
        kept = planned.sample(path, dt, ref, problem.vehicle)
        if not trajectory_violations(ref, problem, kept, static, borrowing=borrowing):
            note = (
                f" (up to {speed.solved.position_violation:.2f} m past a stop or an obstacle's headway:"
                f" braking breaks a check, {bad[0]})"
            )
            return planned, kept, [], note
    return profile, traj, bad, ""


def _message(lateral: LateralPlan, start: EgoFrenet) -> str:
    """What a plan that passes every check says: planned, the lane's end, or a stop before a block."""
    note = ""
    if lateral.held:
        note = f" (no room to steer, lateral QP {lateral.info.status}: keeping the current offset)"
        if lateral.obstacle_on_hold:
            note += " (an obstacle on that offset)"
    if lateral.road_end:
        return f"planned; the lane ends {lateral.bounds.s[-1] - start.s:.1f} m ahead{note}"
    if lateral.blocked is not None:
        return f"the road is blocked {lateral.block_at - start.s:.1f} m ahead; stopping before it{note}"
    return f"planned{note}"
