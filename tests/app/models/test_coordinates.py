"""app.models.coordinates: a query needs at least one point."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from tests.app.helpers import expect, post


@pytest.mark.parametrize("path", ["/v1/frenet", "/v1/cartesian"])
def test_empty_query(client: TestClient, path: str) -> None:
    key = "points" if path.endswith("frenet") else "frenet"
    r = post(client, {"reference_line": [[0, 0], [1, 0]], key: []}, path)
    expect(r, 422, "invalid_request", key)
