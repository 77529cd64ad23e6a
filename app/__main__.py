"""``python -m app``: serve the API with uvicorn as configured by :class:`app.settings.Settings`.

``KAPPA_WORKERS`` > 1 starts that many uvicorn worker processes; their metrics are summed through
prometheus-client's multiprocess mode in ``PROMETHEUS_MULTIPROC_DIR`` (a fresh temporary directory,
removed at exit, unless the variable is set; then its ``*.db`` files of an earlier run are removed).
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import uvicorn

from app.logs import uvicorn_log_config
from app.settings import Settings

#: prometheus-client's multiprocess directory (see app.metrics; not imported here, so that the
#: variable is set before prometheus-client is imported anywhere)
MULTIPROC_ENV = "PROMETHEUS_MULTIPROC_DIR"


def prepare_multiprocess_metrics() -> Path | None:
    """Point ``PROMETHEUS_MULTIPROC_DIR`` at an empty directory; return it if it was made here."""
    given = os.environ.get(MULTIPROC_ENV)
    if given:
        path = Path(given)
        path.mkdir(parents=True, exist_ok=True)
        for stale in path.glob("*.db"):
            stale.unlink()
        return None
    made = Path(tempfile.mkdtemp(prefix="kappa-metrics-"))
    os.environ[MULTIPROC_ENV] = str(made)
    return made


def main() -> None:
    """Run uvicorn with host, port, workers and log level from the environment (``KAPPA_*``)."""
    settings = Settings()
    made = prepare_multiprocess_metrics() if settings.workers > 1 else None
    try:
        uvicorn.run(
            "app.main:app",
            host=settings.host,
            port=settings.port,
            workers=settings.workers,
            log_level=settings.log_level,
            log_config=uvicorn_log_config(settings.log_level),
            access_log=False,  # the service logs one JSON line per request (app.access)
        )
    finally:
        if made is not None:
            shutil.rmtree(made, ignore_errors=True)


if __name__ == "__main__":
    main()
