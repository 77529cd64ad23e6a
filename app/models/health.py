"""The answers of ``/healthz`` and ``/readyz``."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel


class Health(BaseModel):
    """The service is up."""

    status: Literal["ok"] = "ok"


class Ready(BaseModel):
    """The service takes requests: its plan processes answer."""

    status: Literal["ready"] = "ready"
