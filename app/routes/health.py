"""Liveness."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter
from pydantic import BaseModel

router = APIRouter(tags=["health"])


class Health(BaseModel):
    """The service is up."""

    status: Literal["ok"] = "ok"


@router.get("/healthz", operation_id="healthz", summary="Liveness probe")
def healthz() -> Health:
    """Answer `{"status": "ok"}` while the service runs."""
    return Health()
