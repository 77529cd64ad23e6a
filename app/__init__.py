"""The HTTP layer of kappa-planner: FastAPI app, request/response schemas, error mapping."""

__version__ = "0.1.0"
