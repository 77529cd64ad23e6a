"""A request body from bytes to a validated model, at a cost bounded by the body's size.

Runs in a plan process (:mod:`app.jobs`), never in the event loop. Three steps, each refusing with a
:class:`RequestError` (a 422 in the one error shape):

1. **Structure.** A body with more JSON arrays or objects than any valid request of its kind can hold
   (:class:`Structure`, from :mod:`app.limits`) is refused before it is parsed: parsing it would build
   millions of Python objects for nothing.
2. **JSON.** The standard library's parser, as FastAPI's would, except that a key twice in one object is
   refused, with the path of the key (``obstacles.3.id``): JSON leaves duplicates undefined and a
   silent "last one wins" hides a client's bug.
3. **Schema.** The pydantic model, which stops at the first bad item of each long list (``fail_fast``
   on the models' big arrays), so that a body full of type errors costs a few hundred errors at most;
   the answer lists the first :data:`app.errors.MAX_DETAILS`.

Everything refused here is an :class:`app.errors.RequestError`.
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from app.errors import RequestError, invalid_request

M = TypeVar("M", bound=BaseModel)


@dataclasses.dataclass(frozen=True)
class Structure:
    """The most JSON arrays and objects a valid request body can hold, and how many ``[``/``{``
    characters its strings can add (ids, enum values)."""

    arrays: int
    objects: int
    in_strings: int

    def check(self, body: bytes) -> None:
        """Refuse ``body`` if it has more ``[`` or ``{`` than a valid request can (a cheap, exact upper
        bound: every array or object of a body starts with one of them)."""
        for char, most, kind in ((b"[", self.arrays, "arrays"), (b"{", self.objects, "objects")):
            count = body.count(char)
            if count > most + self.in_strings:
                raise RequestError(
                    422,
                    "invalid_request",
                    "The request does not match the schema.",
                    [("", f"the body holds {count} JSON {kind}; a valid request holds at most {most}")],
                )


class _DuplicateKey(Exception):
    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _unique(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """``object_pairs_hook`` of :func:`json.loads`: the object, or :exc:`_DuplicateKey`."""
    out = dict(pairs)
    if len(out) != len(pairs):
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise _DuplicateKey(key)
            seen.add(key)
    return out


class _Pairs(list[tuple[str, Any]]):
    """An object as its list of pairs, duplicates kept (to find where a duplicate is)."""


def _duplicate_path(body: bytes) -> str:
    """The dotted path of the first key that occurs twice in one object of ``body`` (valid JSON)."""
    root = json.loads(body, object_pairs_hook=_Pairs)
    todo: list[tuple[list[str], Any]] = [([], root)]
    while todo:
        path, node = todo.pop(0)
        if isinstance(node, _Pairs):
            seen: set[str] = set()
            for key, value in node:
                if key in seen:
                    return ".".join([*path, key])
                seen.add(key)
                todo.append(([*path, key], value))
        elif isinstance(node, list):
            todo.extend(([*path, str(i)], v) for i, v in enumerate(node))
    return ""


def _malformed(reason: str) -> RequestError:
    return RequestError(422, "malformed_json", "The request body is not valid JSON.", [("", reason)])


def load_json(body: bytes) -> Any:
    """``body`` parsed as JSON (UTF-8, or UTF-16/32 with its BOM as :func:`json.loads` detects), or a
    :class:`RequestError`: malformed (with line and column), nested too deeply, an integer literal too
    long for Python, or a key twice in one object (422 ``duplicate_key`` naming its path)."""
    try:
        return json.loads(body, object_pairs_hook=_unique)
    except _DuplicateKey as dup:
        path = _duplicate_path(body)
        raise RequestError(
            422,
            "duplicate_key",
            "The request body has a key twice in one object.",
            [(path, f"the key {dup.key!r} occurs more than once in this object")],
        ) from None
    except json.JSONDecodeError as exc:
        raise _malformed(f"{exc.msg} at line {exc.lineno}, column {exc.colno}") from None
    except UnicodeDecodeError:
        raise _malformed("the body is not UTF-8 text") from None
    except RecursionError:
        raise _malformed("nested too deeply") from None
    except ValueError as exc:  # e.g. an integer literal over Python's digit limit
        raise _malformed(str(exc).split(":")[0]) from None


def parse(body: bytes, model: type[M], structure: Structure) -> M:
    """``body`` as a validated ``model`` (see the module's docstring), or a :class:`RequestError`."""
    structure.check(body)
    if not body.strip():
        raise invalid_request([{"type": "missing", "loc": ("body",), "msg": ""}])
    data = load_json(body)
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise invalid_request(exc.errors(include_url=False)) from None
