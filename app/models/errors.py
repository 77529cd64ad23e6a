"""The one shape of every error answer (4xx and 5xx); :mod:`app.errors` decides which answer an error
gets."""

from __future__ import annotations

from pydantic import BaseModel, Field


class ErrorDetail(BaseModel):
    """One problem with one field."""

    field: str = Field(description="Dotted path into the request body; empty for the whole body.")
    message: str


class ErrorInfo(BaseModel):
    """What went wrong."""

    code: str = Field(description="Stable machine-readable code, e.g. `invalid_request`.")
    message: str = Field(description="Human-readable summary.")
    details: list[ErrorDetail] = Field(description="The problems, field by field; may be empty.")


class ErrorResponse(BaseModel):
    """The body of every error answer."""

    error: ErrorInfo
