"""Record the `/v1/plan` answers of a fixed set of requests, or compare them with a recording.

For refactorings that must not change behaviour: record before, compare after. The requests are every
golden regression request, every CommonRoad request under ``tests/data/commonroad/`` and, with the whole
road (``road``), under ``tests/data/commonroad-road/``, and the demo
(``GET /v1/demo``); they are posted to the app in-process, so the HTTP layer is part of what is compared.

    python bench/compare_answers.py record /tmp/before.json
    python bench/compare_answers.py compare /tmp/before.json

Plans run in one plan process, in a fixed order, with the largest time budget (so that a loaded machine
changes no answer).
``compare`` prints, per request, whether status and message are the same and the largest absolute
difference of any number of the trajectory and candidates, and the largest of all; the exit status is 1
when a status, a message, a shape or a number differs by more than ``--tolerance`` (default 1e-9).
Wall times (``timing_ms``, ``solve_time_ms``, the request's ``waited_ms`` and ``ran_ms``) are left out:
they differ on every run. So are
``--ignore`` keys (dotted paths, e.g. ``answer.diagnostics.speed``) whose meaning a change fixed
on purpose.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

#: keys whose values are wall times
TIMES = frozenset({"timing_ms", "solve_time_ms", "setup_time_ms", "waited_ms", "ran_ms"})


def requests() -> Iterator[tuple[str, Any]]:
    """(name, request body) of every request compared."""
    for path in sorted((ROOT / "tests/regression/requests").glob("*.json")):
        if not path.name.endswith(".expect.json"):
            yield f"regression/{path.stem}", json.loads(path.read_text())
    for folder in ("commonroad", "commonroad-road"):
        for path in sorted((ROOT / "tests/data" / folder).glob("*.json")):
            if path.name != "index.json":
                yield f"{folder}/{path.stem}", json.loads(path.read_text())


def record() -> dict[str, Any]:
    from fastapi.testclient import TestClient

    from app.main import create_app
    from app.settings import Settings

    out: dict[str, Any] = {}
    # One plan process, as served but in a fixed order: the solvers warm-start from the plan before,
    # which moves answers by up to ~1e-8 when two processes share the requests differently.
    # The largest budget: on a loaded machine a plan past the default budget would be a fallback.
    settings = Settings(log_level="warning", plan_processes=1, time_budget_ms=60_000.0)
    with TestClient(create_app(settings)) as client:
        demo = client.get("/v1/demo").json()
        named = [("demo", demo), *requests()]
        for name, body in named:
            answer = client.post("/v1/plan", json=body)
            out[name] = {"http": answer.status_code, "answer": answer.json()}
            print(f"{name}: {answer.status_code} {out[name]['answer'].get('status')}", file=sys.stderr)
    return out


def _walk(a: Any, b: Any, where: str, ignore: set[str]) -> Iterator[tuple[str, float | None]]:
    """(path, |a − b|) for every number; None where the structure or a non-number differs."""
    if where.rsplit(".", 1)[-1] in TIMES or where in ignore:
        return
    if isinstance(a, dict) and isinstance(b, dict):
        ignored = {key for key in a.keys() | b.keys() if (f"{where}.{key}" if where else key) in ignore}
        if a.keys() - ignored != b.keys() - ignored:
            yield f"{where} keys {sorted((set(a) ^ set(b)) - ignored)}", None
        for key in a.keys() & b.keys():
            yield from _walk(a[key], b[key], f"{where}.{key}" if where else key, ignore)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            yield f"{where} length {len(a)} vs {len(b)}", None
            return
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            yield from _walk(x, y, f"{where}[{i}]", ignore)
    elif isinstance(a, int | float) and isinstance(b, int | float) and not isinstance(a, bool):
        diff = abs(float(a) - float(b))
        yield where, diff if math.isfinite(diff) else (0.0 if a == b else math.inf)
    elif a != b:
        yield f"{where}: {a!r} vs {b!r}", None


def compare(before: dict[str, Any], after: dict[str, Any], tolerance: float, ignore: set[str]) -> bool:
    worst, worst_at, same = 0.0, "", True
    for name in sorted(before.keys() | after.keys()):
        if name not in before or name not in after:
            print(f"{name}: only in {'the recording' if name in before else 'the new answers'}")
            same = False
            continue
        largest, at, mismatches = 0.0, "", []
        for where, diff in _walk(before[name], after[name], "", ignore):
            if diff is None:
                mismatches.append(where)
            elif diff > largest:
                largest, at = diff, where
        if largest > worst:
            worst, worst_at = largest, f"{name}: {at}"
        ok = not mismatches and largest <= tolerance
        same &= ok
        line = f"{'same' if ok else 'DIFFERS'} {name}: largest difference {largest:.3g}"
        print(line + (f" at {at}" if largest > 0 else ""))
        for m in mismatches[:5]:
            print(f"    {m}")
    print(f"\nlargest difference of any number: {worst:.3g}" + (f" ({worst_at})" if worst > 0 else ""))
    return same


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    parser.add_argument("mode", choices=("record", "compare"))
    parser.add_argument("file", type=Path, help="the recording to write (record) or to compare with")
    parser.add_argument("--tolerance", type=float, default=1e-9)
    parser.add_argument("--ignore", action="append", default=[], help="a dotted key left out (repeatable)")
    args = parser.parse_args(argv)
    if args.mode == "record":
        args.file.write_text(json.dumps(record()))
        return 0
    before = json.loads(args.file.read_text())
    return 0 if compare(before, record(), args.tolerance, set(args.ignore)) else 1


if __name__ == "__main__":
    raise SystemExit(main())
