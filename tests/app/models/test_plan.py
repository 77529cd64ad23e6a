"""app.models.plan: the timing model has one field per stage of STAGES, in order, each documented."""

from __future__ import annotations

from app.models.plan import STAGE_DESCRIPTIONS, STAGES, PlanDiagnostics, PlanTiming


def test_the_timing_model_has_one_field_per_stage() -> None:
    assert tuple(PlanTiming.model_fields) == STAGES
    assert all(PlanTiming.model_fields[s].description == STAGE_DESCRIPTIONS[s] for s in STAGES)
    schema = PlanDiagnostics.model_json_schema()["$defs"]["PlanTiming"]
    assert schema["required"] == list(STAGES)
    assert schema["description"] == (
        "Wall time of the plan and of each of its stages [ms]; 0 for a stage that did not run."
    )
