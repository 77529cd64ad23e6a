"""Where plans run: off the event loop, in a pool of processes, at most so many waiting.

A plan is pure Python and numpy for most of its time and holds the GIL nearly all of it. Run in the
event loop's process, even in threads, it delays everything the loop does — ``/healthz`` included —
by whole GIL switch intervals per step (``bench/load.py`` measures it). So each uvicorn worker keeps a
pool of ``processes`` worker processes (:class:`concurrent.futures.ProcessPoolExecutor`, spawned, not
forked from a process with threads) that run the plans, and its own process only parses, validates and
answers. The pool processes run at a lower priority (:data:`PLAN_NICENESS`), so that a busy CPU still
serves the event loop first.

The pool is bounded twice: ``processes`` plans run at once, twice as many are handed to the pool (the
rest wait in the event loop, where they cost nothing: handed over all at once, a burst keeps the pool's
helper threads taking the GIL from the loop), and at most ``max_pending`` are queued or running
(:exc:`Overloaded` beyond, answered 503), so a burst queues in memory, not without end.

``processes = 0``, or a pool never started (an app whose lifespan did not run, such as a
``TestClient`` not used as a context manager), runs the work in a thread of the worker itself, one
call at a time, with the GIL caveat above.

A pool process that dies (a crash in a native solver) breaks the pool: the calls in flight fail (the
caller answers 500) and the next call gets a fresh pool.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import multiprocessing
import os
import signal
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

import anyio
import anyio.to_thread

logger = logging.getLogger(__name__)

#: calls handed to the pool at once per process (one running, one ready to start); the others wait in
#: the event loop, where waiting costs nothing (the pool's helper threads would take the GIL for each)
SLOTS_PER_PROCESS = 2
#: added to the niceness of the pool processes: on a busy CPU the scheduler prefers the worker's event
#: loop (little CPU, wanted at once) to the plans
PLAN_NICENESS = 5

A = TypeVar("A")
R = TypeVar("R")


class Overloaded(Exception):
    """More calls are queued or running than the executor accepts."""


def _process_init(setup: Callable[[], Any] | None) -> None:
    """First thing in each pool process: leave SIGINT to the parent (which shuts the pool down), lower
    its priority by :data:`PLAN_NICENESS`, then ``setup`` (a failure is logged: the process serves all
    the same)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    with contextlib.suppress(OSError, AttributeError):
        os.nice(PLAN_NICENESS)
    if setup is not None:
        try:
            setup()
        except Exception:
            logger.exception("setup of a plan process failed")


def _pid() -> int:
    return multiprocessing.current_process().pid or 0


class PlanExecutor:
    """Runs a picklable ``fn(arg)`` off the event loop (see the module's docstring)."""

    def __init__(
        self, processes: int, max_pending: int, setup: Callable[[], Any] | None = None
    ) -> None:
        """``processes`` pool size (0: a thread), ``max_pending`` calls queued or running at most,
        ``setup`` run first in every pool process (a module-level function)."""
        if processes < 0 or max_pending < 1:
            raise ValueError("processes must be ≥ 0 and max_pending ≥ 1")
        self.processes = processes
        self.max_pending = max_pending
        self._setup = setup
        self._pool: ProcessPoolExecutor | None = None
        self._limiter: anyio.CapacityLimiter | None = None
        self._slots: asyncio.Semaphore | None = None
        self.pending = 0

    @property
    def uses_processes(self) -> bool:
        """Whether calls go to the process pool (started and ``processes`` > 0)."""
        return self._pool is not None

    def _new_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            self.processes,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_process_init,
            initargs=(self._setup,),
        )

    async def start(self) -> None:
        """Start the pool's processes (nothing when ``processes`` is 0) and wait until one answers."""
        if self.processes == 0 or self._pool is not None:
            return
        self._pool = self._new_pool()
        self._slots = asyncio.Semaphore(SLOTS_PER_PROCESS * self.processes)
        loop = asyncio.get_running_loop()
        # one call per process: the pool starts a process per call while none is idle; the first
        # process up may answer them all while the others still run their setup
        pids = await asyncio.gather(*(loop.run_in_executor(self._pool, _pid) for _ in range(self.processes)))
        logger.info("plan pool ready", extra={"processes": self.processes, "answered_by": sorted(set(pids))})

    def shutdown(self) -> None:
        """Stop the pool: queued calls are cancelled, running ones finish."""
        pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)

    async def run(self, fn: Callable[[A], R], arg: A) -> R:
        """``fn(arg)`` in the pool (or a thread); :exc:`Overloaded` when ``max_pending`` calls are
        queued or running; :exc:`BrokenProcessPool` when a pool process died meanwhile. The exceptions
        of ``fn`` come back as they are."""
        if self.pending >= self.max_pending:
            raise Overloaded(f"{self.pending} plans are queued or running")
        self.pending += 1
        try:
            if self._pool is None or self._slots is None:
                if self._limiter is None:
                    self._limiter = anyio.CapacityLimiter(1)
                return await anyio.to_thread.run_sync(fn, arg, limiter=self._limiter)
            async with self._slots:
                return await self._submit(fn, arg)
        finally:
            self.pending -= 1

    async def _submit(self, fn: Callable[[A], R], arg: A) -> R:
        pool = self._pool
        if pool is None:
            raise RuntimeError("the plan pool is shut down")
        try:
            return await asyncio.wrap_future(pool.submit(fn, arg))
        except BrokenProcessPool:
            if self._pool is pool:
                logger.error("a plan process died; starting a new pool")
                self._pool = self._new_pool()
                pool.shutdown(wait=False, cancel_futures=True)
            raise
