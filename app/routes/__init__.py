"""One module per resource; :data:`routers` lists them in the order the OpenAPI document shows."""

from fastapi import APIRouter

from app.routes import candidates, coordinates, demo, health, metrics, plan, viewer

routers: list[APIRouter] = [
    coordinates.router,
    candidates.router,
    plan.router,
    demo.router,
    health.router,
    metrics.router,
    viewer.router,
]
