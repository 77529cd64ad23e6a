"""The Python client material of openapi/clients/python, without a server or a network.

The end-to-end run (a generated, pip-installed client planning the demo against a live server) is
``.ci/clients.sh``; here: the checks of ``plan_demo.plan_problems`` catch what they are meant to, and
a client generated from ``openapi/openapi.json`` and repaired by ``fix_generated.py`` reads and writes
the app's real answers unchanged.
"""

from __future__ import annotations

import copy
import importlib
import importlib.util
import math
import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from fastapi.testclient import TestClient

ROOT = Path(__file__).resolve().parents[2]
CLIENTS = ROOT / "openapi" / "clients" / "python"


def _load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"_clients_{name}", CLIENTS / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


plan_demo = _load("plan_demo")
fix_generated = _load("fix_generated")


@pytest.fixture(scope="module")
def demo_plan(client: TestClient) -> tuple[dict[str, Any], dict[str, Any]]:
    """The demo request and the app's answer to it, as JSON data."""
    request = client.get("/v1/demo").json()
    answer = client.post("/v1/plan", json=request)
    assert answer.status_code == 200, answer.text
    return request, answer.json()


def test_the_demo_plan_passes_the_checks(demo_plan: tuple[dict[str, Any], dict[str, Any]]) -> None:
    request, plan = demo_plan
    assert plan_demo.plan_problems(request, plan) == []


def _broken(plan: dict[str, Any], change: str) -> dict[str, Any]:
    plan = copy.deepcopy(plan)
    points = plan["trajectory"]
    if change == "moved start":
        points[0]["x"] += 1e-5
    elif change == "late start":
        for p in points:
            p["t"] += 0.05
    elif change == "uneven step":
        points[5]["t"] += 1e-6
    elif change == "negative speed":
        points[-1]["v"] = -1e-9
    elif change == "infinite speed":
        points[3]["v"] = math.inf
    elif change == "past the horizon":
        points.append({**points[-1], "t": points[-1]["t"] + 0.1})
    elif change == "empty":
        plan["trajectory"] = []
    elif change == "unknown status":
        plan["status"] = "planned"
    elif change == "fallback":
        plan["status"] = "fallback"
    return plan


@pytest.mark.parametrize(
    ("change", "found"),
    [
        ("moved start", "from the ego"),
        ("late start", "not 0"),
        ("uneven step", "does not follow"),
        ("negative speed", "v[80]"),
        ("infinite speed", "v[3]"),
        ("past the horizon", "past the horizon"),
        ("empty", "empty"),
        ("unknown status", "not one of"),
        ("fallback", "not 'ok'"),
    ],
)
def test_the_checks_catch_a_broken_plan(
    demo_plan: tuple[dict[str, Any], dict[str, Any]], change: str, found: str
) -> None:
    request, plan = demo_plan
    assert len(plan["trajectory"]) == 81  # the indices above
    problems = plan_demo.plan_problems(request, _broken(plan, change))
    assert any(found in p for p in problems), problems


def test_a_fallback_passes_when_not_expected_ok(demo_plan: tuple[dict[str, Any], dict[str, Any]]) -> None:
    request, plan = demo_plan
    assert plan_demo.plan_problems(request, _broken(plan, "fallback"), expect_ok=False) == []


@pytest.fixture(scope="module")
def generated(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ModuleType]:
    """The client generated from openapi/openapi.json (the pinned generator, no network), repaired."""
    pytest.importorskip("openapi_python_client")
    out = tmp_path_factory.mktemp("client") / "kappa_planner_client"
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    subprocess.run(
        [
            sys.executable, "-m", "openapi_python_client", "generate",
            "--path", str(ROOT / "openapi" / "openapi.json"),
            "--config", str(CLIENTS / "config.yaml"),
            "--meta", "none", "--output-path", str(out), "--fail-on-warning",
        ],
        check=True, env=env, capture_output=True, text=True,
    )  # fmt: skip
    assert fix_generated.fix_project(out), "the generator no longer needs the fix: drop fix_generated.py"
    sys.path.insert(0, str(out.parent))
    try:
        yield importlib.import_module("kappa_planner_client.models")
    finally:
        sys.path.remove(str(out.parent))
        for name in [m for m in sys.modules if m.split(".")[0] == "kappa_planner_client"]:
            del sys.modules[name]


def test_the_generated_models_keep_the_answers(
    generated: ModuleType, client: TestClient, demo_plan: tuple[dict[str, Any], dict[str, Any]]
) -> None:
    request, plan = demo_plan
    assert generated.PlanningRequest.from_dict(request).to_dict() == request
    assert generated.PlanResponse.from_dict(plan).to_dict() == plan
    candidates = client.post("/v1/candidates", json=request)
    assert candidates.status_code == 200
    assert generated.CandidatesResponse.from_dict(candidates.json()).to_dict() == candidates.json()
    frenet = client.post("/v1/frenet", json={"reference_line": [[0, 0], [50, 0]], "points": [[10, 2]]})
    assert generated.FrenetResponse.from_dict(frenet.json()).to_dict() == {"s": [10.0], "d": [2.0]}
    error = client.post("/v1/frenet", json={"reference_line": [[0, 0]], "points": [[10, 2]]}).json()
    assert generated.ErrorResponse.from_dict(error).to_dict() == error


def test_the_fix_renames_only_the_local() -> None:
    before = (
        "    def from_dict(cls, src_dict):\n"
        "        d = dict(src_dict)\n"
        '        d = d.pop("d")\n'
        '        odd = d.pop("odd", UNSET)\n'
        "        thing = cls(d=d, odd=odd)\n"
        "        thing.additional_properties = d\n"
    )
    after = fix_generated.fix_source(before)
    assert after == (
        "    def from_dict(cls, src_dict):\n"
        "        _src_dict = dict(src_dict)\n"
        '        d = _src_dict.pop("d")\n'
        '        odd = _src_dict.pop("odd", UNSET)\n'
        "        thing = cls(d=d, odd=odd)\n"
        "        thing.additional_properties = _src_dict\n"
    )
    assert fix_generated.fix_source(after) == after
    with pytest.raises(ValueError, match="_src_dict"):
        fix_generated.fix_source(before + "        _src_dict = 1\n")
