"""The answer of ``/v1/candidates`` (its request is :class:`app.models.planning.PlanningRequest`); a
plan's candidates on request are the same :class:`Candidate` list."""

from __future__ import annotations

from pydantic import Field

from app.models.common import ResponseModel
from planner import problem as pp


class CandidatePoint(ResponseModel):
    """One point of a candidate path, in both frames."""

    s: float = Field(description="Arc length [m].")
    d: float = Field(description="Lateral offset, positive to the left [m].")
    x: float = Field(description="x [m].")
    y: float = Field(description="y [m].")


class Candidate(ResponseModel):
    """One candidate path: the points it keeps, in driving order."""

    points: list[CandidatePoint]
    repaired: bool = Field(description="Whether TransF-κ repaired or jumped any of its points.")


class CandidatesDiagnostics(ResponseModel):
    """Figures about the reference and the generated candidates."""

    generated: int = Field(description="Number of candidates generated.")
    repaired: int = Field(description="Number of candidates with repaired or jumped points.")
    generator: pp.Generator
    reference_samples: int = Field(description="Samples of the uniformly resampled reference.")
    reference_spacing: float = Field(description="Arc length between samples [m].")
    reference_length: float = Field(description="Arc length of the reference [m].")
    reference_max_curvature: float = Field(description="Largest |κ| of the reference [1/m].")
    ego_s: float = Field(description="Ego's arc length on the reference [m].")
    ego_d: float = Field(description="Ego's lateral offset [m].")
    kept_points: int = Field(description="Points kept over all candidates.")


class CandidatesResponse(ResponseModel):
    """Candidate paths and diagnostics."""

    candidates: list[Candidate]
    diagnostics: CandidatesDiagnostics
