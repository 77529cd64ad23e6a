"""The answer of ``/v1/plan``: the trajectory, how each stage of the planner went and, on request, the
candidates behind it.

:func:`app.conversions.plan_data` writes this answer straight from the planner's arrays; these models
document it (the OpenAPI schema) and the tests check every answer against them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pydantic import Field, create_model
from pydantic.json_schema import SkipJsonSchema

from app.models.candidates import Candidate
from app.models.common import ResponseModel
from planner.pipeline import Status as PlanStatus
from solvers.result import SolverStatus

#: the planner's timed stages, in the order of ``diagnostics.timing_ms``
STAGES = ("total", "reference", "candidates", "lateral", "speed")
#: what each stage covers (every stage of :data:`STAGES` needs one)
STAGE_DESCRIPTIONS = {
    "total": "All stages.",
    "reference": "Reference line and the ego's Frenet state.",
    "candidates": "Candidate paths, their collision check and the choice.",
    "lateral": "Lateral bounds and the lateral QP.",
    "speed": "Speed profile.",
}


class TrajectoryPoint(ResponseModel):
    """One sample of the planned motion of the vehicle's centre."""

    t: float = Field(description="Time from now [s]; the first point is the ego at t = 0.")
    x: float = Field(description="Centre x [m].")
    y: float = Field(description="Centre y [m].")
    heading: float = Field(
        description="Heading, counter-clockwise from +x [rad]; continuous along the trajectory (not "
        "wrapped to [-π, π])."
    )
    curvature: float = Field(description="Path curvature, positive to the left [1/m].")
    v: float = Field(description="Speed [m/s], never negative.")
    a: float = Field(description="Acceleration along the path [m/s²].")
    s: float = Field(description="Arc length on the reference [m].")
    d: float = Field(description="Lateral offset from the reference, positive to the left [m].")


class CandidateCounts(ResponseModel):
    """How many candidate paths were generated, repaired by TransF-κ, and clear of static obstacles."""

    generated: int = Field(description="Candidates generated.")
    repaired: int = Field(description="Candidates with repaired or jumped points.")
    collision_free: int = Field(description="Candidates clear of every static obstacle.")


class LateralSolveInfo(ResponseModel):
    """How the lateral QP (offset d along the path) went."""

    status: SolverStatus
    iterations: int = Field(description="Iterations of the QP solver (0 when it did not run).")
    solve_time_ms: float = Field(description="Wall time of the solve [ms].")


class SpeedSolveInfo(ResponseModel):
    """How the speed profile went (`failed` when it did not run because the lateral QP failed)."""

    status: SolverStatus
    solve_time_ms: float = Field(description="Wall time of the solve [ms].")


if TYPE_CHECKING:  # a model built from STAGES has no static fields for the type checker
    PlanTiming = ResponseModel
else:
    PlanTiming = create_model(
        "PlanTiming",
        __doc__="Wall time of the planner's stages [ms]; 0 for a stage that did not run.",
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


class PlanDiagnostics(ResponseModel):
    """What each stage of the planner did, and how long the request waited and ran."""

    candidates: CandidateCounts
    lateral_qp: LateralSolveInfo
    speed: SpeedSolveInfo
    timing_ms: PlanTiming
    request: RequestTiming


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
