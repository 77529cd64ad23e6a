"""Structured logs: one JSON object per line, with the id of the request being served.

Every record becomes ``{"ts", "level", "logger", "message", "request_id"?, …extras, "exc_info"?}``:
``ts`` is UTC ISO 8601 with milliseconds, the extras are the ``extra={…}`` fields of the logging call,
``request_id`` is :data:`REQUEST_ID` (set by :class:`app.middleware.RequestContextMiddleware` while it
serves a request) when the record was made: the log record factory notes it on every record.

``python -m app`` configures every logger (granian's included) with :func:`server_log_config`;
:func:`configure_logging` covers any other server (``uvicorn app.main:app``) and embedding: it sets up
JSON lines on stdout only when nothing configured the root logger before (the semantics of
``logging.basicConfig``).
"""

from __future__ import annotations

import json
import logging
import sys
from contextvars import ContextVar
from datetime import UTC, datetime
from typing import Any

#: the id of the request being served (``None`` outside a request)
REQUEST_ID: ContextVar[str | None] = ContextVar("request_id", default=None)

#: attributes every LogRecord has; anything else on a record came from ``extra``
_RECORD_ATTRIBUTES = frozenset(
    vars(logging.LogRecord("", logging.INFO, "", 0, "", None, None)).keys()
    | {"message", "asctime", "color_message"}  # uvicorn's message with ANSI colours: noise in JSON
)


class JSONFormatter(logging.Formatter):
    """One JSON object per record, on one line (see the module's docstring)."""

    def format(self, record: logging.LogRecord) -> str:
        """The record as one line of JSON; values JSON does not know are written with ``str``."""
        entry: dict[str, Any] = {
            "ts": datetime.fromtimestamp(record.created, UTC).isoformat(timespec="milliseconds"),
            "level": record.levelname.lower(),
            "logger": record.name,
            "message": record.getMessage(),
        }
        entry.update((k, v) for k, v in vars(record).items() if k not in _RECORD_ATTRIBUTES)
        if record.exc_info:
            entry["exc_info"] = self.formatException(record.exc_info)
        if record.stack_info:
            entry["stack_info"] = self.formatStack(record.stack_info)
        return json.dumps(entry, default=str, ensure_ascii=False)


def _install_record_factory() -> None:
    """Make every log record carry ``request_id`` while a request is served (once per process)."""
    previous = logging.getLogRecordFactory()
    if getattr(previous, "notes_request_id", False):
        return

    def factory(*args: Any, **kwargs: Any) -> logging.LogRecord:
        record = previous(*args, **kwargs)
        request_id = REQUEST_ID.get()
        if request_id is not None:
            record.request_id = request_id
        return record

    factory.notes_request_id = True  # type: ignore[attr-defined]
    logging.setLogRecordFactory(factory)


def configure_logging(level: str) -> None:
    """JSON lines on stdout for every logger unless the root logger has handlers already; the
    service's loggers (``app.*``) at ``level``; request ids on every record; the servers' access logs
    off (the service writes its own line per request, ``app.access``)."""
    _install_record_factory()
    if not logging.root.handlers:
        handler = logging.StreamHandler(sys.stdout)
        handler.setFormatter(JSONFormatter())
        logging.root.addHandler(handler)
    logging.getLogger("app").setLevel(level.upper())
    for name in ("uvicorn.access", "granian.access"):
        logging.getLogger(name).disabled = True


def server_log_config(level: str) -> dict[str, Any]:
    """A ``logging.config.dictConfig`` for the HTTP server (granian's ``log_dictconfig``, applied in its
    supervisor and in every worker): everything as JSON lines on stdout, granian's own logger and the
    service's at ``level``; granian's access log off (the service writes its own line per request,
    ``app.access``)."""
    level = level.upper()
    return {
        "version": 1,
        "disable_existing_loggers": False,
        "formatters": {"json": {"()": f"{__name__}.JSONFormatter"}},
        "handlers": {
            "stdout": {"class": "logging.StreamHandler", "formatter": "json", "stream": "ext://sys.stdout"}
        },
        "root": {"handlers": ["stdout"], "level": "WARNING"},
        "loggers": {
            "_granian": {"handlers": [], "level": level, "propagate": True},
            "granian.access": {"handlers": [], "level": "CRITICAL", "propagate": False},
            "app": {"level": level},
        },
    }
