"""The answer of ``/v1/plan``: the trajectory, how each stage of the planner went and, on request, the
candidates behind it.

:func:`app.conversions.plan_data` writes this answer straight from the planner's arrays; these models
document it (the OpenAPI schema) and the tests check every answer against them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

from pydantic import Field, create_model
from pydantic.json_schema import SkipJsonSchema

from app.models.candidates import Candidate
from app.models.common import ResponseModel
from planner.decision import BlockKind, LaneChoice, ReasonKind
from planner.follower import FollowerReason
from planner.goal import GoalReason, GoalStatus
from planner.result import Status as PlanStatus
from planner.speed import ProfileKind
from planner.timing import STAGES as PLANNER_STAGES
from planner.timing import TOTAL
from solvers.result import SolverStatus

#: the keys of ``diagnostics.timing_ms``: the plan's wall time, then the planner's stages in their order
STAGES = (TOTAL, *PLANNER_STAGES)
#: what each key covers (every one of :data:`STAGES` needs one)
STAGE_DESCRIPTIONS = {
    TOTAL: "Wall time of the whole plan, from its start to its answer (at least the sum of the stages).",
    "reference": "Reference line and the ego's Frenet state.",
    "candidates": "Candidate paths, their collision check and the choice (both runs when the lane "
    "decision borrows the road).",
    "lateral": "Lateral bounds and the lateral QP (both runs when the lane decision borrows the road).",
    "decision": "The lane decision: keep the lane or borrow the road beyond it (0 when the request has no "
    "road and nothing blocks the lane).",
    "speed": "Speed profile: space-time bounds, the SQP and any analytic profile replacing it.",
    "trajectory": "Sampling the trajectory at `options.dt` and its checks.",
    "fallback": "The fallback's own work: braking trajectories tried and checked (0 unless `fallback`).",
}


class TrajectoryPoint(ResponseModel):
    """One sample of the planned motion: the position of the footprint's centre and the vehicle's state.

    Without `vehicle.wheelbase` (a vehicle whose centre does not slip), heading, curvature, speed and
    acceleration are those of the centre's path and `steering_angle` is absent. With it (a car, the
    kinematic single-track model), heading is the body's yaw, curvature the rear axle's path's
    (tan(steering_angle) / wheelbase), speed and acceleration the rear axle's, and every point has its
    `steering_angle`: the state of CommonRoad's kinematic single-track model, its position the centre's.
    """

    t: float = Field(description="Time from now [s]; the first point is the ego at t = 0.")
    x: float = Field(description="Centre x [m].")
    y: float = Field(description="Centre y [m].")
    heading: float = Field(
        description="Heading, counter-clockwise from +x [rad]; continuous along the trajectory (not "
        "wrapped to [-π, π]). The centre's direction of travel; a car's body yaw."
    )
    curvature: float = Field(
        description="Path curvature, positive to the left [1/m]: the centre's path's; a car's rear axle "
        "path's."
    )
    v: float = Field(description="Speed [m/s], never negative: the centre's; a car's rear axle's.")
    a: float = Field(description="Acceleration along the path [m/s²]: the centre's; a car's rear axle's.")
    s: float = Field(description="Arc length of the centre on the reference [m].")
    d: float = Field(description="Lateral offset of the centre from the reference, positive to the left [m].")
    steering_angle: float | SkipJsonSchema[None] = Field(
        None,
        description="A car's front wheel steering angle, positive to the left [rad]: atan(wheelbase · "
        "curvature). Present exactly when the request's vehicle has a wheelbase.",
    )


class CandidateCounts(ResponseModel):
    """How many candidate paths were generated, repaired by TransF-κ, and clear of static obstacles."""

    generated: int = Field(description="Candidates generated.")
    repaired: int = Field(description="Candidates with repaired or jumped points.")
    collision_free: int = Field(description="Candidates clear of every static obstacle.")


#: which solver's answer the lateral QP's is (``none``: it did not run)
LateralBackend = Literal["osqp", "clarabel", "none"]


class LateralSolveInfo(ResponseModel):
    """How the lateral QP (offset d along the path) went."""

    status: SolverStatus
    iterations: int = Field(description="OSQP's iterations (0 when it did not run).")
    solve_time_ms: float = Field(description="Wall time of the solve [ms].")
    backend: LateralBackend = Field(
        description="The solver whose answer this is: `osqp`, or `clarabel` (interior point, through "
        "qpsolvers) where OSQP did not converge on the same QP; `none` when the QP did not run."
    )


class SpeedSolveInfo(ResponseModel):
    """How the speed SQP went (`failed` when it did not run because an earlier stage failed), and which
    profile the trajectory follows: the SQP's own status is kept when an analytic profile replaced it."""

    status: SolverStatus
    iterations: int = Field(description="QPs the SQP solved (0 when it did not run).")
    solve_time_ms: float = Field(description="Wall time of the solve [ms].")
    profile: ProfileKind = Field(
        description="The speed profile the trajectory follows: `optimised` (the SQP's), `braking` (full "
        "braking within the jerk limit: a fallback, or the SQP's profile went past a stop), "
        "`keep_speed` (the acceleration released, the speed kept, slowing only where the path's "
        "curvature demands it: a fallback whose braking is hit by moving traffic, from behind or "
        "where it would stand) or `escape` (towards the speed limit as fast as the vehicle's "
        "acceleration allows, within the path's curvature: the same)."
    )


class Follower(ResponseModel):
    """A vehicle from behind that still hits the trajectory as predicted, and why no trajectory within
    the limits keeps ahead of it."""

    obstacle_id: str = Field(description="The vehicle's `id`.")
    t: float = Field(description="The first time its predicted footprint meets the trajectory's [s].")
    reason: FollowerReason = Field(
        description="`acceleration`: it closes faster than the vehicle's acceleration can escape; "
        "`speed_limit`: faster than any acceleration within `options.speed_limit` (else the target "
        "speed) can escape; `curvature`: faster than any acceleration within the curvature's speed "
        "limit ahead can escape; `ahead`: getting away from it would hit something ahead or break "
        "another check (a stop, a leader)."
    )


if TYPE_CHECKING:  # a model built from STAGES has no static fields for the type checker
    PlanTiming = ResponseModel
else:
    PlanTiming = create_model(
        "PlanTiming",
        __doc__="Wall time of the plan and of each of its stages [ms]; 0 for a stage that did not run.",
        __base__=ResponseModel,
        __module__=__name__,
        **{stage: (float, Field(description=STAGE_DESCRIPTIONS[stage])) for stage in STAGES},
    )


class RequestTiming(ResponseModel):
    """The request's budget and how it was spent, from its arrival at the service [ms]."""

    budget_ms: float = Field(
        description="The budget: `options.time_budget_ms`, else the server's `KAPPA_TIME_BUDGET_MS`; it "
        "counts from the request's arrival."
    )
    waited_ms: float = Field(
        description="From the arrival to the start of the plan: reading the body, waiting for a plan "
        "process, parsing and validating. The planner got `budget_ms` − `waited_ms`."
    )
    ran_ms: float = Field(description="The plan, from its start until its trajectory was ready.")


class GoalDiagnostics(ResponseModel):
    """What the trajectory does with the request's `goal`: judged at its samples, with the footprint's
    centre (`x`, `y`) inside the region (boundary included), `t` in the window and `v` within 0.001 m/s
    of the speed range, for each part given."""

    status: GoalStatus = Field(
        description="`reached`: the trajectory meets the goal at some sample (`t`: the first); "
        "`on_the_way`: not within the horizon, which ends before the region or the window, and nothing "
        "found prevents it; `unreachable`: something prevents it (`reason`)."
    )
    t: float | SkipJsonSchema[None] = Field(
        None, description="The first time the goal is met [s]; present exactly when `reached`."
    )
    reason: GoalReason | SkipJsonSchema[None] = Field(
        None,
        description="Why the goal cannot be met; present exactly when `unreachable`. `window_ended`: "
        "before now; `behind`: the region lies behind the vehicle; `off_road`: no point of it is within "
        "the lane for the vehicle's centre (or beyond the reference's end); `too_far`: not reachable "
        "before the window closes within the speed limit (`options.speed_limit`, else the target) and "
        "acceleration; `too_early`: the trajectory passes it before the window opens; `speed_range`: "
        "the speed range is above the speed limit, or the vehicle is never in it while inside; "
        "`blocked`: the road or traffic stops the vehicle before the region; `missed`: the trajectory "
        "passes beside the region; `fallback`: the plan fell back and its braking trajectory does not "
        "meet the goal.",
    )
    message: str = Field(description="Why, in words.")


class DecisionReason(ResponseModel):
    """Why the plan keeps its lane or borrows the road: a kind, what blocks the lane (an obstacle or a
    bend, and where), and for `oncoming` the moving obstacle that would be in the borrowed road; `message`
    says it in words. A field that does not apply is left out."""

    kind: ReasonKind = Field(
        description="`lane_free`: nothing blocks the lane (kept). `passing`: the lane is blocked (`block`): "
        "borrowing the road on `side` to get past. `passing_in_lane`: a much slower vehicle going the same "
        "way (`obstacle_id`, `block` `slow_vehicle`) leaves room beside it in the lane: passed within the "
        "lane on `side` (kept). `returning`: the vehicle is outside its lane, in the "
        "road on `side`, and comes back. Kept although the lane is blocked: `oncoming` (a moving obstacle, "
        "`oncoming_id`, would be in the borrowed road from `t` while the vehicle is: it waits before the "
        "block and goes once it is clear), `road_blocked` (the road leaves no room past the block either), "
        "`no_return` (no way back into the lane within the path: a long block, or a slow vehicle it cannot "
        "pass within the horizon), `no_path` (no path through the road from where the vehicle is: too "
        "close to the block to swing out, or the path through it breaks a check), `no_road` (the request "
        "has no `road`), `goal_first` (the request's `goal` region lies in the lane before the obstacle or "
        "slow vehicle that blocks it: it is reached in the lane)."
    )
    message: str = Field(description="The reason in words; when the lane is blocked, it names what blocks.")
    block: BlockKind | SkipJsonSchema[None] = Field(
        None,
        description="What blocks the lane: `obstacle` (a static one, `obstacle_id`), `slow_vehicle` (a "
        "moving one ahead, `obstacle_id`, much slower than the target speed and too wide to pass in the "
        "lane; for `passing_in_lane`, one that leaves room to), `bend` (tighter than the vehicle can take "
        "in the lane), `narrow` (the lane is narrower "
        "than the vehicle).",
    )
    obstacle_id: str | SkipJsonSchema[None] = Field(None, description="The obstacle that blocks the lane.")
    s: float | SkipJsonSchema[None] = Field(
        None, description="Where the lane is blocked: the arc length of the vehicle's planned point [m]."
    )
    t: float | SkipJsonSchema[None] = Field(
        None, description="`oncoming`: the first time the moving obstacle is in the borrowed road [s]."
    )
    oncoming_id: str | SkipJsonSchema[None] = Field(
        None, description="`oncoming`: the moving obstacle in the borrowed road."
    )
    side: Literal["left", "right"] | SkipJsonSchema[None] = Field(
        None,
        description="The side of the road borrowed (or that would be); for `passing_in_lane`, the side of "
        "the slow vehicle it passes on.",
    )


class LaneDecision(ResponseModel):
    """The lane decision: keep the lane, or borrow the road beyond it (`road` in the request) on one
    side. While it borrows, the trajectory's footprint stays in the road, not necessarily in the lane."""

    lane: LaneChoice = Field(description="`keep`, `borrow_left` or `borrow_right`.")
    reason: DecisionReason


class PlanDiagnostics(ResponseModel):
    """What each stage of the planner did, what the trajectory does with the goal, and how long the
    request waited and ran."""

    candidates: CandidateCounts
    lateral_qp: LateralSolveInfo
    speed: SpeedSolveInfo
    decision: LaneDecision
    timing_ms: PlanTiming
    request: RequestTiming
    goal: GoalDiagnostics | SkipJsonSchema[None] = Field(
        None,
        description="What the trajectory does with the request's `goal`; present exactly when it has one.",
    )
    follower: Follower | SkipJsonSchema[None] = Field(
        None,
        description="Present only when a vehicle from behind still hits the trajectory as predicted (a "
        "`fallback` that did not brake into it): which, when, and why it is not escaped.",
    )


class PlanResponse(ResponseModel):
    """A planned trajectory, how it came about and, on request, the candidates behind it."""

    status: PlanStatus = Field(
        description="`ok`: planned; `stopped`: the road ahead is blocked and the trajectory stops "
        "before it; `fallback`: a stage failed or its result broke a check, and the trajectory brakes "
        "along the best path known."
    )
    message: str = Field(description="Why, in words.")
    trajectory: list[TrajectoryPoint] = Field(
        description="Samples at t = 0 (the ego), `options.dt`, 2·`options.dt`, … up to "
        "`options.horizon_time`."
    )
    candidates: list[Candidate] | SkipJsonSchema[None] = Field(
        None,
        description="The candidate paths (as `/v1/candidates` answers them); the key is present only "
        "when `options.return_candidates` is true.",
    )
    diagnostics: PlanDiagnostics
