"""Which second backend for the lateral QP: ``python bench/lateral_backends.py`` collects the lateral QPs
OSQP does not converge on in CommonRoad closed loops and solves each through qpsolvers with every backend
installed of Clarabel and ProxQP (``pip install proxsuite``; not a dependency), printing their times,
statuses and accuracy against a tight Clarabel solve (asserts nothing).

    python bench/lateral_backends.py                       # two scenes with many such QPs
    python bench/lateral_backends.py --only USA_Peach-3_1_T-1 --limit 100
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:] = [p for p in sys.path if Path(p or ".").resolve() != Path(__file__).resolve().parent]
sys.path.insert(0, str(ROOT))

import qpsolvers  # noqa: E402 (after the path fix)

from solvers.conic_qp import qpsolvers_problem, solve_conic_qp  # noqa: E402
from solvers.lateral_qp import LateralQPProblem, LateralQPSolver, build_qp_matrices  # noqa: E402
from solvers.lateral_qp_problem import max_violation, objective  # noqa: E402


def collect(names: list[str], limit: int) -> list[LateralQPProblem]:
    """The lateral QPs handed to the second backend in the closed loops of ``names``."""
    sys.path.insert(0, str(ROOT / "bench"))
    from cycles import run  # the loops and their recorder

    found: list[LateralQPProblem] = []
    solve = LateralQPSolver.solve

    def keep(self: LateralQPSolver, problem: LateralQPProblem, **kwargs: Any) -> Any:
        out = solve(self, problem, **kwargs)
        if out.info.extras.get("second_status") and len(found) < limit:
            found.append(problem)
        return out

    LateralQPSolver.solve = keep  # type: ignore[method-assign]
    try:
        run(names, "request", 35.0)
    finally:
        LateralQPSolver.solve = solve  # type: ignore[method-assign]
    return found


def _problem(P: Any, q: np.ndarray, A: Any, lower: np.ndarray, upper: np.ndarray, dense: bool) -> Any:
    """The QP as solvers.conic_qp hands it to qpsolvers, its matrices dense for a dense backend."""
    problem = qpsolvers_problem(P, q, A, lower, upper)
    if dense:
        return qpsolvers.Problem(*(m.toarray() if hasattr(m, "toarray") else m for m in problem.unpack()))
    return problem


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--only", nargs="*", default=["USA_Peach-3_1_T-1", "DEU_LocationALower-28_1_S-1"])
    parser.add_argument("--limit", type=int, default=200, help="most QPs to compare")
    args = parser.parse_args(argv)
    problems = collect(args.only, args.limit)
    backends = [("clarabel", {}, False)]
    if "proxqp" in qpsolvers.available_solvers:
        backends += [("proxqp", {"eps_abs": 1e-6, "backend": "sparse"}, False)]
        backends += [("proxqp", {"eps_abs": 1e-6, "backend": "dense"}, True)]
    rows: dict[str, list[tuple[int, bool, bool, float, float, float]]] = {}
    for problem in problems:
        P, q, A, lower, upper = build_qp_matrices(problem)
        reference = solve_conic_qp(P, q, A, lower, upper, max_iter=200)
        ref_found = reference.info.converged
        ref_cost = objective(problem, *np.split(reference.x, 3)) if ref_found else np.nan
        for name, settings, dense in backends:
            label = f"{name}{' dense' if dense else ''}"
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t0 = time.perf_counter()
                qp = _problem(P, q, A, lower, upper, dense)
                solution = qpsolvers.solve_problem(qp, solver=name, **settings)
                ms = 1e3 * (time.perf_counter() - t0)
            found = bool(solution.found) and solution.x is not None
            violation = max_violation(A @ solution.x, lower, upper) if found else np.nan
            gap = abs(objective(problem, *np.split(solution.x, 3)) - ref_cost) / max(abs(ref_cost), 1e-9)
            row = (problem.n, found, ref_found, ms, violation, gap if found else np.nan)
            rows.setdefault(label, []).append(row)
    print(f"{len(problems)} lateral QPs OSQP did not converge on ({', '.join(args.only)})")
    for label, values in rows.items():
        arr = np.array(values, dtype=float)
        big = arr[:, 0] > 150
        found = arr[:, 1] == 1
        print(
            f"{label:13s} solved {int(found.sum())}/{len(arr)} (reference {int(arr[:, 2].sum())}), agree "
            f"{int((arr[:, 1] == arr[:, 2]).sum())}; time median {np.median(arr[:, 3]):.2f} ms, p90 "
            f"{np.percentile(arr[:, 3], 90):.2f}, max {arr[:, 3].max():.1f}, over 150 knots median "
            f"{np.median(arr[big, 3]) if big.any() else np.nan:.2f}; largest violation "
            f"{np.nanmax(arr[found, 4]) if found.any() else np.nan:.1e}, objective gap "
            f"{np.nanmax(arr[found, 5]) if found.any() else np.nan:.1e}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
