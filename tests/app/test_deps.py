"""app.deps: the routes take the settings and the plan executor through the dependencies, so a test (or
an embedding) can replace either. (Each application's own settings reaching its plans: test_plan.py's
time budget test.)"""

from __future__ import annotations

from typing import Any

from fastapi.testclient import TestClient

from app.deps import get_plan_executor, get_settings
from app.executor import PlanExecutor
from app.main import create_app
from app.settings import Settings


def test_the_settings_dependency_decides_the_budget(demo: dict[str, Any]) -> None:
    app = create_app(Settings(plan_processes=0, time_budget_ms=10_000.0))
    client = TestClient(app)
    assert client.post("/v1/plan", json=demo).json()["status"] == "ok"
    app.dependency_overrides[get_settings] = lambda: Settings(plan_processes=0, time_budget_ms=1.0)
    answer = client.post("/v1/plan", json=demo).json()  # 1 ms from arrival: spent before the plan starts
    assert answer["status"] == "fallback" and "time budget of 1 ms spent" in answer["message"]


def test_the_executor_dependency_runs_the_plans(demo: dict[str, Any]) -> None:
    calls: list[str] = []

    class Recording(PlanExecutor):
        async def run(self, fn: Any, arg: Any, deadline: float | None = None) -> Any:
            calls.append(f"{fn.__name__}({arg.kind})")
            return await super().run(fn, arg, deadline)

    app = create_app(Settings(plan_processes=0))
    app.dependency_overrides[get_plan_executor] = lambda: Recording(processes=0, max_pending=1)
    assert TestClient(app).post("/v1/plan", json=demo).json()["status"] == "ok"
    assert calls == ["run_job(plan)"]
