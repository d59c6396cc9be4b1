"""Helpers for the JSON form of identification results (no NaN or infinity in JSON)."""

from __future__ import annotations

import math
from collections.abc import Iterable

__all__ = ["finite_list", "finite_or_none", "none_to_nan"]


def finite_or_none(value: float | None) -> float | None:
    """``float(value)`` when finite, else ``None`` (JSON ``null``)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def finite_list(values: Iterable[float]) -> list[float | None]:
    """:func:`finite_or_none` applied to every value."""
    return [finite_or_none(v) for v in values]


def none_to_nan(value: float | None) -> float:
    """Inverse of :func:`finite_or_none` for reading: ``None`` becomes NaN."""
    return float("nan") if value is None else float(value)
