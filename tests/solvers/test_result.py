"""The shared result type: one set of status values, one usable set, one converged set, read-only extras."""

from __future__ import annotations

import pytest

from solvers.result import CONVERGED, USABLE, SolveInfo, SolverStatus


def test_status_values() -> None:
    assert [s.value for s in SolverStatus] == [
        "solved", "solved_inaccurate", "infeasible", "relaxed", "max_iterations", "time_limit", "failed",
    ]  # fmt: skip
    assert SolverStatus("infeasible") is SolverStatus.INFEASIBLE


def test_usable_and_converged_sets() -> None:
    assert {
        SolverStatus.SOLVED,
        SolverStatus.SOLVED_INACCURATE,
        SolverStatus.MAX_ITERATIONS,
        SolverStatus.TIME_LIMIT,
        SolverStatus.RELAXED,
    } == USABLE
    assert {SolverStatus.SOLVED, SolverStatus.SOLVED_INACCURATE} == CONVERGED
    for status in SolverStatus:
        info = SolveInfo(status=status, iterations=3, solve_time_ms=0.1, objective=None, message="")
        assert (
            info.converged
            == status.converged
            == (status in (SolverStatus.SOLVED, SolverStatus.SOLVED_INACCURATE))
        )
        assert info.usable == status.usable == (status not in (SolverStatus.INFEASIBLE, SolverStatus.FAILED))


def test_new_fields_default_to_no_solve_and_extras_are_read_only() -> None:
    info = SolveInfo(SolverStatus.FAILED, 0, 0.0, None, "not run")
    assert (info.max_violation, info.setup_time_ms, dict(info.extras)) == (0.0, 0.0, {})
    given = {"polished": True, "qp_solves": 2}
    info = SolveInfo(SolverStatus.SOLVED, 5, 1.0, 0.5, "", 1e-7, 3.0, given)
    given["polished"] = False  # a copy is kept
    assert info.extras == {"polished": True, "qp_solves": 2}
    with pytest.raises(TypeError):
        info.extras["polished"] = False  # type: ignore[index]
