"""The viewer in a real browser: Playwright (extra ``browser``, PyPI ``playwright``) driving the system
Chromium (Debian's ``chromium``; no browser download), against a live server.

    python -m pytest -m browser                                     # starts its own server
    python -m pytest -m browser tests/browser --viewer-url http://127.0.0.1:8000   # a running one

The tests carry the marker ``browser`` (``pytestmark``), which the default run (``python -m pytest``,
pyproject's ``addopts``) deselects and names at its end; ``.ci/viewer.sh`` installs Chromium and runs them in
CI. Without Chromium or Playwright they fail, saying what to install: asked for, they never skip.
Screenshots go to ``$VIEWER_ARTIFACTS`` (default ``.ci/artifacts/viewer/``, git-ignored).

Chromium is ``$CHROMIUM`` or the first of ``chromium``, ``chromium-browser`` on PATH, started headless
with the flags a machine without network access needs (no background connections, QUIC, sync or
component updates) and a fresh profile.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

ROOT = Path(__file__).resolve().parents[2]
ARTIFACTS = Path(os.environ.get("VIEWER_ARTIFACTS", ROOT / ".ci" / "artifacts" / "viewer"))
CHROMIUM_FLAGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
#: the longest a page may take to draw a plan [ms] (a plan takes tens of ms; CI machines are slow)
DRAW_TIMEOUT_MS = 60_000
INSTALL = (
    "install Debian's Chromium (apt-get install chromium) and Playwright "
    "(pip install -e '.[browser]'), or run bash .ci/viewer.sh, which does both"
)


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.getgroup("browser").addoption(
        "--viewer-url",
        default=None,
        help="test the viewer of the kappa-planner at this URL (default: start one on a free port)",
    )


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture(scope="session")
def base_url(pytestconfig: pytest.Config, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The service under test: ``--viewer-url``, or ``python -m app`` (granian, as deployed) started here
    on a free port (stopped at the end)."""
    given = pytestconfig.getoption("viewer_url")
    if given:
        yield str(given).rstrip("/")
        return
    port = _free_port()
    log = (tmp_path_factory.mktemp("server") / "server.log").open("w")
    proc = subprocess.Popen(
        [sys.executable, "-m", "app"],
        cwd=ROOT,
        env={**os.environ, "KAPPA_HOST": "127.0.0.1", "KAPPA_PORT": str(port)},
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        deadline = time.monotonic() + 60
        while True:
            if proc.poll() is not None:
                pytest.fail(f"the server exited with {proc.returncode}; see {log.name}")
            try:
                if httpx.get(f"{url}/healthz", timeout=2).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.monotonic() > deadline:
                pytest.fail(f"the server did not answer /healthz within 60 s; see {log.name}")
            time.sleep(0.2)
        yield url
    finally:
        proc.terminate()
        proc.wait(timeout=30)
        log.close()


@pytest.fixture(scope="session")
def api(base_url: str) -> Iterator[httpx.Client]:
    """The same service, for the answers the page is compared with."""
    with httpx.Client(base_url=base_url, timeout=120) as client:
        yield client


def _chromium() -> str:
    path = os.environ.get("CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    if not path:
        pytest.fail(f"no Chromium found: {INSTALL}", pytrace=False)
    return path


@pytest.fixture(scope="session")
def browser() -> Iterator[Any]:
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail(f"Playwright is not installed: {INSTALL}", pytrace=False)
    with sync_playwright() as p:
        chromium = p.chromium.launch(executable_path=_chromium(), args=CHROMIUM_FLAGS)
        yield chromium
        chromium.close()


class PageProblems:
    """Uncaught errors of the page and Content-Security-Policy violations: each fails the test."""

    def __init__(self) -> None:
        self.errors: list[str] = []

    def console(self, message: Any) -> None:
        if "Content Security Policy" in message.text:
            self.errors.append(f"console: {message.text}")

    def page_error(self, error: Any) -> None:
        self.errors.append(f"page error: {error}")


@pytest.fixture
def page(browser: Any, request: pytest.FixtureRequest) -> Iterator[Any]:
    """A fresh page (its own context: no storage shared between tests) of 1400 × 860 px."""
    context = browser.new_context(viewport={"width": 1400, "height": 860})
    page = context.new_page()
    page.set_default_timeout(DRAW_TIMEOUT_MS)
    problems = PageProblems()
    page.on("console", problems.console)
    page.on("pageerror", problems.page_error)
    yield page
    ARTIFACTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / f"{request.node.name}.png"))
    context.close()
    assert not problems.errors, "\n".join(problems.errors)
