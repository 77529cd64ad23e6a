"""GET /healthz (liveness: the event loop answers) and GET /readyz (readiness: the plan processes
answer; 503 once the service drains)."""

from __future__ import annotations

import httpx
import pytest
from fastapi.testclient import TestClient

from app.executor import PlanExecutor
from app.main import create_app
from app.settings import Settings


def test_healthz(client: TestClient) -> None:
    r = client.get("/healthz")
    assert r.status_code == 200
    assert r.json() == {"status": "ok"}


@pytest.mark.anyio
async def test_readyz_follows_the_plan_processes() -> None:
    app = create_app(Settings(plan_processes=1))
    async with app.router.lifespan_context(app):
        executor: PlanExecutor = app.state.plan_executor
        transport = httpx.ASGITransport(app=app)
        async with httpx.AsyncClient(transport=transport, base_url="http://test") as client:
            r = await client.get("/readyz")
            assert r.status_code == 200 and r.json() == {"status": "ready"}
            executor.drain(0.1)  # what SIGTERM does
            r = await client.get("/readyz")
            assert r.status_code == 503 and r.json()["error"]["code"] == "not_ready"
            assert (await client.get("/healthz")).status_code == 200  # alive while it drains
