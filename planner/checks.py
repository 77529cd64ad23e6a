"""Checks of the values a planning problem is built from: each returns the value as the planner keeps
it, or raises :class:`~planner.errors.InvalidInputError` naming the field as the JSON request does
(``ego.speed``, ``lane.left_width.3``, ``obstacles.2.prediction``)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from planner.errors import InvalidInputError
from planner.reference import FloatArray

#: largest vehicle or obstacle dimension [m]: longer than the equator (4·10⁷ m), so no real object's;
#: far beyond it the squares of lengths overflow
MAX_SIZE = 1e8


def number(value: Any, where: str) -> float:
    """``value`` as a finite float, or :class:`InvalidInputError` naming ``where``."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidInputError("must be a number", field=where)
    out = float(value)
    if not math.isfinite(out):
        raise InvalidInputError("must be finite", field=where)
    return out


def integer(value: Any, where: str, minimum: int) -> int:
    """``value`` as an int of at least ``minimum``, or :class:`InvalidInputError` naming ``where``."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise InvalidInputError("must be an integer", field=where)
    if value < minimum:
        raise InvalidInputError(f"must be at least {minimum}", field=where)
    return int(value)


def width(value: Any, where: str) -> float | FloatArray:
    """A lane or road width [m] in ``[0, MAX_SIZE]``, or a 1-D float array of them (``value`` itself when
    it is one already); a bad value of an array is named by its index (``lane.left_width.3``)."""
    if isinstance(value, int | float | np.integer | np.floating | bool | str | bytes):
        scalar = number(value, where)
        if not 0.0 <= scalar <= MAX_SIZE:
            raise InvalidInputError(f"must be between 0 and {MAX_SIZE:g} m", field=where)
        return scalar
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError("must be a number or an array of numbers", field=where) from None
    if arr.ndim == 0:
        return width(float(arr), where)
    if arr.ndim != 1:
        raise InvalidInputError(
            f"must be a number or one number per reference point, not {arr.shape}", field=where
        )
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise InvalidInputError("must be finite", field=f"{where}.{bad[0]}")
    bad = np.flatnonzero((arr < 0.0) | (arr > MAX_SIZE))
    if bad.size:
        raise InvalidInputError(f"must be between 0 and {MAX_SIZE:g} m", field=f"{where}.{bad[0]}")
    return arr


def array(value: Any, where: str, shape: tuple[int | None, ...], *, min_rows: int = 1) -> FloatArray:
    """``value`` as a finite float array of ``shape`` (``None``: any length, at least ``min_rows``);
    ``value`` itself when it is one already."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError("must be an array of numbers", field=where) from None
    if arr.ndim != len(shape) or (shape[-1] is not None and arr.shape[-1] != shape[-1]):
        wanted = " × ".join("k" if n is None else str(n) for n in shape)
        raise InvalidInputError(f"must have shape ({wanted}), not {arr.shape}", field=where)
    if arr.ndim and arr.shape[0] < min_rows:
        raise InvalidInputError(f"needs at least {min_rows} rows, has {arr.shape[0]}", field=where)
    if not np.isfinite(arr).all():
        raise InvalidInputError("must be finite", field=where)
    return arr


def size(value: Any, where: str) -> float:
    """A size [m] in ``[0, MAX_SIZE]``; zero (or a size below rounding) makes the obstacle a point or a
    segment."""
    out = number(value, where)
    if not 0.0 <= out <= MAX_SIZE:
        raise InvalidInputError(f"must be between 0 and {MAX_SIZE:g} m", field=where)
    return out
