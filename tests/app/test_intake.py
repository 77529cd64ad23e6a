"""app.intake: a body's structure bounded before it is parsed, duplicate keys found with their path,
the long lists validated fail-fast."""

from __future__ import annotations

import json

import pytest

from app.errors import RequestError
from app.intake import Structure, load_json, parse
from app.jobs import COORDINATES_STRUCTURE, PLANNING_STRUCTURE
from app.models.coordinates import FrenetRequest
from tests.app.test_limits import largest_request


def test_the_structure_bound_refuses_only_what_no_valid_request_holds() -> None:
    bound = Structure(arrays=3, objects=1, in_strings=2)
    bound.check(b'{"a": [[1], [2]], "b": "[["}')  # 3 arrays and 2 brackets in a string
    with pytest.raises(RequestError) as refused:
        bound.check(b"[[[[[[]]]]]]")
    assert refused.value.details == [("", "the body holds 6 JSON arrays; a valid request holds at most 3")]
    # the largest valid request passes its own bound
    PLANNING_STRUCTURE.check(json.dumps(largest_request()).encode())


def test_a_duplicate_key_is_named_by_its_path() -> None:
    with pytest.raises(RequestError) as dup:
        load_json(b'{"a": [{"b": 1}, {"c": {"d": 1, "d": 2}}]}')
    assert (dup.value.code, dup.value.details[0][0]) == ("duplicate_key", "a.1.c.d")
    assert load_json(b'{"a": {"b": 1}, "b": {"b": 2}}') == {"a": {"b": 1}, "b": {"b": 2}}  # not duplicates


@pytest.mark.parametrize(
    ("body", "reason"),
    [
        (b'{"a": ', "Expecting value at line 1, column 7"),
        (b"[" * 100_000, "nested too deeply"),
        (b'{"a": 1' + b"0" * 5000 + b"}", "Exceeds the limit (4300 digits) for integer string conversion"),
        (b'{"a": "\xff"}', "the body is not UTF-8 text"),
    ],
)
def test_malformed_bodies(body: bytes, reason: str) -> None:
    with pytest.raises(RequestError) as bad:
        load_json(body)
    assert (bad.value.status, bad.value.code, bad.value.details) == (422, "malformed_json", [("", reason)])


def test_parse_validates_into_the_model() -> None:
    body = b'{"reference_line": [[0, 0], [1, 0]], "points": [[0.5, 1]]}'
    assert parse(body, FrenetRequest, COORDINATES_STRUCTURE).points == [(0.5, 1.0)]
    with pytest.raises(RequestError) as empty:
        parse(b"  ", FrenetRequest, COORDINATES_STRUCTURE)
    assert empty.value.details == [("", "a JSON object is required")]
