"""One plan, as its stages (:data:`planner.timing.STAGES`).

reference and start (:mod:`planner.reference`, :mod:`planner.ego`) → candidates and the choice
(:mod:`planner.candidates`, :mod:`planner.selection`) → lateral bounds and QP (:mod:`planner.lateral`) →
lane decision (:mod:`planner.decision`) → speed profile (:mod:`planner.speed`, :mod:`planner.st_bounds`)
→ trajectory and its checks (:mod:`planner.validation`) → :mod:`planner.fallback` where a stage fails;
the last three along one lateral plan in :mod:`planner.drive`.

Each stage is a function of the ones before; :func:`plan` only wires them and times them. A planning
failure is a status (``stopped`` when the road ahead is blocked, ``fallback`` when a stage fails or its
result breaks a check), always with a trajectory that brakes safely along the best path known.

A request's goal adds its decisions to the stages (:mod:`planner.goal_plan`: the candidates' length and
choice, the lateral QP's reference offsets, the speed profile's terms) and every answer says what its
trajectory does with it (:mod:`planner.goal_report`); without a goal each of these is the identity.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from planner.candidates import CandidateSet, generate_candidates
from planner.collision import FrenetBoxes, frenet_boxes
from planner.config import DEFAULT_CONFIG, PlannerConfig
from planner.decision import decide, no_path
from planner.drive import Run, drive
from planner.ego import EgoFrenet, start_state
from planner.goal_plan import (
    GoalSetup,
    candidate_cost,
    candidate_options,
    goal_setup,
    toward_region,
)
from planner.lane import corridor_width
from planner.lateral import lateral_stage
from planner.problem import Lane, PlanningProblem
from planner.reference import FloatArray, ReferenceLine, build_reference
from planner.result import CandidateStats, PlanResult
from planner.selection import choose_candidate
from planner.speed import reach_speed
from planner.st_bounds import static_shapes
from planner.thread_solvers import thread_solvers
from planner.timing import StageTimer
from planner.trajectory import Path, polyline_path

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
    run = Run(ref, problem, start, static, picked.cands, picked.best, picked.stats, timer, config, goal)
    candidate = picked.path
    if reason := timer.overrun("candidates"):
        return run.fallback(reason, candidate, candidate)

    with timer.stage("lateral"):
        lateral = lateral_stage(
            solvers.lateral, ref, problem, start, picked.offsets, boxes, timer.remaining_s, config
        )
    with timer.stage("decision"):
        decision = decide(ref, problem, start, lateral, static, boxes, picked.s_end, config, goal)
    run = replace(run, decision=decision)
    if decision.corridor is None or decision.boxes is None:  # keep the lane
        if decision.wait_at is not None:
            lateral = lateral.stopping_at(decision.wait_at)
        return drive(run, solvers, lateral, candidate).answer(run)
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
    # a pass within the lane that must stop before the slow vehicle's sweep is worse than following it
    usable = through.path is not None and not (decision.passes_within and through.stops)
    driven = drive(borrowing, solvers, through, borrow.path) if usable else None
    if driven is not None and (driven.result is not None or driven.overrun):
        return driven.answer(borrowing)
    # no path through the road from here, or one that breaks a check: the lane plan stands if it passes
    in_lane = replace(run, decision=no_path(decision))
    kept = drive(in_lane, solvers, lateral, candidate)
    if kept.result is not None or driven is None:
        return kept.answer(in_lane)
    return driven.answer(borrowing)


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
