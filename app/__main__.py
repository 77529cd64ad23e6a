"""``python -m app``: serve the API with uvicorn as configured by :class:`app.settings.Settings`."""

from __future__ import annotations

import uvicorn

from app.settings import Settings


def main() -> None:
    """Run uvicorn with host, port, workers and log level from the environment (``KAPPA_*``)."""
    settings = Settings()
    uvicorn.run(
        "app.main:app",
        host=settings.host,
        port=settings.port,
        workers=settings.workers,
        log_level=settings.log_level,
    )


if __name__ == "__main__":
    main()
