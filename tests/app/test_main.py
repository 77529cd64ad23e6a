"""app.main: SIGTERM starts the executor's drain and then runs whatever handled SIGTERM before (the
server's graceful stop)."""

from __future__ import annotations

import os
import signal
import time
from types import FrameType

from app.main import _on_sigterm


def test_sigterm_drains_then_reaches_the_previous_handler() -> None:
    calls: list[str] = []

    def previous(signum: int, frame: FrameType | None) -> None:
        calls.append("server")

    original = signal.signal(signal.SIGTERM, previous)
    try:
        _on_sigterm(lambda: calls.append("drain"))
        os.kill(os.getpid(), signal.SIGTERM)
        deadline = time.monotonic() + 5
        while len(calls) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert calls == ["drain", "server"]
    finally:
        signal.signal(signal.SIGTERM, original)
