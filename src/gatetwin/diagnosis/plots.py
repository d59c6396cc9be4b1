"""The diagnosis figure: measured, baseline and augmented level; residuals before and after.

Rendered on matplotlib's Agg canvas directly (no pyplot state, no display needed).
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np

from gatetwin.diagnosis.data import DiagnosisData

__all__ = ["diagnosis_png"]


def diagnosis_png(
    data: DiagnosisData,
    baseline_mm: np.ndarray,
    augmented_mm: np.ndarray | None,
    *,
    sigma_mm: float,
    windows: Sequence[dict[str, float]],
    title: str,
) -> bytes:
    """PNG of one diagnosis (``augmented_mm`` None when no effect was named)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 7.5), layout="constrained")
    FigureCanvasAgg(fig)
    ax_level, ax_res, ax_open = fig.subplots(3, 1, sharex=True, height_ratios=(3, 2, 1))
    t = data.time_s
    ax_level.plot(t, data.level_mm, ".", ms=2.0, color="0.5", label="measured")
    ax_level.plot(t, baseline_mm, "-", lw=1.2, color="C0", label="baseline (free run)")
    if augmented_mm is not None:
        ax_level.plot(t, augmented_mm, "-", lw=1.2, color="C3", label="augmented (free run)")
    ax_level.set_ylabel(f"level {data.gauge} (mm)")
    ax_level.set_title(title, fontsize=10)
    ax_level.legend(loc="best", fontsize=8)
    ax_res.plot(t, data.level_mm - baseline_mm, "-", lw=0.7, color="C0", label="before")
    if augmented_mm is not None:
        ax_res.plot(t, data.level_mm - augmented_mm, "-", lw=0.7, color="C3", label="after")
    ax_res.axhspan(-sigma_mm, sigma_mm, color="0.85", label=f"±σ = {sigma_mm:.2g} mm")
    for w in windows:
        ax_res.axvspan(w["t_start_s"], w["t_end_s"], color="C1", alpha=0.12, lw=0)
    ax_res.set_ylabel("measured − model (mm)")
    ax_res.legend(loc="best", fontsize=8)
    ax_open.step(t, data.command_mm, where="post", color="C2", lw=1.0, label="commanded opening")
    ax_open.axvline(data.split_time_s, color="0.3", ls="--", lw=0.8, label="hold-out from here")
    ax_open.set_ylabel("opening (mm)")
    ax_open.set_xlabel("time (s)")
    ax_open.legend(loc="best", fontsize=8)
    for ax in (ax_level, ax_res, ax_open):
        ax.grid(True, lw=0.4, alpha=0.6)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()
