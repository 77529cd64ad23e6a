"""Where the service's computations run: off the event loop, one call at a time per plan process.

A plan is pure Python and numpy for most of its time and holds the GIL nearly all of it; so are the
parsing and validation of a large request. Run in the event loop's process, even in threads, they
delay everything the loop does — ``/healthz`` included. So each HTTP worker keeps ``processes`` plan
processes, and its own process only reads bodies and writes answers; every computation (parsing and
validating the body included, :mod:`app.jobs`) runs in a plan process, handed over as bytes.

Each plan process is a :class:`~concurrent.futures.ProcessPoolExecutor` of one process of its own (a
*slot*), spawned (not forked from a process with threads), at a lower CPU priority
(:data:`PLAN_NICENESS`), so that:

* a process that dies (a crash in a native solver, the OOM killer) fails only the call it was running
  (:exc:`ProcessDied`, answered 503 to retry); its slot gets a fresh process;
* a process is recycled after ``max_calls`` calls, or once it is above ``max_rss_bytes`` resident
  after a call (it measures itself after returning freed memory to the OS), so that no request leaves
  a process big for good;
* a process dies with its parent (``PR_SET_PDEATHSIG`` on Linux), so that killing a worker leaves no
  orphans.

Admission is bounded twice: at most ``max_pending`` calls are queued or running (:exc:`Overloaded`
beyond), and a call that finds no free process before its ``deadline`` is refused
(:exc:`DeadlineExceeded`) rather than started too late. Waiting callers are served first come, first
served. Stopping is bounded: :meth:`PlanExecutor.drain` (on SIGTERM) refuses new calls and cuts the
ones still running after a timeout (their processes killed, :exc:`ProcessDied`);
:meth:`PlanExecutor.shutdown` does the same at the end of the lifespan.

``processes = 0``, or an executor never started (an app whose lifespan did not run, such as a
``TestClient`` not used as a context manager), runs the work in a thread of the worker itself, one call
at a time, with the GIL caveat above.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import dataclasses
import logging
import multiprocessing
import os
import signal
import sys
import time
import traceback
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Generic, Literal, TypeVar

import anyio
import anyio.to_thread

logger = logging.getLogger(__name__)

#: added to the niceness of the plan processes: on a busy CPU the scheduler prefers the worker's event
#: loop (little CPU, wanted at once) to the plans
PLAN_NICENESS = 10
#: ``prctl`` option that has the kernel send a signal to a process when its parent dies (Linux)
PR_SET_PDEATHSIG = 1

A = TypeVar("A")
R = TypeVar("R")


class Overloaded(Exception):
    """More calls are queued or running than the executor accepts."""


class DeadlineExceeded(Exception):
    """No plan process became free before the call's deadline."""


class ProcessDied(Exception):
    """The plan process running the call died (or was killed at shutdown) before it answered."""


class ShuttingDown(Exception):
    """The executor is stopping and takes no new call."""


def die_with_parent(parent: int) -> None:
    """Have the kernel kill this process when ``parent`` (its parent) dies (Linux; elsewhere nothing);
    exit at once if it is dead already."""
    if not sys.platform.startswith("linux"):
        return
    with contextlib.suppress(OSError, AttributeError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    if os.getppid() != parent:  # the parent died before the line above
        os._exit(1)


def _process_init(setup: Callable[[], Any] | None, parent: int) -> None:
    """First thing in each plan process: die with the worker, leave SIGINT and SIGTERM to it (which
    stops the processes), lower its priority by :data:`PLAN_NICENESS`, then ``setup`` (a failure is
    logged: the process serves all the same)."""
    die_with_parent(parent)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    with contextlib.suppress(OSError, AttributeError):
        os.nice(PLAN_NICENESS)
    if setup is not None:
        try:
            setup()
        except Exception:
            logger.exception("setup of a plan process failed")


def resident_bytes() -> int:
    """Resident memory of this process [bytes] (Linux ``/proc``; 0 elsewhere)."""
    try:
        pages = int(open("/proc/self/statm").read().split()[1])  # noqa: SIM115
    except (OSError, ValueError, IndexError):
        return 0
    return pages * os.sysconf("SC_PAGE_SIZE")


def _trim_heap() -> None:
    """Give the C heap's free pages back to the OS (glibc ``malloc_trim``; elsewhere nothing)."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).malloc_trim(0)


@dataclasses.dataclass(frozen=True)
class _Reply(Generic[R]):
    """What a plan process sends back: the value or the exception of the call, and its size after."""

    value: R | None
    error: BaseException | None
    rss_bytes: int


def _call(fn: Callable[[A], R], arg: A) -> _Reply[R]:
    """Run ``fn(arg)`` in a plan process; the exception it raises travels back with its traceback as a
    note."""
    try:
        value, error = fn(arg), None
    except Exception as exc:
        exc.add_note("".join(traceback.format_exception(exc)))
        value, error = None, exc
    _trim_heap()
    return _Reply(value, error, resident_bytes())


def _pid() -> int:
    return multiprocessing.current_process().pid or 0


SlotState = Literal["starting", "idle", "busy", "stopped"]


@dataclasses.dataclass(eq=False)
class _Slot:
    """One plan process and what the executor knows of it."""

    index: int
    pool: ProcessPoolExecutor
    state: SlotState = "starting"
    calls: int = 0
    future: Future[Any] | None = None


class PlanExecutor:
    """Runs a picklable ``fn(arg)`` off the event loop (see the module's docstring)."""

    def __init__(
        self,
        processes: int,
        max_pending: int,
        setup: Callable[[], Any] | None = None,
        *,
        max_calls: int | None = None,
        max_rss_bytes: int | None = None,
        on_replace: Callable[[str], object] | None = None,
    ) -> None:
        """``processes`` plan processes (0: a thread), ``max_pending`` calls queued or running at most,
        ``setup`` run first in every plan process (a module-level function); a process is replaced
        after ``max_calls`` calls or when above ``max_rss_bytes`` resident after a call, and
        ``on_replace(reason)`` told (the metrics)."""
        if processes < 0 or max_pending < 1:
            raise ValueError("processes must be ≥ 0 and max_pending ≥ 1")
        self.processes = processes
        self.max_pending = max_pending
        self.max_calls = max_calls
        self.max_rss_bytes = max_rss_bytes
        self._setup = setup
        self._on_replace = on_replace
        self._slots: list[_Slot] = []
        self._idle: asyncio.Queue[_Slot] | None = None
        self._limiter: anyio.CapacityLimiter | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._closing = False
        self._background: set[asyncio.Task[int]] = set()
        self.pending = 0
        #: processes replaced so far, by reason (``calls``, ``memory``, ``died``)
        self.recycled: dict[str, int] = {"calls": 0, "memory": 0, "died": 0}

    @property
    def uses_processes(self) -> bool:
        """Whether calls go to plan processes (started, not stopped, ``processes`` > 0)."""
        return bool(self._slots) and not self._closing

    @property
    def closing(self) -> bool:
        """Whether :meth:`shutdown` has begun."""
        return self._closing

    def _new_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            1,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_process_init,
            initargs=(self._setup, os.getpid()),
        )

    async def start(self) -> None:
        """Start the plan processes (nothing when ``processes`` is 0) and wait until each answers."""
        if self.processes == 0 or self._slots:
            return
        self._loop = asyncio.get_running_loop()
        self._idle = asyncio.Queue()
        self._closing = False
        self._slots = [_Slot(i, self._new_pool()) for i in range(self.processes)]
        pids = await asyncio.gather(*(self._warm(slot) for slot in self._slots))
        logger.info("plan processes ready", extra={"processes": self.processes, "pids": sorted(pids)})

    async def _warm(self, slot: _Slot) -> int:
        """Spawn the slot's process (it runs ``setup``) and put the slot in the idle queue."""
        assert self._loop is not None and self._idle is not None
        pid = await self._loop.run_in_executor(slot.pool, _pid)
        if self._closing:
            return pid
        slot.state = "idle"
        self._idle.put_nowait(slot)
        return pid

    def _replace(self, slot: _Slot, reason: str) -> None:
        """Retire the slot's process and start a fresh one in the background."""
        old, slot.pool, slot.calls, slot.state = slot.pool, self._new_pool(), 0, "starting"
        old.shutdown(wait=False, cancel_futures=True)
        self.recycled[reason] += 1
        if self._on_replace is not None:
            self._on_replace(reason)
        logger.info("plan process replaced", extra={"slot": slot.index, "reason": reason})
        task = asyncio.ensure_future(self._warm(slot))
        self._background.add(task)
        task.add_done_callback(self._background.discard)

    def _finished(self, slot: _Slot, future: Future[_Reply[Any]]) -> None:
        """In the event loop, once the slot's call is done: recycle the process or make it idle."""
        slot.future = None
        if self._closing:
            slot.state = "stopped"
            return
        reason = None
        if not future.cancelled():  # cancelled before it started: nothing ran
            slot.calls += 1
        if future.cancelled():
            pass
        elif future.exception() is not None:
            reason = "died"
        elif self.max_rss_bytes is not None and future.result().rss_bytes > self.max_rss_bytes:
            reason = "memory"
        elif self.max_calls is not None and slot.calls >= self.max_calls:
            reason = "calls"
        if reason is not None:
            self._replace(slot, reason)
            return
        slot.state = "idle"
        assert self._idle is not None
        self._idle.put_nowait(slot)

    async def _acquire(self, deadline: float | None) -> _Slot:
        assert self._idle is not None
        with contextlib.suppress(asyncio.QueueEmpty):
            return self._idle.get_nowait()
        timeout = None if deadline is None else deadline - time.monotonic()
        if timeout is not None and timeout <= 0:
            raise DeadlineExceeded("no plan process is free and the deadline has passed")
        try:
            return await asyncio.wait_for(self._idle.get(), timeout)
        except TimeoutError:
            raise DeadlineExceeded("no plan process became free before the deadline") from None

    async def run(self, fn: Callable[[A], R], arg: A, deadline: float | None = None) -> R:
        """``fn(arg)`` in a plan process (or a thread) and its value; the exceptions of ``fn`` come back
        as they are.

        Raises :exc:`Overloaded` when ``max_pending`` calls are queued or running,
        :exc:`DeadlineExceeded` when no process is free before ``deadline`` (``time.monotonic()``),
        :exc:`ProcessDied` when the process died before it answered, :exc:`ShuttingDown` once
        :meth:`shutdown` has begun.
        """
        if self._closing:
            raise ShuttingDown("the service is shutting down")
        if self.pending >= self.max_pending:
            raise Overloaded(f"{self.pending} requests are queued or running")
        self.pending += 1
        try:
            if not self._slots:
                if self._limiter is None:
                    self._limiter = anyio.CapacityLimiter(1)
                return await anyio.to_thread.run_sync(fn, arg, limiter=self._limiter)
            slot = await self._acquire(deadline)
            if self._closing:  # woken by the shutdown
                raise ShuttingDown("the service is shutting down")
            return await self._submit(slot, fn, arg)
        finally:
            self.pending -= 1

    async def _submit(self, slot: _Slot, fn: Callable[[A], R], arg: A) -> R:
        assert self._loop is not None
        loop = self._loop
        slot.state = "busy"
        try:
            future: Future[_Reply[R]] = slot.pool.submit(_call, fn, arg)
        except (BrokenProcessPool, RuntimeError):
            self._replace(slot, "died")
            raise ProcessDied("the plan process had died") from None
        slot.future = future
        # released when the process is done, even if the caller stopped waiting (cancelled)
        future.add_done_callback(lambda f: loop.call_soon_threadsafe(self._finished, slot, f))
        try:
            reply = await asyncio.wrap_future(future)
        except BrokenProcessPool:
            raise ProcessDied("the plan process died before it answered") from None
        if reply.error is not None:
            raise reply.error
        return reply.value  # type: ignore[return-value]

    async def ping(self, timeout: float) -> bool:
        """Whether the plan processes answer: every process is up (busy or idle) and an idle one, if
        any, answers a trivial call within ``timeout`` s. True in thread mode unless shutting down."""
        if self._closing:
            return False
        if not self._slots:
            return True
        if any(slot.state not in ("idle", "busy") for slot in self._slots):
            return False
        assert self._idle is not None
        try:
            slot = self._idle.get_nowait()
        except asyncio.QueueEmpty:
            return True  # all busy with calls: answering
        try:
            await asyncio.wait_for(self._submit(slot, abs, 0), timeout)
        except (TimeoutError, ProcessDied):
            return False
        return True

    def drain(self, timeout: float) -> None:
        """Begin stopping (the service got SIGTERM): take no new call, and in ``timeout`` s kill the
        processes of the calls still running (their callers get :exc:`ProcessDied`, answered 503)
        — so that every request in flight is answered before the server's own deadline."""
        if self._closing:
            return
        self._closing = True
        if self._loop is not None and self._slots:
            self._loop.call_later(timeout, self._cut)
        self._wake_waiters()
        logger.info("draining", extra={"cut_after_s": timeout, "pending": self.pending})

    def _wake_waiters(self) -> None:
        """Wake every caller waiting for a process: each finds the executor closing (:exc:`ShuttingDown`)."""
        if self._idle is None or not self._slots:
            return
        for _ in range(self.pending):
            self._idle.put_nowait(self._slots[0])

    def _cut(self) -> None:
        for slot in self._slots:
            if slot.future is not None and not slot.future.done():
                logger.warning("cutting a call at shutdown", extra={"slot": slot.index})
                _kill(slot.pool)

    async def shutdown(self, timeout: float = 0.0) -> None:
        """Stop: take no new call and wake the waiting callers (:exc:`ShuttingDown`), let the running
        calls finish for up to ``timeout`` s, then kill the processes (calls still running get
        :exc:`ProcessDied`)."""
        self._closing = True
        if not self._slots:
            return
        self._wake_waiters()
        running = [slot.future for slot in self._slots if slot.future is not None]
        if running and timeout > 0:
            await asyncio.wait([asyncio.wrap_future(f) for f in running], timeout=timeout)
        self._cut()
        for slot in self._slots:
            _kill(slot.pool)
            slot.pool.shutdown(wait=False, cancel_futures=True)
            slot.state = "stopped"
        for task in list(self._background):
            task.cancel()
        self._wake_waiters()
        self._slots = []


def _kill(pool: ProcessPoolExecutor) -> None:
    """SIGKILL the process of a one-process pool (if it has one and it is alive)."""
    processes = getattr(pool, "_processes", None) or {}
    for process in list(processes.values()):
        with contextlib.suppress(OSError, AttributeError, ValueError):
            if process.is_alive():
                process.kill()
