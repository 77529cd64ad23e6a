"""The stages of a plan, named once, and the timer that measures them against the time budget.

``PlanDiagnostics.timing_ms`` has one entry [ms] per stage that ran (:data:`STAGES`, in that order of
execution) and :data:`TOTAL`: the wall time of the whole plan from its first line to its return, which
is at least the sum of the stages (what runs between them is counted too).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Final, Literal, get_args

Stage = Literal["reference", "candidates", "lateral", "decision", "speed", "trajectory", "fallback"]
#: every stage of a plan, in the order they run: the reference line and the ego's start on it; the
#: candidates, their collision check and the choice; the lateral bounds and QP; the lane decision (keep
#: the lane or borrow the road: a borrow runs the candidates and the lateral stage again, timed as
#: theirs); the speed profile; the trajectory sampled and checked; the fallback's own work (choosing a
#: braking trajectory)
STAGES: Final[tuple[Stage, ...]] = get_args(Stage)
#: the key of the plan's wall time in ``timing_ms``
TOTAL: Final = "total"


class StageTimer:
    """Wall time per stage [ms] and of the whole plan since the timer was made, against a budget [ms].

    The stages have the budget less a reserve (``reserve_share`` of it) for the fallback an overrun
    leads to, so that the answer is ready within the budget as long as the fallback's work fits in the
    reserve. The budget is wall time: the same request can overrun on a loaded machine and not on an
    idle one (the lateral QP's time limit is the budget left, too).
    """

    def __init__(self, budget_ms: float | None = None, reserve_share: float = 0.0) -> None:
        self._t0 = time.perf_counter()
        self._budget_ms = budget_ms
        self._deadline_ms = None if budget_ms is None else budget_ms * (1.0 - reserve_share)
        self._ms: dict[Stage, float] = {}

    def elapsed_ms(self) -> float:
        """Wall time since the timer was made [ms]."""
        return 1e3 * (time.perf_counter() - self._t0)

    def remaining_s(self) -> float | None:
        """Time left for the stages [s] (at least 1 ms), or None without a budget."""
        if self._deadline_ms is None:
            return None
        return max(1e-3 * self._deadline_ms - (time.perf_counter() - self._t0), 1e-3)

    def overrun(self, stage: Stage) -> str | None:
        """Why the plan must stop after ``stage``, if the stages' share of the budget is spent; else None."""
        elapsed = self.elapsed_ms()
        if self._deadline_ms is None or elapsed <= self._deadline_ms:
            return None
        reserve = "" if self._deadline_ms == self._budget_ms else ", the rest kept for the fallback"
        return (
            f"time budget of {self._budget_ms:g} ms spent after the {stage} stage "
            f"({elapsed:.0f} ms{reserve})"
        )

    @contextmanager
    def stage(self, name: Stage) -> Iterator[None]:
        """Time the block as (part of) stage ``name``."""
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self._ms[name] = self._ms.get(name, 0.0) + 1e3 * (time.perf_counter() - t0)

    def timing_ms(self) -> dict[str, float]:
        """Every stage that ran [ms], then :data:`TOTAL`: the wall time since the timer was made [ms]."""
        out: dict[str, float] = {name: self._ms[name] for name in STAGES if name in self._ms}
        out[TOTAL] = self.elapsed_ms()
        return out


def time_for(time_left: Callable[[], float | None], needed_ms: float) -> bool:
    """Whether the budget leaves ``needed_ms`` [ms] for an optional solve (what the one before it took):
    a re-solve that only improves a stage's answer is skipped rather than run past the budget, so that
    an overrun reaches its fallback in time. Always, without a budget (``time_left()`` None)."""
    left = time_left()
    return left is None or 1e3 * left > needed_ms
