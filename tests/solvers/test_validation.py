"""The shared input checks: converted values back, a ValueError naming the field otherwise."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from solvers.validation import check_ordered, check_weights, float_array, integer, scalar


def test_scalar() -> None:
    assert scalar("x", np.float32(1.5)) == 1.5 and isinstance(scalar("x", 2), float)
    assert scalar("x", math.inf, allow_posinf=True) == math.inf
    for value, match in (
        (math.inf, "x: must be finite, got inf"),
        (-math.inf, "finite or"),
        (math.nan, "nan"),
    ):
        with pytest.raises(ValueError, match=match):
            scalar("x", value, allow_posinf=match == "finite or")
    for value in (True, "1.0", None, [1.0]):
        with pytest.raises(ValueError, match="x: must be a number"):
            scalar("x", value)


def test_integer() -> None:
    assert integer("n", np.int64(3), low=1) == 3
    with pytest.raises(ValueError, match="n: must be an integer ≥ 1, got 0"):
        integer("n", 0, low=1)
    with pytest.raises(ValueError, match="n: must be an integer in 1 … 5, got 6"):
        integer("n", 6, low=1, high=5)
    for value in (True, 2.0, "2"):
        with pytest.raises(ValueError, match="n: must be an integer"):
            integer("n", value, low=0)


def test_float_array() -> None:
    source = [1.0, 2.0]
    array = float_array("a", source, size=2)
    assert array.dtype == np.float64 and not array.flags.writeable
    assert float_array("a", [-math.inf, 1.0], allow_neginf=True)[0] == -math.inf
    cases = [
        ({"value": [[1.0]]}, "a: expected a 1-D array, got shape"),
        ({"value": [1.0], "size": 2}, r"a: expected shape \(2,\), got \(1,\)"),
        ({"value": [1.0, math.nan]}, "a: invalid value nan at index 1"),
        ({"value": [math.inf], "allow_neginf": True}, "a: invalid value inf at index 0"),
        (
            {"value": [0.0, -math.inf], "allow_posinf": True, "item": "knot"},
            "a: invalid value -inf at knot 1",
        ),
        ({"value": ["x"]}, "a: must be an array of numbers"),
    ]
    for kwargs, match in cases:
        with pytest.raises(ValueError, match=match):
            float_array("a", **kwargs)  # type: ignore[arg-type]


def test_check_ordered() -> None:
    check_ordered("lo", np.zeros(3), "hi", np.zeros(3))
    with pytest.raises(ValueError, match=r"lo > hi at knot 2: 1\.0 > 0\.0"):
        check_ordered("lo", np.array([0.0, 0.0, 1.0]), "hi", np.zeros(3))


@dataclass(frozen=True)
class _Weights:
    a: float = 1.0
    b: float = 0.0

    def __post_init__(self) -> None:
        check_weights(self, zero_allowed=("b",))


def test_check_weights() -> None:
    assert isinstance(_Weights(a=2).a, float)
    for kwargs, match in (
        ({"a": 0.0}, r"weights\.a: must be > 0"),
        ({"b": -1.0}, r"weights\.b: must be ≥ 0"),
    ):
        with pytest.raises(ValueError, match=match):
            _Weights(**kwargs)
    for value in (math.nan, True, "1"):
        with pytest.raises(ValueError, match=r"weights\.a: must be a finite number"):
            _Weights(a=value)  # type: ignore[arg-type]
