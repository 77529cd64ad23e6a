"""What the routes take from the application, as ``Annotated`` dependencies.

:func:`app.main.create_app` makes the settings and the plan executor once per application (tests make
applications with different settings) and keeps them in ``app.state``; a route takes them as
parameters (``settings: SettingsDep``) rather than reading ``request.app.state``, and a test can
replace them with ``app.dependency_overrides[get_settings]``. The getters are ``async`` so that FastAPI
calls them in the event loop rather than in its threadpool.
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from app.executor import PlanExecutor
from app.settings import Settings


async def get_settings(request: Request) -> Settings:
    """The settings the application was made with."""
    settings: Settings = request.app.state.settings
    return settings


async def get_plan_executor(request: Request) -> PlanExecutor:
    """The application's plan executor (its process pool runs while the lifespan does)."""
    executor: PlanExecutor = request.app.state.plan_executor
    return executor


SettingsDep = Annotated[Settings, Depends(get_settings)]
PlanExecutorDep = Annotated[PlanExecutor, Depends(get_plan_executor)]
