"""What the ``physical`` family fixes before its fit, and where its fit starts, from the data.

Nothing here knows the gate's size: every value comes from the static table, the records and
their sidecars (rules in :mod:`gatetwin.identification.physical`'s docstring). Each function returns
the value with a short statement of its source, which the model file's report carries.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.plant import physical_kernel as kernel
from gatetwin.records import Record

__all__ = [
    "DEPTH_MARGIN",
    "FINEST_QUANTUM_MM",
    "SUBSTEPS_PER_TIME_CONSTANT",
    "TEXTBOOK_CD",
    "WIDTH_QUANTILE",
    "area_scan_m2",
    "depth_bracket_m",
    "flow_normalisation",
    "gate_width_m",
    "max_substep_s",
    "opening_quantum_mm",
    "sample_period_s",
]

#: Free-flow discharge coefficient of a sluice gate at small openings (Henderson, Open
#: Channel Flow, 1966: 0.60-0.61), used only when the gate's width is not given.
TEXTBOOK_CD = 0.61
#: Share of the static points, at the smallest opening ratios, the width is taken from.
WIDTH_QUANTILE = 0.25
#: Margin of the bisection bracket over the highest level: a quarter of the smallest opening
#: at the largest discharge raises the steady depth at most sixteen-fold in free underflow
#: (h ~ 1/e^2); four covers half the smallest opening.
DEPTH_MARGIN = 4.0
#: Sub-steps per shortest time constant (RK4 is accurate to ~1e-5 of the step at 10).
SUBSTEPS_PER_TIME_CONSTANT = 10.0
#: Finest opening quantum looked for, mm (a micrometre).
FINEST_QUANTUM_MM = 1e-3


def _sidecar_value(records: dict[str, Record], key: str) -> tuple[float | None, str]:
    """The first record's sidecar ``key`` (a Record attribute where the reader exposes one)."""
    for name, rec in records.items():
        value = getattr(rec, key, None)
        if value is None:
            value = (getattr(rec, "metadata", None) or {}).get(key)
        if value is not None:
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise IdentificationError(
                    f"{name}: sidecar field {key!r}: {value!r}; expected a positive number"
                ) from None
            if not (math.isfinite(v) and v > 0):
                raise IdentificationError(
                    f"{name}: sidecar field {key!r}: {value!r}; expected a positive number"
                )
            return v, f"sidecar {key} of {name}"
    return None, ""


def gate_width_m(static: Any, records: dict[str, Record], gauge: str) -> tuple[float, str]:
    """The gate's width: the sidecar's, else the static points' at :data:`TEXTBOOK_CD`, m."""
    given, source = _sidecar_value(records, "gate_width_m")
    if given is not None:
        return given, source
    q = np.asarray(static.flow_m3h, float) / 3600.0
    e = np.asarray(static.opening_mm, float) / 1000.0
    h = np.asarray(static.levels_mm[gauge], float) / 1000.0
    ok = np.isfinite(q) & np.isfinite(e) & np.isfinite(h) & (e > 0) & (h > 0) & (q > 0)
    if not np.any(ok):
        raise IdentificationError(f"physical {gauge}: no static point to estimate the gate width")
    ratio = e[ok] / h[ok]
    small = ratio <= np.quantile(ratio, WIDTH_QUANTILE)
    width = q[ok][small] / (TEXTBOOK_CD * e[ok][small] * np.sqrt(2.0 * kernel.G * h[ok][small]))
    return float(np.median(width)), (
        f"static points at the smallest opening ratios with Cd = {TEXTBOOK_CD} (no gate_width_m)"
    )


def opening_quantum_mm(records: dict[str, Record]) -> tuple[float, str]:
    """The sidecar's actuator resolution, else the largest power of ten dividing every opening."""
    given, source = _sidecar_value(records, "actuator_resolution_mm")
    if given is not None:
        return given, source
    e = np.concatenate([rec.opening_mm[rec.hold] for rec in records.values()])
    e = np.abs(e[np.isfinite(e)])
    if e.size == 0:
        raise IdentificationError("physical: no recorded opening to find the actuator's quantum")
    quantum = 10.0 ** math.floor(math.log10(max(float(e.max()), FINEST_QUANTUM_MM)))
    while quantum > FINEST_QUANTUM_MM:
        k = e / quantum
        # a recorded multiple of the quantum differs from an integer by rounding only
        if np.all(np.abs(k - np.round(k)) <= 1e-6 * np.maximum(1.0, k)):
            break
        quantum /= 10.0
    quantum = max(quantum, FINEST_QUANTUM_MM)
    return float(f"{quantum:.3g}"), "largest power of ten dividing every recorded opening"


def flow_normalisation(static: Any) -> tuple[float, float, str]:
    """Centre (two significant figures of the mid-range) and scale (power of ten at or above
    the span) of the static table's discharges, m³/h."""
    q = np.asarray(static.flow_m3h, float)
    q = q[np.isfinite(q)]
    lo, hi = float(q.min()), float(q.max())
    mid = 0.5 * (lo + hi)
    centre = float(f"{mid:.2g}") if mid > 0 else 0.0
    span = hi - lo if hi > lo else max(hi, 1.0)
    scale = 10.0 ** math.ceil(math.log10(span))
    return centre, scale, "static table's discharge mid-range and span"


def depth_bracket_m(points_level_mm: np.ndarray, records: dict[str, Record], gauge: str) -> float:
    """The power of two at or above :data:`DEPTH_MARGIN` times the highest level, m."""
    levels = [np.asarray(points_level_mm, float)]
    levels += [rec.levels_mm[gauge] for rec in records.values() if gauge in rec.levels_mm]
    x = np.concatenate(levels)
    top = float(np.max(x[np.isfinite(x)])) / 1000.0
    return 2.0 ** math.ceil(math.log2(max(DEPTH_MARGIN * top, 1e-3)))


def sample_period_s(records: dict[str, Record]) -> float:
    """The shortest nominal sample period of the records, s."""
    return float(min(rec.sample_period_s for rec in records.values()))


def max_substep_s(period_s: float, time_constants_s: np.ndarray) -> tuple[float, str]:
    """Half the sample period, or a tenth of the shortest time constant when that is shorter."""
    t = np.asarray(time_constants_s, float)
    t = t[np.isfinite(t) & (t > 0)]
    half = 0.5 * period_s
    if t.size and float(t.min()) / SUBSTEPS_PER_TIME_CONSTANT < half:
        return float(f"{t.min() / SUBSTEPS_PER_TIME_CONSTANT:.3g}"), (
            "a tenth of the shortest time constant at the steady points"
        )
    return half, "half the sample period"


def area_scan_m2(period_s: float, longest_s: float, conductance_m2s: float, n: int
                 ) -> np.ndarray:  # fmt: skip
    """Storage areas whose time constants, at the conductance ``∂Q_g/∂h`` (m²/s), span one
    sample period to the longest record (log-spaced, ``n`` of them), m²."""
    taus = np.geomspace(period_s, max(longest_s, 2.0 * period_s), n)
    return taus * conductance_m2s
