"""Helpers of the HTTP tests: the one error shape, a raw JSON post, an expected error, a failing route."""

from __future__ import annotations

import json
from typing import Any

import pytest
from fastapi.testclient import TestClient

from app import jobs as candidates_route


def error_fields(response: Any) -> list[str]:
    """The fields named by an error answer, after checking it has the one error shape."""
    body = response.json()
    assert set(body) == {"error"}
    error = body["error"]
    assert set(error) == {"code", "message", "details"}
    assert error["code"] and error["message"]
    for detail in error["details"]:
        assert set(detail) == {"field", "message"}
        assert detail["message"]
    return [d["field"] for d in error["details"]]


def post(client: TestClient, body: Any, path: str = "/v1/candidates") -> Any:
    content = body if isinstance(body, str | bytes) else json.dumps(body)
    return client.post(path, content=content, headers={"content-type": "application/json"})


def expect(response: Any, status: int, code: str, field: str) -> None:
    assert response.status_code == status, response.text
    assert response.json()["error"]["code"] == code
    assert field in error_fields(response)


def fail_candidates(monkeypatch: pytest.MonkeyPatch, error: Exception) -> None:
    """Make ``POST /v1/candidates`` raise ``error`` where it generates the candidates."""

    def fail(*args: Any, **kwargs: Any) -> Any:
        raise error

    monkeypatch.setattr(candidates_route, "generate_candidates", fail)
