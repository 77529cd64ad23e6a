"""Test-wide settings: under CI (``CI`` set) hypothesis draws the same examples on every run; the
browser tests, deselected by default (pyproject's ``addopts``), are counted and named at the end."""

from __future__ import annotations

import os

import pytest
from hypothesis import settings

settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

_BROWSER_DESELECTED = pytest.StashKey[int]()


def pytest_deselected(items: list[pytest.Item]) -> None:
    # counted only when the browser tests are left out by the default `-m 'not browser'`
    if items and "not browser" in (items[0].config.option.markexpr or ""):
        config = items[0].config
        browser = sum(1 for item in items if item.get_closest_marker("browser"))
        config.stash[_BROWSER_DESELECTED] = config.stash.get(_BROWSER_DESELECTED, 0) + browser


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter, config: pytest.Config) -> None:
    count = config.stash.get(_BROWSER_DESELECTED, 0)
    if count:
        terminalreporter.write_line(
            f"{count} browser tests not run here (marker 'browser', headless Chromium): run them with "
            "`python -m pytest -m browser` or `bash .ci/viewer.sh` (see the README's viewer section)",
            yellow=True,
        )
