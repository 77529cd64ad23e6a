"""What a plan answers: a status, why, the trajectory, and what each stage did."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from planner.candidates import CandidateSet
from planner.decision import KEEP_LANE, Decision
from planner.follower import UnescapedFollower
from planner.goal import GoalReport
from planner.speed import ProfileKind
from planner.trajectory import Trajectory
from planner.validation import Violation
from solvers.result import SolveInfo, SolverStatus

#: ``ok``: planned; ``stopped``: the road ahead is blocked and the plan stops before it; ``fallback``: a
#: stage failed or its result broke a check, and the trajectory brakes along the best path known
Status = Literal["ok", "stopped", "fallback"]

#: the solve info of a solver that did not run (its stage was never reached)
NOT_RUN = SolveInfo(SolverStatus.FAILED, 0, 0.0, None, "not run")


@dataclass(frozen=True)
class CandidateStats:
    """How many candidates were generated, repaired (Algorithm 5) and collision-free."""

    generated: int
    repaired: int
    collision_free: int


@dataclass(frozen=True)
class PlanDiagnostics:
    """What each stage did.

    Attributes:
        candidates: candidate counts.
        lateral_qp: how the lateral QP went (:data:`NOT_RUN` when it did not run).
        speed: how the speed SQP went (:data:`NOT_RUN` when it did not run), also when its profile was
            not the one used.
        timing_ms: wall time of every stage that ran and ``total`` [ms] (see :mod:`planner.timing`).
        reference_samples: samples of the resampled reference line.
        knots: knots of the lateral QP (0 when it did not run).
        chosen_candidate: index of the candidate followed.
        speed_profile: the speed profile the trajectory samples: the SQP's, or an analytic one.
        goal: what the trajectory does with the request's goal (None without one).
        follower: the vehicle from behind that still hits the trajectory as predicted, and why it is
            not escaped (:mod:`planner.follower`); None when none does.
        decision: the lane decision: keep the lane or borrow the road beyond it, and why.
    """

    candidates: CandidateStats
    lateral_qp: SolveInfo
    speed: SolveInfo
    timing_ms: dict[str, float]
    reference_samples: int
    knots: int
    chosen_candidate: int | None
    speed_profile: ProfileKind
    goal: GoalReport | None = None
    follower: UnescapedFollower | None = None
    decision: Decision = KEEP_LANE


@dataclass(frozen=True)
class PlanResult:
    """The answer: status, why, the trajectory, (optionally) the candidates behind it, and for a
    fallback what its trajectory still breaks."""

    status: Status
    message: str
    trajectory: Trajectory
    candidates: CandidateSet | None
    diagnostics: PlanDiagnostics
    violations: tuple[Violation, ...] = field(default=())
