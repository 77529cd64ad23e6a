"""app.executor: plans in a process pool while the event loop answers, a dead process renews the pool,
and no more than max_pending calls are taken.

No timing here: the latency of /healthz under load is measured by ``bench/load.py``."""

from __future__ import annotations

import asyncio
import os
from typing import Any

import httpx
import pytest

from app.executor import Overloaded, PlanExecutor, ProcessDied
from app.main import create_app
from app.settings import Settings


@pytest.mark.anyio
async def test_plans_run_in_a_process_pool_while_the_loop_answers(demo: dict[str, Any]) -> None:
    app = create_app(Settings(plan_processes=1))
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
