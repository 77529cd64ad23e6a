"""Liveness."""

from __future__ import annotations

from fastapi import APIRouter

from app.models.health import Health

router = APIRouter(tags=["health"])


@router.get("/healthz", operation_id="healthz", summary="Liveness probe")
def healthz() -> Health:
    """Answer `{"status": "ok"}` while the service runs."""
    return Health()
