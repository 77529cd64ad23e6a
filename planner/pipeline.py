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
from planner.collision import FrenetBoxes, frenet_boxes
from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.decision import KEEP_LANE, Decision, ReasonKind, decide, no_path
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
from planner.problem import Lane, PlanningProblem
from planner.reference import FloatArray, ReferenceLine, build_reference
from planner.result import NOT_RUN, CandidateStats, PlanDiagnostics, PlanResult, Status
from planner.selection import choose_candidate
from planner.speed import Profile, ProfileKind, SpeedPlan, reach_speed, speed_stage
from planner.st_bounds import static_shapes
from planner.thread_solvers import Solvers, thread_solvers
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
    with timer.stage("reference"):
        ref = build_reference(problem.reference_line)
        start = start_state(ref, problem, config)
    with timer.stage("candidates"):
        goal = goal_setup(ref, problem, config)
        static = static_shapes(problem)
        boxes = frenet_boxes(ref, static, reach=corridor_width(problem, config))
        fastest = reach_speed(ref, problem, start.s)
        picked = _Picked.of(ref, problem, start, problem.lane, boxes, config, goal, fastest)
    run = _Run(ref, problem, start, static, picked.cands, picked.best, picked.stats, timer, config, goal)
    candidate = picked.path
    if reason := timer.overrun("candidates"):
        return run.fallback(reason, candidate, candidate)

    with timer.stage("lateral"):
        lateral = lateral_stage(
            solvers.lateral, ref, problem, start, picked.offsets, boxes, timer.remaining_s, config
        )
    with timer.stage("decision"):
        decision = decide(ref, problem, start, lateral, static, boxes, picked.s_end, config)
    run = replace(run, decision=decision)
    if decision.corridor is None or decision.boxes is None:  # keep the lane
        if decision.wait_at is not None:
            lateral = lateral.stopping_at(decision.wait_at)
        return _drive(run, solvers, lateral, candidate).answer(run)
    with timer.stage("candidates"):
        borrow = _Picked.of(ref, problem, start, decision.corridor, decision.boxes, config, goal, fastest)
    if reason := timer.overrun("candidates"):
        return run.fallback(reason, candidate, candidate)
    with timer.stage("lateral"):
        through = lateral_stage(
            solvers.lateral,
            ref,
            problem,
            start,
            borrow.offsets,
            decision.boxes,
            timer.remaining_s,
            config,
            lane=decision.corridor,
            braking_share=config.decision.urgent_braking_share if decision.urgent else 0.5,
            sides=decision.sides,
        )
    borrowing = replace(run, cands=borrow.cands, best=borrow.best, stats=borrow.stats)
    driven = _drive(borrowing, solvers, through, borrow.path) if through.path is not None else None
    if driven is not None and (driven.result is not None or driven.overrun):
        return driven.answer(borrowing)
    # no path through the road from here, or one that breaks a check: the lane plan stands if it passes
    in_lane = replace(run, decision=no_path(decision))
    kept = _drive(in_lane, solvers, lateral, candidate)
    if kept.result is not None or driven is None:
        return kept.answer(in_lane)
    return driven.answer(borrowing)


@dataclass(frozen=True)
class _Driven:
    """The end of a plan along a lateral plan: its answer (``result``), or why it fails and what its
    fallback needs (``fallback``, the arguments of :meth:`_Run.fallback` after the reason); ``overrun``
    when the time budget ended it."""

    result: PlanResult | None
    reason: str = ""
    fallback: tuple[Path, Path, SolveInfo, SolveInfo, SpeedResult | None] | None = None
    overrun: bool = False

    def answer(self, run: _Run) -> PlanResult:
        """The answer: the plan's, or ``run``'s fallback for it."""
        if self.result is not None:
            return self.result
        if self.fallback is None:
            raise ValueError("a failed plan without what its fallback needs")  # a bug of _drive
        path, candidate, lateral, speed, planned = self.fallback
        return run.fallback(self.reason, path, candidate, lateral, speed, planned)


def _drive(run: _Run, solvers: Solvers, lateral: LateralPlan, candidate: Path) -> _Driven:
    """The speed profile along ``lateral``'s path, the trajectory and its checks (the decision of ``run``:
    the overtaken vehicles, the road or the lane to keep to): the answer, or why it fails."""
    timer, decision, start = run.timer, run.decision, run.start
    run = replace(run, knots=lateral.knots)
    if lateral.path is None:
        failed = f"lateral QP failed: {lateral.info.status}"
        return _Driven(None, failed, (candidate, candidate, lateral.info, NOT_RUN, None))
    path = lateral.path
    if reason := timer.overrun("lateral"):
        return _Driven(None, reason, (path, candidate, lateral.info, NOT_RUN, None), overrun=True)

    with timer.stage("speed"):
        aim = speed_aim(run.goal, path, run.problem, run.config)
        speed = speed_stage(
            solvers.speed, run.ref, lateral, path, run.problem, start, run.config, aim, decision.passing
        )
    sqp = speed.solved
    if not sqp.info.usable:
        failed = f"speed profile failed: {sqp.info.status}"
        return _Driven(None, failed, (path, candidate, lateral.info, sqp.info, None))
    if reason := timer.overrun("speed"):
        return _Driven(None, reason, (path, candidate, lateral.info, sqp.info, None), overrun=True)

    with timer.stage("trajectory"):
        profile, traj, bad, note = _trajectory(
            run.ref, run.problem, path, speed, run.static, decision.borrows
        )
    if reason := timer.overrun("trajectory"):
        return _Driven(None, reason, (path, candidate, lateral.info, sqp.info, None), overrun=True)
    if bad:
        # A follower's bound may have given way to a stop or a leader: the fallback then also weighs
        # keeping speed and this profile against braking into the follower.
        failed = f"the optimised trajectory breaks a check: {bad[0]}"
        return _Driven(None, failed, (path, candidate, lateral.info, sqp.info, sqp))
    status: Status = "stopped" if lateral.stops else "ok"
    message = _message(lateral, start) + note
    if decision.borrows or (lateral.stops and decision.reason.kind is not ReasonKind.NO_ROAD):
        message += f"; {decision.reason.message}"  # why it leaves the lane, or why it stops in it
    return _Driven(
        run.result(status, message, traj, lateral.info, sqp.info, profile.kind, stopped=lateral.stops)
    )


@dataclass(frozen=True)
class _Picked:
    """The candidates in a lane (the problem's, or a borrow's corridor), the one chosen and the offsets
    the lateral stage tracks (towards a goal's region beside the reference)."""

    cands: CandidateSet
    best: int
    stats: CandidateStats
    offsets: tuple[FloatArray, FloatArray]
    path: Path

    @classmethod
    def of(
        cls,
        ref: ReferenceLine,
        problem: PlanningProblem,
        start: EgoFrenet,
        lane: Lane,
        boxes: FrenetBoxes,
        config: PlannerConfig,
        goal: GoalSetup | None,
        fastest: float | None,
    ) -> _Picked:
        """``fastest``: the speed the candidates' paths must let the plan reach (None: the target's)."""
        options = candidate_options(goal, problem.options)
        cands = generate_candidates(
            ref, lane, problem.ego, problem.vehicle, options, start=start, reach_speed=fastest
        )
        choice = choose_candidate(cands, boxes, problem, config, candidate_cost(goal, cands, problem, config))
        s_c, d_c, _ = cands.points(choice.best)
        stats = CandidateStats(cands.count, int(cands.repaired.sum()), choice.collision_free)
        d_aim = toward_region(goal, ref, s_c, d_c, boxes, problem, config)
        return cls(cands, choice.best, stats, (s_c, d_aim), polyline_path(ref, s_c, d_c))

    @property
    def s_end(self) -> float:
        """Where the chosen candidate ends [m]."""
        return float(self.offsets[0][-1])


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
