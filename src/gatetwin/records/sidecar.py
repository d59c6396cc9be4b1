"""The optional JSON sidecar of a record (``NAME.json`` next to ``NAME.csv``).

Reads and checks the sidecar fields of ``docs/record_format.md`` (``test``, ``sample_period_s``,
``gauges``, ``gate_width_m``, ``bounds``; ``condition`` and anything else are kept as
metadata). A bad sidecar is
refused with a one-line :class:`~gatetwin.errors.RecordError` naming the sidecar file and
field. This module does not read the CSV.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gatetwin.errors import RecordError
from gatetwin.records.bounds import Bounds, bounds_from_sidecar
from gatetwin.records.limits import MAX_SIDECAR_BYTES, open_regular

__all__ = [
    "TEST_TYPES",
    "VALIDATION_ROLE",
    "Sidecar",
    "read_sidecar",
    "sidecar_from_dict",
    "sidecar_path",
]

#: The test types of the data format.
TEST_TYPES = ("step", "prbs", "free", "routine")
#: Sidecar ``role`` of a record that is read and validated against but never fitted
#: (the others: ``fit``, the default, and ``held_out``, which checks the fits).
VALIDATION_ROLE = "validation"


@dataclass(frozen=True)
class Sidecar:
    """Checked sidecar contents (every field optional).

    Attributes
    ----------
    test : str or None
        ``"step"``, ``"prbs"``, ``"free"`` or ``"routine"`` (a history of routine
        operation: no designed test).
    sample_period_s : float or None
        Nominal sample period, s.
    gauges_m : dict[str, float]
        Gauge distance upstream of the gate, m.
    metadata : dict
        The whole sidecar object as read.
    gate_width_m : float or None
        Width of the gate opening (the sluice's clear span), m.
    bounds : Bounds
        Accepted value ranges (``bounds`` field, else the physical defaults).
    """

    test: str | None = None
    sample_period_s: float | None = None
    gauges_m: dict[str, float] = field(default_factory=dict)
    metadata: dict[str, Any] = field(default_factory=dict)
    gate_width_m: float | None = None
    bounds: Bounds = field(default_factory=Bounds)


def sidecar_path(csv_path: str | Path) -> Path:
    """The sidecar belonging to a record file (same stem, ``.json``)."""
    return Path(csv_path).with_suffix(".json")


def read_sidecar(csv_path: str | Path) -> Sidecar:
    """Read the sidecar of ``csv_path``; an empty :class:`Sidecar` if there is none.

    Raises
    ------
    RecordError
        If the sidecar is not UTF-8 JSON, not an object, or a field is invalid.
    """
    path = sidecar_path(csv_path)
    if not os.path.lexists(path):
        return Sidecar()
    try:
        with open_regular(path, MAX_SIDECAR_BYTES, "a JSON sidecar") as handle:
            text = handle.read().decode("utf-8-sig")
    except OSError as exc:
        raise RecordError(f"{path}: sidecar cannot be read ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise RecordError(f"{path}: sidecar is not UTF-8 text; expected a JSON object") from None
    return sidecar_from_dict(str(path), _parse_json(path, text))


def _parse_json(path: Path, text: str) -> Any:
    try:
        return json.loads(text, parse_constant=_refuse_constant)
    except json.JSONDecodeError as exc:
        raise RecordError(
            f"{path}: sidecar is not valid JSON (line {exc.lineno}, column {exc.colno}: "
            f"{exc.msg}); expected a JSON object"
        ) from None
    except (ValueError, RecursionError) as exc:
        raise RecordError(f"{path}: sidecar is not valid JSON ({exc})") from None


def _refuse_constant(word: str) -> None:
    raise ValueError(f"{word} is not a JSON number; expected finite numbers only")


def sidecar_from_dict(name: str, data: Any) -> Sidecar:
    """Check sidecar contents already parsed (``name`` labels error messages)."""
    if not isinstance(data, dict):
        raise RecordError(f"{name}: sidecar is a JSON {type(data).__name__}; expected an object")
    return Sidecar(
        test=_test_word(name, data.get("test")),
        sample_period_s=_period(name, data.get("sample_period_s")),
        gauges_m=_gauges(name, data.get("gauges")),
        metadata=dict(data),
        gate_width_m=_width(name, data.get("gate_width_m")),
        bounds=bounds_from_sidecar(name, data.get("bounds")),
    )


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _test_word(name: str, value: Any) -> str | None:
    if value is None or value in TEST_TYPES:
        return value
    raise RecordError(
        f"{name}: sidecar field 'test': {value!r} is not a test type; expected "
        "'step', 'prbs', 'free' or 'routine'"
    )


def _period(name: str, value: Any) -> float | None:
    if value is None:
        return None
    if _is_number(value) and math.isfinite(value) and value > 0:
        return float(value)
    raise RecordError(
        f"{name}: sidecar field 'sample_period_s': {value!r}; expected a positive number of seconds"
    )


def _width(name: str, value: Any) -> float | None:
    if value is None:
        return None
    if _is_number(value) and math.isfinite(value) and value > 0:
        return float(value)
    raise RecordError(
        f"{name}: sidecar field 'gate_width_m': {value!r}; expected a positive, finite width "
        "of the gate in metres"
    )


def _gauges(name: str, value: Any) -> dict[str, float]:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise RecordError(
            f"{name}: sidecar field 'gauges': expected an object of gauge name to distance "
            "upstream of the gate in m"
        )
    for gauge, distance in value.items():
        if not (_is_number(distance) and math.isfinite(distance) and distance >= 0):
            raise RecordError(
                f"{name}: sidecar field 'gauges': gauge {gauge!r} at {distance!r}; expected "
                "a distance upstream of the gate ≥ 0 m"
            )
    return {str(gauge): float(distance) for gauge, distance in value.items()}
