"""The planner's domain errors: one hierarchy, mapped to HTTP status codes in one place (`app.errors`).

A caller that cannot go on raises one of these; a solver that does not converge returns a status
instead. Every error names the input field it is about (a dotted path such as
``reference_line`` or ``lane.left_width``) so that the HTTP layer can report it precisely.
"""

from __future__ import annotations


class PlannerError(Exception):
    """Base of every error the planner raises on purpose."""

    def __init__(self, message: str, *, field: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.field = field

    def __str__(self) -> str:
        return f"{self.field}: {self.message}" if self.field else self.message


class InvalidInputError(PlannerError):
    """The request is well-formed but geometrically unusable (the client's mistake → 422)."""


class InvalidReferenceError(InvalidInputError):
    """The reference line cannot be turned into a Frenet frame (too few points, non-finite, …)."""
