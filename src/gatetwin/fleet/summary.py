"""The fleet summary: one JSON document, a Markdown table, an HTML page and one figure.

``fleet.json`` holds one entry per gate (``status`` ok, failed, or no_window for a gate of
routine histories without any informative window; the model families identified and
``fopdt_source``, each model's validity envelope, each model's free-run fit on the held-out
records, each routine history's overall K, T, L under ``routine``, the warnings raised
while identifying, and for a gate that is not ok the reason).
``fleet.md`` and ``fleet.html`` show the same as a table; ``fleet.png`` plots the held-out
free-run fit of every gate and family, failed gates marked.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin import __version__

__all__ = [
    "HEADER",
    "SUMMARY_SCHEMA",
    "fleet_document",
    "fleet_figure_png",
    "fleet_html",
    "fleet_markdown",
    "summary_paths",
]

SUMMARY_SCHEMA = "gatetwin-fleet/1"


def fleet_document(results: list[dict[str, Any]], mode: str) -> dict[str, Any]:
    """``fleet.json``: every gate's summary entry, sorted by gate, and the totals."""
    gates = [r["summary"] for r in results]
    ok = [g for g in gates if g["status"] == "ok"]
    no_window = [g for g in gates if g["status"] == "no_window"]
    return {
        "schema": SUMMARY_SCHEMA,
        "gatetwin_version": __version__,
        "mode": mode,
        "n_gates": len(gates),
        "n_ok": len(ok),
        "n_no_window": len(no_window),
        "n_failed": len(gates) - len(ok) - len(no_window),
        "samples": int(sum(g["samples"] for g in gates)),
        "gates": gates,
    }


def _best_fit(entry: dict[str, Any], family: str) -> float | None:
    """Mean held-out free-run fit (%) of the gate's models of ``family``; None without."""
    fits = [v["fit_percent"] for name, recs in entry["held_out"].items()
            if name.startswith(family + "_") for v in recs.values()]  # fmt: skip
    return float(np.mean(fits)) if fits else None


def _range(entry: dict[str, Any], key: str) -> str:
    spans = [v[key] for v in entry["validity"].values() if key in v]
    if not spans:
        return ""
    return f"{min(s[0] for s in spans):g}–{max(s[1] for s in spans):g}"


def _row(entry: dict[str, Any]) -> list[str]:
    def fit(family: str) -> str:
        value = _best_fit(entry, family)
        return "" if value is None else f"{value:.1f}"

    note = entry["error"] if entry["status"] != "ok" else "; ".join(entry["warnings"])
    if entry.get("fopdt_source") == "routine":
        note = "; ".join(filter(None, [_routine_note(entry), note]))
    return [entry["gate"], entry["status"], ", ".join(entry["families"]),
            _range(entry, "flow_m3h"), _range(entry, "opening_mm"), fit("fopdt"),
            fit("physical"), fit("arx"), str(len(entry["warnings"])), note]  # fmt: skip


def _routine_note(entry: dict[str, Any]) -> str:
    """The FOPDT a gate's routine histories gave (medians over their windows)."""
    found = [r for r in entry.get("routine", {}).values() if r["n_windows"]]
    if not found:
        return ""
    parts = [f"K {r['gain_mm_per_mm']:.2f} mm/mm, T {r['time_constant_s']:.0f} s, "
             f"L {r['dead_time_s']:.1f} s" for r in found]  # fmt: skip
    windows = sum(r["n_windows"] for r in found)
    return f"FOPDT from routine history ({windows} windows): " + ", ".join(parts)


HEADER = ["gate", "status", "families", "Q m³/h", "e mm", "FOPDT fit %", "physical fit %",
          "ARX fit %", "warnings", "note"]  # fmt: skip


def _no_window_words(doc: dict[str, Any]) -> str:
    n = doc.get("n_no_window", 0)
    return f", {n} without an informative window" if n else ""


def fleet_markdown(doc: dict[str, Any]) -> str:
    """The fleet as a Markdown table (fit: mean free-run fit on held-out records)."""
    lines = [f"# Fleet: {doc['n_gates']} gates, {doc['n_ok']} identified, "
             f"{doc['n_failed']} failed{_no_window_words(doc)}", "",
             f"Run: {doc['mode']}. Fit: free-run fit on the gate's held-out records, %.", "",
             "| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]  # fmt: skip
    for entry in doc["gates"]:
        cells = [c.replace("|", "/") for c in _row(entry)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def fleet_html(doc: dict[str, Any], png: bytes) -> str:
    """A self-contained page: the overview figure and the table."""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in HEADER)
    rows = []
    for entry in doc["gates"]:
        cls = {"ok": "", "no_window": ' class="nowindow"'}.get(entry["status"], ' class="failed"')
        cells = "".join(f"<td>{html.escape(c)}</td>" for c in _row(entry))
        rows.append(f"<tr{cls}>{cells}</tr>")
    image = base64.b64encode(png).decode("ascii")
    title = (f"Fleet: {doc['n_gates']} gates, {doc['n_ok']} identified, "
             f"{doc['n_failed']} failed{_no_window_words(doc)}")  # fmt: skip
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(title)}</title><style>body{{font-family:sans-serif}}"
        "table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:2px 6px}"
        "tr.failed{background:#fdd}tr.nowindow{background:#eee}</style></head><body>"
        f"<h1>{html.escape(title)}</h1><p>Run: {html.escape(doc['mode'])}. Fit: free-run "
        "fit on the gate's held-out records, %.</p>"
        f'<img alt="held-out free-run fit per gate" src="data:image/png;base64,{image}">'
        f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>"
        "</body></html>\n"
    )


def fleet_figure_png(doc: dict[str, Any]) -> bytes:
    """Held-out free-run fit (%) per gate and family; failed gates as red crosses at 0,
    gates without an informative window as grey circles at 0."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gates = doc["gates"]
    x = np.arange(len(gates))
    fig, ax = plt.subplots(figsize=(max(6.0, min(16.0, 0.18 * len(gates) + 4)), 3.6))
    for family, marker in (("fopdt", "o"), ("physical", "s"), ("arx", "^")):
        fits = [_best_fit(g, family) for g in gates]
        have = [i for i, f in enumerate(fits) if f is not None]
        if have:
            ax.plot(x[have], [fits[i] for i in have], marker, ms=4, ls="", label=family)
    failed = [i for i, g in enumerate(gates) if g["status"] == "failed"]
    if failed:
        ax.plot(x[failed], np.zeros(len(failed)), "x", color="red", ms=7, label="failed")
    quiet = [i for i, g in enumerate(gates) if g["status"] == "no_window"]
    if quiet:
        ax.plot(x[quiet], np.zeros(len(quiet)), "o", mfc="none", color="grey", ms=6,
                label="no informative window")  # fmt: skip
    ax.set_xlabel("gate")
    ax.set_ylabel("held-out free-run fit, %")
    ax.set_title(f"{doc['n_gates']} gates: {doc['n_ok']} identified, {doc['n_failed']} failed")
    if len(gates) <= 30:
        ax.set_xticks(x, [g["gate"] for g in gates], rotation=90, fontsize=7)
    ax.grid(alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, metadata={"Software": None})
    plt.close(fig)
    return buf.getvalue()


def summary_paths(out: Path) -> dict[str, Path]:
    """Where the summary files go."""
    return {"json": out / "fleet.json", "markdown": out / "fleet.md",
            "html": out / "fleet.html", "figure": out / "fleet.png"}  # fmt: skip
