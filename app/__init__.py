"""The HTTP layer of kappa-planner: FastAPI app, request/response models and their limits, error mapping."""

__version__ = "0.1.0"
