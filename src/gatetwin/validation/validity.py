"""Whether a record lies inside the validity envelope an FMU states for itself.

A gatetwin FMU carries ``resources/provenance.json``; its ``validity`` object (written at
export, see :func:`gatetwin.modelfile.validity_envelope`) gives ``[low, high]`` ranges of
the discharge ``flow_m3h`` (m³/h), the gate opening ``opening_mm`` (mm) and the level at the
model's gauge ``level_mm`` (mm), each only when known. FMUs exported before the object
existed state only ``validity_flow_m3h``, read as the flow range.

A record is compared with the envelope on the signals the harness drives the FMU with and
compares it against: the opening given to the FMU (hold openings, reconstructed while the
gate moves), the measured discharge and the measured level at the FMU's gauge. Per quantity,
``outside_by`` is the largest distance of a sample beyond the range, in the quantity's unit
(0 when every sample is inside). A quantity counts as outside only when that distance exceeds
its measurement tolerance (:data:`TOLERANCES`; the level's is :data:`LEVEL_TOLERANCE_SIGMAS`
times the record's noise SD): a discharge logged 0.4 m³/h beyond the range of the records the
model was identified from is still their operating point.

``inside`` is three-valued: ``False`` when any stated range is left, ``True`` only when all
three ranges are stated and kept, ``None`` otherwise (no envelope, or one that leaves a
quantity unknown): an unknown range is never taken as kept.

Findings only; whether an outside record fails is the caller's decision.
"""

from __future__ import annotations

import json
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.errors import ValidationError
from gatetwin.modelfile import FLOW_METER_ACCURACY_M3H
from gatetwin.records.segments import RESOLUTION_MM

__all__ = [
    "LABELS",
    "LEVEL_TOLERANCE_SIGMAS",
    "PROVENANCE",
    "QUANTITIES",
    "TOLERANCES",
    "Envelope",
    "ValidityFinding",
    "read_envelope",
    "record_validity",
]

#: The quantities of an envelope, in report order.
QUANTITIES = ("opening_mm", "flow_m3h", "level_mm")
#: Word and unit of each quantity in messages.
LABELS = {"opening_mm": ("opening", "mm"), "flow_m3h": ("flow", "m³/h"),
          "level_mm": ("level", "mm")}  # fmt: skip
#: Fixed measurement tolerances: the flow meter's accuracy and the actuator's resolution.
TOLERANCES = {"flow_m3h": FLOW_METER_ACCURACY_M3H, "opening_mm": RESOLUTION_MM}
#: The level's tolerance in noise SDs: a sample this close to the range is noise around it.
LEVEL_TOLERANCE_SIGMAS = 3.0
#: Where an FMU keeps its provenance.
PROVENANCE = "resources/provenance.json"

Envelope = dict[str, tuple[float, float]]


def _range(fmu: Path, key: str, value: Any) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValidationError(
            f"{fmu}: {PROVENANCE}: validity range {key} must be [low, high], got {value!r}"
        ) from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise ValidationError(f"{fmu}: {PROVENANCE}: validity range {key} [{lo}, {hi}] is empty")
    return lo, hi


def read_envelope(path: str | Path) -> Envelope | None:
    """The validity envelope an FMU states, or None when it states none.

    Parameters
    ----------
    path : str or Path
        A readable FMU (a zip archive; see :func:`~gatetwin.validation.fmu_runner.inspect_fmu`).

    Returns
    -------
    dict or None
        ``{quantity: (low, high)}`` for the quantities the FMU states (a subset of
        :data:`QUANTITIES`); None without ``resources/provenance.json``, without a
        ``validity`` object or ``validity_flow_m3h`` in it, or when it is not a JSON object.

    Raises
    ------
    ValidationError
        A stated range that is not two finite numbers with low <= high.
    """
    fmu = Path(path)
    try:
        with zipfile.ZipFile(fmu) as archive:
            provenance = json.loads(archive.read(PROVENANCE).decode("utf-8"))
    except (KeyError, zipfile.BadZipFile, OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    if not isinstance(provenance, dict):
        return None
    stated = provenance.get("validity")
    if not isinstance(stated, dict):
        legacy = provenance.get("validity_flow_m3h")
        stated = {"flow_m3h": legacy} if legacy is not None else {}
    envelope = {q: _range(fmu, q, stated[q]) for q in QUANTITIES if q in stated}
    return envelope or None


@dataclass(frozen=True)
class ValidityFinding:
    """A record against an FMU's validity envelope.

    Attributes
    ----------
    envelope : dict or None
        The FMU's stated ranges (None when it states none).
    record_range : dict[str, tuple[float, float]]
        Smallest and largest sample of each quantity in the record.
    outside_by : dict[str, float or None]
        Per quantity, the largest distance of a sample beyond the range, in its unit (0 when
        inside; None when the range is unknown).
    tolerance : dict[str, float]
        Per quantity, how far beyond the range still counts as inside, in its unit.
    """

    envelope: Envelope | None
    record_range: dict[str, tuple[float, float]]
    outside_by: dict[str, float | None]
    tolerance: dict[str, float]

    @property
    def outside(self) -> tuple[str, ...]:
        """Quantities beyond their range by more than their tolerance."""
        return tuple(q for q in QUANTITIES if (self.outside_by.get(q) or 0.0) > self.tolerance[q])

    @property
    def unknown(self) -> tuple[str, ...]:
        """Quantities the FMU states no range for."""
        return tuple(q for q in QUANTITIES if self.outside_by.get(q) is None)

    @property
    def inside(self) -> bool | None:
        """False when outside, True when inside every range and none is unknown, else None."""
        if self.envelope is None:
            return None
        if self.outside:
            return False
        return None if self.unknown else True

    def problems(self) -> list[str]:
        """One phrase per quantity outside, e.g. ``opening 12.0 mm below 15.0 mm``."""
        out = []
        for q in self.outside:
            word, unit = LABELS[q]
            lo, hi = (self.envelope or {})[q]
            low, high = self.record_range[q]
            if lo - low >= high - hi:
                out.append(f"{word} {low:.1f} {unit} below {lo:.1f} {unit}")
            else:
                out.append(f"{word} {high:.1f} {unit} above {hi:.1f} {unit}")
        return out

    def to_dict(self) -> dict[str, Any]:
        """``inside_validity``, ``validity``, ``outside_by`` and their details."""
        env = self.envelope
        return {
            "inside_validity": self.inside,
            "validity": None if env is None else {q: list(env[q]) for q in env},
            "outside_by": {q: self.outside_by.get(q) for q in QUANTITIES},
            "validity_tolerance": dict(self.tolerance),
            "validity_unknown": list(self.unknown),
            "record_range": {q: list(r) for q, r in self.record_range.items()},
        }


def _extent(values: np.ndarray) -> tuple[float, float] | None:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return (float(v.min()), float(v.max())) if v.size else None


def record_validity(
    envelope: Envelope | None,
    opening_mm: np.ndarray,
    flow_m3h: np.ndarray,
    level_mm: np.ndarray,
    level_noise_sd_mm: float,
) -> ValidityFinding:
    """Compare a record's samples with an envelope (see the module docstring).

    Parameters
    ----------
    envelope : dict or None
        From :func:`read_envelope`.
    opening_mm, flow_m3h, level_mm : ndarray
        The opening given to the FMU (mm), the discharge (m³/h) and the measured level at the
        FMU's gauge (mm); NaN samples are skipped.
    level_noise_sd_mm : float
        The record's level noise SD, mm (NaN: no level tolerance).
    """
    sigma = level_noise_sd_mm if math.isfinite(level_noise_sd_mm) else 0.0
    tolerance = {**TOLERANCES, "level_mm": LEVEL_TOLERANCE_SIGMAS * sigma}
    signals = {"opening_mm": opening_mm, "flow_m3h": flow_m3h, "level_mm": level_mm}
    extents = {q: _extent(signals[q]) for q in QUANTITIES}
    record_range = {q: e for q, e in extents.items() if e is not None}
    outside_by: dict[str, float | None] = {}
    for q in QUANTITIES:
        extent, stated = extents[q], (envelope or {}).get(q)
        if stated is None or extent is None:
            outside_by[q] = None
        else:
            outside_by[q] = max(0.0, stated[0] - extent[0], extent[1] - stated[1])
    return ValidityFinding(envelope, record_range, outside_by, tolerance)
