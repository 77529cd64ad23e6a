"""Counting a method's calls in a test (how many solves a plan made)."""

from __future__ import annotations

from typing import Any

import pytest


def counted_calls(monkeypatch: pytest.MonkeyPatch, owner: type, name: str) -> list[int]:
    """Replace ``owner.name`` by a wrapper that calls it and appends 1 to the returned list each time
    (clear the list to count afresh); ``monkeypatch`` undoes it after the test."""
    calls: list[int] = []
    method = getattr(owner, name)

    def counted(self: Any, *args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return method(self, *args, **kwargs)

    monkeypatch.setattr(owner, name, counted)
    return calls
