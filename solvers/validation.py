"""Input checks shared by the solvers' problem types: misuse is a ``ValueError`` naming the field.

Each check returns the value converted (``float``, ``int`` or a read-only float64 copy), so a problem's
``__post_init__`` stores exactly what it checked.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def scalar(name: str, value: object, *, allow_posinf: bool = False) -> float:
    """``value`` as a finite float (or ``+inf`` with ``allow_posinf``); booleans and strings are misuse."""
    if isinstance(value, bool | str | bytes):
        raise ValueError(f"{name}: must be a number, got {value!r}")
    try:
        result = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a number, got {value!r}") from None
    if math.isnan(result) or result == -math.inf or (result == math.inf and not allow_posinf):
        raise ValueError(f"{name}: must be finite{' or +inf' if allow_posinf else ''}, got {result}")
    return result


def integer(name: str, value: object, *, low: int, high: int | None = None) -> int:
    """``value`` as an ``int`` in ``low … high`` (no upper end when ``high`` is ``None``)."""
    ok = isinstance(value, int | np.integer) and not isinstance(value, bool)
    number = int(value) if ok else 0  # type: ignore[call-overload]
    if not ok or number < low or (high is not None and number > high):
        rule = f"≥ {low}" if high is None else f"in {low} … {high}"
        raise ValueError(f"{name}: must be an integer {rule}, got {value!r}")
    return number


def float_array(
    name: str,
    value: ArrayLike,
    *,
    size: int | None = None,
    allow_posinf: bool = False,
    allow_neginf: bool = False,
    item: str = "index",
) -> FloatArray:
    """A read-only float64 copy of ``value``: 1-D (of ``size`` entries if given), no NaN, no ±∞ unless
    allowed. ``item`` names an entry in the messages (``"index"``, ``"knot"``)."""
    try:
        array = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be an array of numbers") from None
    if size is None and array.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D array, got shape {array.shape}")
    if size is not None and array.shape != (size,):
        raise ValueError(f"{name}: expected shape ({size},), got {array.shape}")
    bad = np.isnan(array)
    if not allow_posinf:
        bad |= np.isposinf(array)
    if not allow_neginf:
        bad |= np.isneginf(array)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name}: invalid value {array[i]} at {item} {i}")
    array.setflags(write=False)
    return array


def check_ordered(lower_name: str, lower: FloatArray, upper_name: str, upper: FloatArray) -> None:
    """``lower ≤ upper`` entry by entry (knots)."""
    bad = lower > upper
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{lower_name} > {upper_name} at knot {i}: {lower[i]} > {upper[i]}")


def check_weights(weights: Any, *, zero_allowed: Collection[str]) -> None:
    """Every field of the frozen dataclass ``weights`` a finite number, ``≥ 0`` for the names in
    ``zero_allowed`` and ``> 0`` for the others; stored back as ``float``."""
    for entry in fields(weights):
        name = entry.name
        value = getattr(weights, name)
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise ValueError(f"weights.{name}: must be a finite number, got {value!r}")
        positive = name not in zero_allowed
        if value < 0 or (positive and value == 0):
            raise ValueError(f"weights.{name}: must be {'> 0' if positive else '≥ 0'}, got {value!r}")
        object.__setattr__(weights, name, float(value))
