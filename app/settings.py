"""Service settings from the environment (prefix ``KAPPA_``), e.g. ``KAPPA_PORT=9000``."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

LogLevel = Literal["critical", "error", "warning", "info", "debug"]


class Settings(BaseSettings):
    """Where and how the service runs (read by ``python -m app`` and ``app.main.create_app``)."""

    model_config = SettingsConfigDict(env_prefix="KAPPA_", extra="ignore")

    host: str = Field("127.0.0.1", description="Interface to listen on.")
    port: int = Field(8000, ge=1, le=65535, description="TCP port.")
    workers: int = Field(1, ge=1, le=256, description="Worker processes.")
    log_level: LogLevel = Field("info", description="Log level of the service and of uvicorn.")
    max_body_bytes: int = Field(
        16 * 1024 * 1024, ge=1024, description="Largest request body accepted [bytes]; else 413."
    )

    @field_validator("log_level", mode="before")
    @classmethod
    def _lower(cls, value: object) -> object:
        return value.lower() if isinstance(value, str) else value
