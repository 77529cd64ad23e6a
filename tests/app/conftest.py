"""Fixtures of the HTTP tests: a client on the app and the demo request."""

from __future__ import annotations

import copy
import sys
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # `pytest tests/app` without PYTHONPATH=.
    sys.path.insert(0, str(ROOT))

from fastapi.testclient import TestClient  # noqa: E402

from app.conversions import demo_request  # noqa: E402
from app.main import create_app  # noqa: E402


@pytest.fixture(scope="session")
def client() -> TestClient:
    """A client that answers server errors as responses instead of raising them."""
    return TestClient(create_app(), raise_server_exceptions=False)


@pytest.fixture
def demo() -> dict[str, Any]:
    """A fresh copy of the demo planning request as JSON data."""
    return copy.deepcopy(demo_request().model_dump(mode="json"))
