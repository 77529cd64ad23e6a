"""Functions the executor tests run in plan processes: a module of their own, light to import (a
spawned process imports the module of the function it runs)."""

from __future__ import annotations

import os
import time


def sleep_then_pid(seconds: float) -> int:
    """Sleep ``seconds`` [s], then answer this process's id."""
    time.sleep(seconds)
    return os.getpid()


def pid(_: object) -> int:
    """This process's id."""
    return os.getpid()
