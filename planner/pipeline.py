"""One plan, as its stages (:data:`planner.timing.STAGES`).

reference and start (:mod:`planner.reference`, :mod:`planner.ego`) → candidates and the choice
(:mod:`planner.candidates`, :mod:`planner.selection`) → lateral bounds and QP (:mod:`planner.lateral`) →
speed profile (:mod:`planner.speed`, :mod:`planner.st_bounds`) → trajectory and its checks
(:mod:`planner.validation`) → :mod:`planner.fallback` where a stage fails.

Each stage is a function of the ones before; :func:`plan` only wires them and times them. A planning
failure is a status (``stopped`` when the road ahead is blocked, ``fallback`` when a stage fails or its
result breaks a check), always with a trajectory that brakes safely along the best path known.

A request's goal adds its decisions to the stages (:mod:`planner.goal_plan`: the candidates' length and
choice, the lateral QP's reference offsets, the speed profile's terms) and every answer says what its
trajectory does with it (:mod:`planner.goal_report`); without a goal each of these is the identity.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from shapely.geometry.base import BaseGeometry

from planner.candidates import CandidateSet, generate_candidates
from planner.collision import frenet_boxes
from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.ego import EgoFrenet, start_state
from planner.fallback import fallback
from planner.follower import UnescapedFollower
from planner.goal_plan import (
    GoalSetup,
    candidate_cost,
    candidate_options,
    goal_setup,
    speed_aim,
    toward_region,
)
from planner.goal_report import judge
from planner.lane import corridor_width
from planner.lateral import LateralPlan, lateral_stage
from planner.problem import PlanningProblem
from planner.reference import ReferenceLine, build_reference
from planner.result import NOT_RUN, CandidateStats, PlanDiagnostics, PlanResult, Status
from planner.selection import choose_candidate
from planner.speed import Profile, ProfileKind, SpeedPlan, reach_speed, speed_stage
from planner.st_bounds import static_shapes
from planner.thread_solvers import thread_solvers
from planner.timing import StageTimer
from planner.trajectory import Path, Trajectory, polyline_path
from planner.validation import Violation, trajectory_violations
from solvers.result import SolveInfo
from solvers.speed_problem import SpeedResult

__all__ = ["plan"]


def plan(problem: PlanningProblem, config: PlannerConfig = DEFAULT_CONFIG) -> PlanResult:
    """Plan a trajectory for ``problem``; never raises for a planning failure (only for invalid input)."""
    timer = StageTimer(problem.options.time_budget_ms, config.budget_reserve)
    solvers = thread_solvers(config)
    options, vehicle = problem.options, problem.vehicle
    with timer.stage("reference"):
        ref = build_reference(problem.reference_line)
        start = start_state(ref, problem, config)
    with timer.stage("candidates"):
        goal = goal_setup(ref, problem, config)
        fastest = reach_speed(ref, problem, start.s)
        cands = generate_candidates(
            ref, problem.lane, problem.ego, vehicle, candidate_options(goal, options), start=start,
            reach_speed=fastest,
        )  # fmt: skip
        static = static_shapes(problem)
        boxes = frenet_boxes(ref, static, reach=corridor_width(problem, config))
        choice = choose_candidate(cands, boxes, problem, config, candidate_cost(goal, cands, problem, config))
        s_c, d_c, _ = cands.points(choice.best)
    stats = CandidateStats(cands.count, int(cands.repaired.sum()), choice.collision_free)
    run = _Run(ref, problem, start, static, cands, choice.best, stats, timer, config, goal)
    candidate = polyline_path(ref, s_c, d_c)
    if reason := timer.overrun("candidates"):
        return run.fallback(reason, candidate, candidate)

    with timer.stage("lateral"):
        d_aim = toward_region(goal, ref, s_c, d_c, boxes, problem, config)
        lateral = lateral_stage(
            solvers.lateral, ref, problem, start, (s_c, d_aim), boxes, timer.remaining_s, config
        )
    run = replace(run, knots=lateral.knots)
    if lateral.path is None:
        return run.fallback(f"lateral QP failed: {lateral.info.status}", candidate, candidate, lateral.info)
    path = lateral.path
    if reason := timer.overrun("lateral"):
        return run.fallback(reason, path, candidate, lateral.info)

    with timer.stage("speed"):
        aim = speed_aim(goal, path, problem, config)
        speed = speed_stage(solvers.speed, ref, lateral, path, problem, start, config, aim)
    sqp = speed.solved
    if not sqp.info.usable:
        return run.fallback(
            f"speed profile failed: {sqp.info.status}", path, candidate, lateral.info, sqp.info
        )
    if reason := timer.overrun("speed"):
        return run.fallback(reason, path, candidate, lateral.info, sqp.info)

    with timer.stage("trajectory"):
        profile, traj, bad, note = _trajectory(ref, problem, path, speed, static)
    if reason := timer.overrun("trajectory"):
        return run.fallback(reason, path, candidate, lateral.info, sqp.info)
    if bad:
        # A follower's bound may have given way to a stop or a leader: the fallback then also weighs
        # keeping speed and this profile against braking into the follower.
        reason = f"the optimised trajectory breaks a check: {bad[0]}"
        return run.fallback(reason, path, candidate, lateral.info, sqp.info, planned=sqp)
    status: Status = "stopped" if lateral.stops else "ok"
    message = _message(lateral, start) + note
    return run.result(status, message, traj, lateral.info, sqp.info, profile.kind, stopped=lateral.stops)


def _trajectory(
    ref: ReferenceLine,
    problem: PlanningProblem,
    path: Path,
    speed: SpeedPlan,
    static: list[tuple[str, BaseGeometry]],
) -> tuple[Profile, Trajectory, list[Violation], str]:
    """The trajectory of the speed stage's profile along ``path`` and what it breaks; where full braking
    replaced the SQP's profile and breaks a check (it is hit from behind), the SQP's profile if it passes
    every check, with a note saying so."""
    dt = problem.options.dt
    profile = speed.profile
    traj = profile.sample(path, dt, ref, problem.vehicle)
    bad = trajectory_violations(ref, problem, traj, static)
    if bad and profile.kind is not ProfileKind.OPTIMISED:
        planned = Profile.optimised(speed.solved)
        kept = planned.sample(path, dt, ref, problem.vehicle)
        if not trajectory_violations(ref, problem, kept, static):
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


@dataclass(frozen=True)
class _Run:
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
                reason, path, candidate, self.ref, self.problem, self.start, self.static, planned, self.config
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
        stopped: bool = False,
        follower: UnescapedFollower | None = None,
    ) -> PlanResult:
        """The answer, what it does with the goal (``stopped``: before a block), its diagnostics timed up
        to now."""
        report = None
        if self.goal is not None:
            report = judge(self.goal, traj, fallback=status == "fallback", stopped=stopped)
        timing = self.timer.timing_ms()
        diag = PlanDiagnostics(
            self.stats, lateral, speed, timing, self.ref.size, self.knots, self.best, profile, report,
            follower,
        )
        cands = self.cands if self.problem.options.return_candidates else None
        return PlanResult(status, message, traj, cands, diag, violations)
