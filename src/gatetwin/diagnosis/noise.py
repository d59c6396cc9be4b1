"""The noise floor of a record and where a model's residual rises above it.

**Noise floor.** :func:`noise_floor` is :func:`gatetwin.noise.noise_floor` (the SD of the
level around a quadratic over the last half of steady holds, pooled; see that module) on the
diagnosis' steady stretches: hold samples at one *commanded* opening with no step of the
discharge, at least :data:`~gatetwin.noise.MIN_STRETCH_SAMPLES` long.

**Windows.** The residual's moving RMS over :data:`WINDOW_S` (``w`` samples) is compared with
the level a white residual of SD ``sigma`` exceeds by chance with probability
:data:`FALSE_ALARM` over the whole record: ``sigma sqrt(chi2_w^-1(1 - a / m) / w)``, ``m`` the
number of independent windows in the record (Bonferroni). Runs above it are merged and
reported with their RMS; :func:`regions` scores operating regions the same way (``m`` the
number of regions).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import stats

from gatetwin import noise as shared
from gatetwin.diagnosis.data import DiagnosisData
from gatetwin.noise import NoiseFloor

__all__ = [
    "FALSE_ALARM",
    "WINDOW_S",
    "noise_floor",
    "regions",
    "steady_stretches",
    "threshold_mm",
    "windows",
]

WINDOW_S = 30.0
#: Chance that a white residual at the noise floor raises a window (or a region) anywhere.
FALSE_ALARM = 0.01


def steady_stretches(data: DiagnosisData) -> list[tuple[int, int]]:
    """``(start, stop)`` runs of hold samples at one command with no discharge step."""
    return shared.steady_stretches(data.time_s, data.hold, data.command_mm, data.flow_m3h,
                                   data.sample_period_s)  # fmt: skip


def noise_floor(data: DiagnosisData) -> NoiseFloor:
    """The record's noise floor (see the module docstring)."""
    return shared.noise_floor(data.time_s, data.level_mm, data.hold, steady_stretches(data))


def threshold_mm(sigma_mm: float, n_samples: int, tests: float = 1.0) -> float:
    """RMS over ``n_samples`` that a white residual of SD ``sigma`` exceeds with probability
    ``FALSE_ALARM / tests``."""
    n = max(int(n_samples), 1)
    return sigma_mm * float(np.sqrt(stats.chi2.isf(FALSE_ALARM / max(tests, 1.0), n) / n))


def windows(
    time_s: np.ndarray, residual_mm: np.ndarray, sigma_mm: float, sample_period_s: float
) -> list[dict[str, float]]:
    """Time windows where the residual's moving RMS exceeds the noise floor's band.

    Runs closer than half a window are merged; runs of fewer than 3 samples are dropped.
    """
    w = max(5, int(round(WINDOW_S / sample_period_s)))
    r = np.where(np.isfinite(residual_mm), residual_mm, 0.0)
    kernel = np.ones(w)
    count = np.convolve(np.isfinite(residual_mm).astype(float), kernel, mode="same")
    ms = np.convolve(r * r, kernel, mode="same") / np.maximum(count, 1.0)
    above = (ms > threshold_mm(sigma_mm, w, time_s.size / w) ** 2) & (count >= w / 2)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], above.astype(np.int8), [0]])))
    merged: list[list[int]] = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        if merged and a - merged[-1][1] <= w // 2:
            merged[-1][1] = int(b)
        else:
            merged.append([int(a), int(b)])
    out = []
    for a, b in merged:
        seg = residual_mm[a:b][np.isfinite(residual_mm[a:b])]
        if b - a >= 3 and seg.size:
            out.append({"t_start_s": float(time_s[a]), "t_end_s": float(time_s[b - 1]),
                        "rms_mm": float(np.sqrt(np.mean(seg * seg)))})  # fmt: skip
    return out


def _region_row(name: str, mask: np.ndarray, residual: np.ndarray, sigma: float,
                extra: dict[str, Any]) -> dict[str, Any] | None:  # fmt: skip
    r = residual[mask & np.isfinite(residual)]
    if r.size < 10:
        return None
    rms = float(np.sqrt(np.mean(r * r)))
    return {"region": name, **extra, "n": int(r.size), "rms_mm": rms}


def regions(data: DiagnosisData, residual_mm: np.ndarray, sigma_mm: float,
            settle_s: float) -> list[dict[str, Any]]:  # fmt: skip
    """Residual RMS by operating region: after moves / steady, opening level, discharge level."""
    t = data.time_s
    since = np.full(t.size, np.inf)
    for move in data.moves:
        later = t >= move.time_s
        since[later] = np.minimum(since[later], t[later] - move.time_s)
    rows = [
        _region_row("after moves", since <= settle_s, residual_mm, sigma_mm,
                    {"within_s": settle_s}),
        _region_row("steady", since > settle_s, residual_mm, sigma_mm, {"after_s": settle_s}),
    ]  # fmt: skip
    for value in np.unique(data.command_mm):
        rows.append(_region_row("opening", data.command_mm == value, residual_mm, sigma_mm,
                                {"opening_mm": float(value)}))  # fmt: skip
    edges = np.unique(np.quantile(data.flow_m3h, [0.0, 1 / 3, 2 / 3, 1.0]))
    if edges.size > 2 and edges[-1] - edges[0] > 1.0:
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            mask = (data.flow_m3h >= lo) & (data.flow_m3h <= hi)
            rows.append(_region_row("discharge", mask, residual_mm, sigma_mm,
                                    {"flow_m3h": [float(lo), float(hi)]}))  # fmt: skip
    kept = [r for r in rows if r is not None]
    for row in kept:
        row["exceeds"] = bool(row["rms_mm"] > threshold_mm(sigma_mm, row["n"], len(kept)))
    return kept
