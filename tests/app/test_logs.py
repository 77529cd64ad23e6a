"""app.logs: one JSON object per record, with the request id; the HTTP server's logs in the same form."""

from __future__ import annotations

import json
import logging
import logging.config
from pathlib import Path

from app.logs import REQUEST_ID, JSONFormatter, server_log_config


def test_the_json_formatter() -> None:
    make = logging.getLogRecordFactory()  # notes the request id (app.logs)
    token = REQUEST_ID.set("rid-9")
    try:
        record = make("app.x", logging.WARNING, __file__, 1, "%d things", (3,), None)
    finally:
        REQUEST_ID.reset(token)
    record.__dict__.update(count=3, where=Path("/tmp"))
    line = JSONFormatter().format(record)
    assert "\n" not in line
    entry = json.loads(line)
    assert entry["message"] == "3 things" and entry["level"] == "warning" and entry["logger"] == "app.x"
    assert (entry["request_id"], entry["count"], entry["where"]) == ("rid-9", 3, "/tmp")
    assert entry["ts"].endswith("+00:00")
    outside = make("app.x", logging.WARNING, __file__, 1, "%d things", (3,), None)
    assert "request_id" not in json.loads(JSONFormatter().format(outside))


def test_the_servers_logs_are_json_too() -> None:
    config = server_log_config("debug")
    assert config["formatters"]["json"]["()"] == "app.logs.JSONFormatter"
    assert config["loggers"]["app"]["level"] == config["loggers"]["_granian"]["level"] == "DEBUG"
    assert config["loggers"]["_granian"]["propagate"] is True  # to the root's JSON handler
    assert config["loggers"]["granian.access"]["propagate"] is False  # the service logs requests itself
    logging.config.dictConfig({**config, "root": {"handlers": [], "level": "WARNING"}})  # a valid config
