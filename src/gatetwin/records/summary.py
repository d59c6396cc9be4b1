"""JSON-ready summaries of records and rating tables (what ``gatetwin check`` reports).

Plain dictionaries of finite numbers, strings, lists and None, so they can be written with
``allow_nan=False``. This module only describes; it does not check.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from gatetwin.records.record import Record
    from gatetwin.records.static import StaticTable


def _range(values: np.ndarray) -> dict[str, float] | None:
    finite = values[np.isfinite(values)]
    if not finite.size:
        return None
    return {
        "mean": float(finite.mean()),
        "min": float(finite.min()),
        "max": float(finite.max()),
    }


def record_summary(record: Record) -> dict[str, Any]:
    """Summarise a :class:`~gatetwin.records.Record`."""
    lengths = np.array([h.n_samples for h in record.holds])
    return {
        "kind": "record",
        "path": record.path,
        "sha256": record.sha256,
        "test": record.test,
        "test_source": record.test_source,
        "n_samples": record.n_samples,
        "sample_period_s": record.sample_period_s,
        "time_s": {"start": float(record.time_s[0]), "stop": float(record.time_s[-1])},
        "duration_s": float(record.time_s[-1] - record.time_s[0]),
        "gauges": [_gauge_summary(record, g) for g in record.gauges],
        "flow_m3h": _range(record.flow_m3h),
        "opening_mm": _range(record.opening_mm),
        "hold_segments": {
            "count": int(lengths.size),
            "samples_total": int(lengths.sum()),
            "samples_min": int(lengths.min()),
            "samples_median": float(np.median(lengths)),
            "samples_max": int(lengths.max()),
        },
        "opening_filled_samples": int(np.count_nonzero(record.opening_filled))
        if record.opening_filled is not None
        else 0,
        "steps": [
            {
                "index": s.index,
                "time_s": s.time_s,
                "opening_before_mm": s.before.opening_mm,
                "opening_after_mm": s.after.opening_mm,
                "delta_e_mm": s.delta_e_mm,
            }
            for s in record.steps
        ],
        "unobserved_steps": record.unobserved_steps,
        "metadata": record.metadata,
    }


def _gauge_summary(record: Record, gauge: str) -> dict[str, Any]:
    level = record.levels_mm[gauge]
    return {
        "name": gauge,
        "distance_m": record.gauges_m.get(gauge),
        "valid_samples": int(np.count_nonzero(np.isfinite(level))),
        "level_mm": _range(level),
    }


def static_summary(table: StaticTable) -> dict[str, Any]:
    """Summarise a :class:`~gatetwin.records.StaticTable`."""
    return {
        "kind": "static",
        "path": table.path,
        "sha256": table.sha256,
        "n_points": table.n_points,
        "flow_m3h": _range(table.flow_m3h),
        "opening_mm": _range(table.opening_mm),
        "gauges": [
            {
                "name": g,
                "level_mm": _range(table.levels_mm[g]),
                "has_sd": g in table.level_sd_mm,
            }
            for g in table.gauges
        ],
    }


def _fmt_range(stats: dict[str, float] | None, unit: str) -> str:
    if stats is None:
        return "no values"
    return f"mean {stats['mean']:.4g} {unit}, range {stats['min']:.4g} … {stats['max']:.4g} {unit}"


def _fmt_gauges(gauges: list[dict[str, Any]]) -> str:
    parts = []
    for g in gauges:
        where = "distance unknown" if g.get("distance_m") is None else f"{g['distance_m']:g} m"
        parts.append(f"{g['name']} ({where})")
    return ", ".join(parts)


_SOURCE_TEXT = {
    "option": "from --test",
    "sidecar": "from the sidecar",
    "detected": "detected from the data",
}


def format_record_summary(summary: dict[str, Any]) -> str:
    """Human-readable lines for :func:`record_summary`'s output."""
    holds = summary["hold_segments"]
    span = summary["time_s"]
    opening = summary["opening_mm"]
    lines = [
        f"record   {summary['path']}",
        f"test     {summary['test']} ({_SOURCE_TEXT[summary['test_source']]})",
        f"samples  {summary['n_samples']} at {summary['sample_period_s']:.4g} s "
        f"(time {span['start']:g} … {span['stop']:g} s, {summary['duration_s']:.1f} s)",
        f"gauges   {_fmt_gauges(summary['gauges'])}",
        f"flow     {_fmt_range(summary['flow_m3h'], 'm³/h')}",
        f"opening  {opening['min']:.4g} … {opening['max']:.4g} mm"
        f" ({summary['opening_filled_samples']} empty hold openings filled)",
        f"holds    {holds['count']} segment(s) of {holds['samples_min']} … "
        f"{holds['samples_max']} samples (median {holds['samples_median']:g}), "
        f"{holds['samples_total']} hold samples in total",
        f"steps    {len(summary['steps'])}"
        + (f" ({summary['unobserved_steps']} more inside logging gaps)"
           if summary["unobserved_steps"] else ""),
    ]
    for k, step in enumerate(summary["steps"], 1):
        lines.append(
            f"  step {k} at {step['time_s']:g} s (sample {step['index']}): opening "
            f"{step['opening_before_mm']:g} → {step['opening_after_mm']:g} mm, "
            f"Δe = {step['delta_e_mm']:+g} mm"
        )
    return "\n".join(lines)


def format_static_summary(summary: dict[str, Any]) -> str:
    """Human-readable lines for :func:`static_summary`'s output."""
    flow, opening = summary["flow_m3h"], summary["opening_mm"]
    gauges = ", ".join(
        g["name"] + (" (with SD)" if g["has_sd"] else "") for g in summary["gauges"]
    )
    return "\n".join(
        [
            f"static   {summary['path']}",
            f"points   {summary['n_points']}",
            f"flow     {flow['min']:.4g} … {flow['max']:.4g} m³/h",
            f"opening  {opening['min']:.4g} … {opening['max']:.4g} mm",
            f"gauges   {gauges}",
        ]
    )
