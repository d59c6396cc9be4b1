"""The text ``gatetwin check`` prints from a record's or rating table's summary.

Summaries are the plain dictionaries of ``Record.summary()`` and ``StaticTable.summary()``
(finite numbers, strings, lists and None, written with ``allow_nan=False``); this module
only formats them, it does not check.
"""

from __future__ import annotations

from typing import Any

__all__ = ["format_record_summary", "format_static_summary"]


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


def _units_line(units: dict[str, Any] | None) -> list[str]:
    """A ``units`` line when the file was not in mm and m³/h throughout (else none)."""
    if not units:
        return []
    levels = units.get("levels") or {}
    shown = {"opening": units.get("opening"), "flow": units.get("flow")}
    shown.update({f"level {g}": u for g, u in levels.items()})
    if all(u in ("mm", "m3h", None) for u in shown.values()):
        return []
    text = ", ".join(f"{k} {u}" for k, u in shown.items() if u is not None)
    return [f"units    {text} (read as mm and m³/h)"]


_SOURCE_TEXT = {
    "option": "from --test",
    "sidecar": "from the sidecar",
    "detected": "detected from the data",
}


def format_record_summary(summary: dict[str, Any]) -> str:
    """Human-readable lines for the output of ``Record.summary()``."""
    holds = summary["hold_segments"]
    span = summary["time_s"]
    opening = summary["opening_mm"]
    lines = [
        f"record   {summary['path']}",
        f"test     {summary['test']} ({_SOURCE_TEXT[summary['test_source']]})",
        f"samples  {summary['n_samples']} at {summary['sample_period_s']:.4g} s "
        f"(time {span['start']:g} … {span['stop']:g} s, {summary['duration_s']:.1f} s)",
        *_units_line(summary.get("units")),
        f"gauges   {_fmt_gauges(summary['gauges'])}",
        f"flow     {_fmt_range(summary['flow_m3h'], 'm³/h')}"
        + (
            f" ({summary['flow_filled_samples']} empty cells held from the logged ones)"
            if summary.get("flow_filled_samples")
            else ""
        ),  # fmt: skip
        f"opening  {opening['min']:.4g} … {opening['max']:.4g} mm"
        f" ({summary['opening_filled_samples']} empty hold openings filled)",
        f"holds    {holds['count']} segment(s) of {holds['samples_min']} … "
        f"{holds['samples_max']} samples (median {holds['samples_median']:g}), "
        f"{holds['samples_total']} hold samples in total",
        f"steps    {len(summary['steps'])}"
        + (
            f" ({summary['unobserved_steps']} more inside logging gaps)"
            if summary["unobserved_steps"]
            else ""
        ),
    ]
    for k, step in enumerate(summary["steps"], 1):
        lines.append(
            f"  step {k} at {step['time_s']:g} s (sample {step['index']}): opening "
            f"{step['opening_before_mm']:g} → {step['opening_after_mm']:g} mm, "
            f"Δe = {step['delta_e_mm']:+g} mm"
        )
    return "\n".join(lines)


def format_static_summary(summary: dict[str, Any]) -> str:
    """Human-readable lines for the output of ``StaticTable.summary()``."""
    flow, opening = summary["flow_m3h"], summary["opening_mm"]
    gauges = ", ".join(g["name"] + (" (with SD)" if g["has_sd"] else "") for g in summary["gauges"])
    return "\n".join(
        [
            f"static   {summary['path']}",
            f"points   {summary['n_points']}",
            *_units_line(summary.get("units")),
            f"flow     {flow['min']:.4g} … {flow['max']:.4g} m³/h",
            f"opening  {opening['min']:.4g} … {opening['max']:.4g} mm",
            f"gauges   {gauges}",
        ]
    )
