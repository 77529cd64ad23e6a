"""The service the regression suite talks to: ``--base-url URL`` for a running server, else the app
in-process (FastAPI's TestClient).

    pytest tests/regression                                   # in-process
    pytest tests/regression --base-url http://localhost:8000  # a running server or container

``--base-url`` is known to pytest when ``tests/regression`` (or a file in it) is named on the command
line, since this conftest is then loaded before the arguments are parsed. With pytest-base-url installed,
its option of the same name is used.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:  # `pytest tests/regression` without PYTHONPATH=.
    sys.path.insert(0, str(ROOT))

#: seconds to wait for one answer of a remote server
TIMEOUT = 120.0


def pytest_addoption(parser: pytest.Parser) -> None:
    with contextlib.suppress(ValueError):  # pytest-base-url defines it already
        parser.getgroup("regression").addoption(
            "--base-url",
            dest="base_url",
            default=None,
            help="run tests/regression against the kappa-planner at this URL (default: the app in-process)",
        )


@pytest.fixture(scope="session")
def base_url(pytestconfig: pytest.Config) -> str | None:
    """The ``--base-url`` given, or None (in-process)."""
    url = pytestconfig.getoption("base_url", default=None)
    return str(url).rstrip("/") if url else None


@pytest.fixture(scope="session")
def service(base_url: str | None) -> Iterator[httpx.Client]:
    """An HTTP client on the service under test."""
    if base_url:
        with httpx.Client(base_url=base_url, timeout=TIMEOUT) as client:
            yield client
        return
    from fastapi.testclient import TestClient

    from app.main import create_app

    with TestClient(create_app(), raise_server_exceptions=False) as client:
        yield client
