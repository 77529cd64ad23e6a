"""app.executor: plans in plan processes while the event loop answers; a dead process fails only its own
call and is replaced, as is one that served max_calls or grew above max_rss; no more than max_pending
calls are taken and none starts after its deadline; draining refuses new work and cuts running work;
plan processes die with their parent.

No timing here: the latency of /healthz under load is measured by ``bench/load.py``."""

from __future__ import annotations

import asyncio
import contextlib
import os
import subprocess
import sys
import time
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from app.executor import DeadlineExceeded, Overloaded, PlanExecutor, ProcessDied, ShuttingDown
from app.main import create_app
from app.settings import Settings
from tests.app.workers import sleep_then_pid

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.anyio
async def test_plans_run_in_a_process_pool_while_the_loop_answers(demo: dict[str, Any]) -> None:
    app = create_app(Settings(plan_processes=1))
    # a budget (and so a deadline) that four queued plans fit in on a loaded machine too: this test is
    # about the pool, the deadline's refusal has tests of its own
    demo["options"] = {**demo.get("options", {}), "time_budget_ms": 30_000.0}
    async with app.router.lifespan_context(app):
        executor: PlanExecutor = app.state.plan_executor
        assert executor.uses_processes
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as client:
            plans = [asyncio.create_task(client.post("/v1/plan", json=demo)) for _ in range(4)]
            while executor.pending < 4:  # all four queued for the one process
                await asyncio.sleep(0.001)
            health = await client.get("/healthz")
            assert health.status_code == 200 and health.json() == {"status": "ok"}
            assert executor.pending > 0  # answered while plans were queued or running
            answers = await asyncio.gather(*plans)
            assert [r.json()["status"] for r in answers] == ["ok"] * 4
            # a planner error raised in the pool process keeps its type, status and field
            demo["ego"]["heading"] = 3.0
            r = await client.post("/v1/plan", json=demo)
            assert r.status_code == 422 and r.json()["error"]["code"] == "invalid_input"
            assert r.json()["error"]["details"][0]["field"] == "ego.heading"
    assert not executor.uses_processes  # the lifespan's end stopped the pool


@pytest.mark.anyio
async def test_a_dead_pool_process_fails_its_call_and_the_pool_is_renewed() -> None:
    executor = PlanExecutor(processes=1, max_pending=4)
    await executor.start()
    try:
        with pytest.raises(ProcessDied, match="died before it answered"):
            await executor.run(os._exit, 3)
        assert await executor.run(abs, -2) == 2
    finally:
        await executor.shutdown()


@pytest.mark.anyio
async def test_the_executor_refuses_more_than_max_pending() -> None:
    executor = PlanExecutor(processes=0, max_pending=1)
    started, release = asyncio.Event(), asyncio.Event()
    loop = asyncio.get_running_loop()

    def blocking(_: None) -> str:
        loop.call_soon_threadsafe(started.set)
        asyncio.run_coroutine_threadsafe(release.wait(), loop).result()
        return "done"

    first = asyncio.create_task(executor.run(blocking, None))
    await started.wait()
    with pytest.raises(Overloaded):
        await executor.run(blocking, None)
    release.set()
    assert await first == "done" and executor.pending == 0


@contextlib.asynccontextmanager
async def started(**options: Any) -> AsyncIterator[PlanExecutor]:
    """A started executor (``max_pending`` 4 unless given), shut down afterwards."""
    executor = PlanExecutor(**{"max_pending": 4, **options})
    await executor.start()
    try:
        yield executor
    finally:
        await executor.shutdown()


@pytest.mark.anyio
async def test_a_dead_process_fails_only_its_own_call() -> None:
    async with started(processes=2) as executor:
        survivor = asyncio.ensure_future(executor.run(sleep_then_pid, 1.0))
        await asyncio.sleep(0.2)  # the survivor runs in one process, the crash goes to the other
        with pytest.raises(ProcessDied):
            await executor.run(os._exit, 3)
        assert await survivor > 0  # not failed with it
        assert executor.recycled["died"] == 1
        assert await executor.run(abs, -2) == 2  # the slot got a fresh process


@pytest.mark.anyio
async def test_a_process_is_replaced_after_max_calls_and_above_max_rss() -> None:
    async with started(processes=1, max_calls=2) as executor:
        pids = [await executor.run(sleep_then_pid, 0.0) for _ in range(3)]
        assert pids[0] == pids[1] != pids[2] and executor.recycled["calls"] == 1
    async with started(processes=1, max_rss_bytes=1) as executor:  # every process is too big
        first, second = [await executor.run(sleep_then_pid, 0.0) for _ in range(2)]
        assert first != second and executor.recycled["memory"] == 2


@pytest.mark.anyio
async def test_a_call_that_cannot_start_before_its_deadline_is_refused() -> None:
    async with started(processes=1) as executor:
        busy = asyncio.ensure_future(executor.run(sleep_then_pid, 1.5))
        await asyncio.sleep(0.2)
        with pytest.raises(DeadlineExceeded):
            await executor.run(abs, -1, deadline=time.monotonic() + 0.2)
        with pytest.raises(DeadlineExceeded):
            await executor.run(abs, -1, deadline=time.monotonic() - 1.0)
        assert await busy > 0
        assert await executor.run(abs, -1, deadline=time.monotonic() + 10) == 1


@pytest.mark.anyio
async def test_draining_refuses_new_and_queued_calls_and_cuts_running_ones() -> None:
    executor = PlanExecutor(processes=1, max_pending=4)
    await executor.start()
    running = asyncio.ensure_future(executor.run(sleep_then_pid, 30.0))
    await asyncio.sleep(0.3)
    queued = asyncio.ensure_future(executor.run(abs, -1))
    await asyncio.sleep(0.1)
    assert await executor.ping(2.0)  # busy is answering
    executor.drain(0.5)
    assert not await executor.ping(2.0)
    with pytest.raises(ShuttingDown):
        await queued
    with pytest.raises(ShuttingDown):
        await executor.run(abs, -1)
    with pytest.raises(ProcessDied):  # cut after 0.5 s, not after 30
        await asyncio.wait_for(running, 10)
    await executor.shutdown()


def test_plan_processes_die_with_their_parent(tmp_path: Path) -> None:
    script = tmp_path / "parent.py"
    script.write_text(
        "import asyncio, os, sys, time\n"
        f"sys.path.insert(0, {str(ROOT)!r})\n"
        "from app.executor import PlanExecutor\n"
        "async def main():\n"
        "    executor = PlanExecutor(processes=1, max_pending=1)\n"
        "    await executor.start()\n"
        "    print(await executor.run(pid, None), flush=True)\n"
        "    time.sleep(60)\n"
        "from tests.app.workers import pid\n"
        "if __name__ == '__main__':\n"
        "    asyncio.run(main())\n"
    )
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, cwd=ROOT)
    try:
        assert parent.stdout is not None
        lines = (line.strip() for line in parent.stdout)  # log lines first, then the child's pid
        child = int(next(line for line in lines if line.isdigit()))
        assert _alive(child)
        parent.kill()
        parent.wait(10)
        deadline = time.monotonic() + 10
        while _alive(child) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(child)
    finally:
        parent.kill()


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"
