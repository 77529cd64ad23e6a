"""The exported OpenAPI document is current and shows the limits, operations and examples."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app.main import app

EXPORT = Path(__file__).resolve().parents[2] / "openapi" / "export.py"


def _export_module() -> Any:
    spec = importlib.util.spec_from_file_location("openapi_export", EXPORT)
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_export_check_passes(capsys: pytest.CaptureFixture[str]) -> None:
    assert _export_module().main(["--check"]) == 0, capsys.readouterr().err


def test_export_check_fails_on_a_stale_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    module = _export_module()
    stale = tmp_path / "openapi.json"
    stale.write_text("{}\n")
    monkeypatch.setattr(module, "TARGET", stale)
    monkeypatch.setattr(module, "ROOT", tmp_path)
    assert module.main(["--check"]) == 1
    assert "not what the app serves" in capsys.readouterr().err


def test_operations_are_tagged_and_named() -> None:
    spec = app.openapi()
    ops = {
        (path, method): op for path, item in spec["paths"].items() for method, op in item.items()
    }
    assert {(p, m): o["operationId"] for (p, m), o in ops.items()} == {
        ("/healthz", "get"): "healthz",
        ("/readyz", "get"): "readyz",
        ("/v1/frenet", "post"): "to_frenet",
        ("/v1/cartesian", "post"): "to_cartesian",
        ("/v1/candidates", "post"): "generate_candidates",
        ("/v1/plan", "post"): "plan_trajectory",
        ("/v1/demo", "get"): "get_demo_request",
        ("/metrics", "get"): "metrics",
    }
    for op in ops.values():
        assert op["tags"] and op["summary"] and op["description"]
        assert "\n" not in op["description"]
    for path in ("/v1/frenet", "/v1/cartesian", "/v1/candidates"):
        post = spec["paths"][path]["post"]
        assert post["requestBody"]["content"]["application/json"]["examples"]
        error = post["responses"]["422"]["content"]["application/json"]["schema"]
        assert error == {"$ref": "#/components/schemas/ErrorResponse"}


def test_limits_show_in_the_schema() -> None:
    schemas = app.openapi()["components"]["schemas"]
    ref = schemas["PlanningRequest"]["properties"]["reference_line"]
    assert (ref["minItems"], ref["maxItems"]) == (2, 20000)
    assert ref["items"]["prefixItems"][0]["maximum"] == 1e7
    options = schemas["Options"]["properties"]
    assert options["dt"]["minimum"] == 0.02 and options["dt"]["maximum"] == 1
    assert options["horizon_time"]["exclusiveMinimum"] == 0
    assert options["generator"]["enum"] == ["naive", "transf_kappa"]
    assert options["num_candidates"]["maximum"] == 2000
    assert schemas["DynamicObstacle"]["properties"]["prediction"]["maxItems"] == 2000
    assert schemas["PolygonObstacle"]["properties"]["polygon"]["minItems"] == 3
    assert len(schemas["PlanningRequest"]["properties"]["obstacles"]["items"]["oneOf"]) == 3
    assert schemas["Vehicle"]["properties"]["length"]["default"] == 4.5


def test_every_request_example_is_accepted(client: TestClient) -> None:
    for path, item in app.openapi()["paths"].items():
        body = item.get("post", {}).get("requestBody")
        if not body:
            continue
        for name, example in body["content"]["application/json"]["examples"].items():
            r = client.post(path, json=example["value"])
            assert r.status_code == 200, (path, name, r.text[:300])
