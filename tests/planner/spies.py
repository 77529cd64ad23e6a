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


def started_work(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Replace ``planner.thread_solvers.Spare.submit`` by a wrapper that appends the name of each function
    handed to a plan's spare thread to the returned list (``"emergency"``: the speed stage's profile with
    the emergency jerk; ``"_solve_elastic"``: a lateral QP's elastic problem); undone after the test."""
    from planner.thread_solvers import Spare

    started: list[str] = []
    submit = Spare.submit

    def named(self: Spare, fn: Any, /, *args: Any, **kwargs: Any) -> Any:
        started.append(fn.__name__)
        return submit(self, fn, *args, **kwargs)

    monkeypatch.setattr(Spare, "submit", named)
    return started
