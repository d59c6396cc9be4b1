"""Figures like the reference study's Figures 2–12, plus the schedule on Q (matplotlib PNG).

Each function draws one figure from an :class:`~gatetwin.identification.suite.Identified` and
writes it; :func:`write_all` writes every figure that the identified records support.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gatetwin.identification.arx import predict_one_step  # noqa: E402
from gatetwin.identification.preprocess import record_segments  # noqa: E402
from gatetwin.identification.suite import Identified  # noqa: E402

__all__ = [
    "CAPTIONS",
    "GAUGE",
    "arx_prediction",
    "arx_residuals",
    "caption",
    "prbs_record",
    "schedule_plot",
    "static_level_vs_flow",
    "static_level_vs_opening",
    "step_all_gauges",
    "step_compare",
    "step_fit",
    "write_all",
]

GAUGE = "3F"


def _save(fig: plt.Figure, path: Path) -> Path:
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _delta(ident: Identified, cond: str, gauge: str) -> tuple[np.ndarray, np.ndarray]:
    rec, step = ident.records[cond], ident.steps[cond]
    t = rec.time_s - step.onset_time_s
    return t, rec.levels_mm[gauge] - step.gauges[gauge].paper.pre_mean_mm


def step_all_gauges(ident: Identified, cond: str, path: Path) -> Path:
    """Figures 2 and 4: ΔH at every gauge after the step."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for g in ident.steps[cond].gauges:
        t, dh = _delta(ident, cond, g)
        ax.plot(t, dh, lw=0.8, label=g)
    ax.set(
        xlabel="time since step onset (s)",
        ylabel="ΔH (mm)",
        title=f"Step response, condition {cond} (Q ≈ {ident.steps[cond].flow_m3h:.1f} m³/h)",
    )
    ax.legend(ncol=5, fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def step_fit(ident: Identified, path: Path) -> Path:
    """Figure 3: measured ΔH and the FOPDT (least-squares) at 3F, A and B."""
    conds = [c for c in ("A", "B") if c in ident.steps]
    fig, axes = plt.subplots(1, len(conds), figsize=(10, 4), squeeze=False)
    for ax, cond in zip(axes[0], conds, strict=True):
        t, dh = _delta(ident, cond, GAUGE)
        res = ident.steps[cond].gauges[GAUGE]
        t_abs = ident.records[cond].time_s
        curve = res.fit.curve(t_abs) - res.paper.pre_mean_mm
        ax.plot(t, dh, ".", ms=2, label="measured")
        ax.plot(
            t,
            curve,
            "r-",
            lw=1.2,
            label=f"FOPDT K {res.fit.gain_mm_per_mm:.2f}, "
            f"T {res.fit.time_constant_s:.0f} s, L {res.fit.dead_time_s:.1f} s",
        )
        ax.set(xlabel="time since onset (s)", ylabel="ΔH (mm)", title=f"{cond}, gauge {GAUGE}")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    return _save(fig, path)


def step_compare(ident: Identified, path: Path) -> Path:
    """Figure 5: ΔH at 3F, A against B."""
    fig, ax = plt.subplots(figsize=(7, 4))
    for cond in ("A", "B"):
        if cond in ident.steps:
            t, dh = _delta(ident, cond, GAUGE)
            ax.plot(t, dh, lw=0.8, label=f"{cond} (Q ≈ {ident.steps[cond].flow_m3h:.1f})")
    ax.set(xlabel="time since onset (s)", ylabel="ΔH at 3F (mm)", title="A against B")
    ax.legend()
    ax.grid(alpha=0.3)
    return _save(fig, path)


def prbs_record(ident: Identified, cond: str, path: Path) -> Path:
    """Figures 6 and 7: PRBS opening and the level at 3F."""
    rec = ident.records[cond]
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    a1.step(rec.time_s, rec.opening_mm, where="post", lw=0.8)
    a1.set(ylabel="opening (mm)", title=f"PRBS test {cond}")
    a2.plot(rec.time_s, rec.levels_mm[GAUGE], lw=0.6)
    a2.set(xlabel="time (s)", ylabel=f"level {GAUGE} (mm)")
    for ax in (a1, a2):
        ax.grid(alpha=0.3)
    return _save(fig, path)


def _one_step(ident: Identified, cond: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rec, fit = ident.records[cond], ident.prbs[cond].fit
    from gatetwin.identification.preprocess import reconstructed_opening

    u = reconstructed_opening(rec.time_s, rec.opening_mm, rec.hold) - fit.opening_mean_mm
    y = rec.levels_mm[GAUGE] - fit.level_mean_mm
    segs = record_segments(rec) if ident.prbs[cond].rows == "hold" else [(0, rec.n_samples)]
    return rec.time_s, y, predict_one_step(fit, u, y, segs)


def arx_prediction(ident: Identified, cond: str, path: Path) -> Path:
    """Figures 8 and 9: measured vs one-step-ahead predicted deviations."""
    t, y, yhat = _one_step(ident, cond)
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ax.plot(t, y, lw=0.6, label="measured")
    ax.plot(t, yhat, lw=0.6, label="one-step prediction")
    ax.set(xlabel="time (s)", ylabel="y' (mm)", title=f"ARX(2,2,1), condition {cond}")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def arx_residuals(ident: Identified, path: Path) -> Path:
    """Figure 10: one-step residuals of the ARX models."""
    conds = list(ident.prbs)
    fig, axes = plt.subplots(len(conds), 1, figsize=(8, 2.5 * len(conds)), squeeze=False)
    for ax, cond in zip(axes[:, 0], conds, strict=True):
        t, y, yhat = _one_step(ident, cond)
        ax.plot(t, y - yhat, lw=0.5)
        ax.set(ylabel="ε (mm)", title=f"residuals, {cond}")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)")
    return _save(fig, path)


def static_level_vs_opening(ident: Identified, path: Path) -> Path:
    """Figure 11: H3 against the opening at several flows (points and rating relation)."""
    rating = ident.ratings[GAUGE]
    fig, ax = plt.subplots(figsize=(7, 4))
    for q in (30.0, 50.0, 70.0, 90.0):
        e = np.linspace(10, 80, 200)
        h = rating.level_mm(np.full_like(e, q), e)
        ok = (h > 90) & (h < 400)
        ax.plot(e[ok], h[ok], label=f"rating, Q {q:g}")
    ax.set(xlabel="opening e (mm)", ylabel="H3 (mm)", title="Static level against opening")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def static_level_vs_flow(ident: Identified, path: Path) -> Path:
    """Figure 12: H3 against discharge at several openings."""
    rating = ident.ratings[GAUGE]
    fig, ax = plt.subplots(figsize=(7, 4))
    for e in (15.0, 25.0, 35.0, 50.0):
        q = np.linspace(20, 90, 200)
        h = rating.level_mm(q, np.full_like(q, e))
        ok = (h > 90) & (h < 400)
        ax.plot(q[ok], h[ok], label=f"rating, e {e:g} mm")
    ax.set(xlabel="Q (m³/h)", ylabel="H3 (mm)", title="Static level against discharge")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def schedule_plot(ident: Identified, path: Path) -> Path:
    """K, T, L per condition and the schedule on Q, with the held-out condition."""
    doc = ident.models[f"fopdt_{GAUGE}"]
    sched = doc["plant"]["schedule"]
    fig, axes = plt.subplots(1, 3, figsize=(11, 3.5))
    for ax, key, label in zip(axes, ("gain_mm_per_mm", "time_constant_s", "dead_time_s"),
                              ("K (mm/mm)", "T (s)", "L (s)"), strict=True):  # fmt: skip
        ax.plot(sched["flow_m3h"], sched[key], "b-", label="schedule")
        ax.plot([c["flow_m3h"] for c in doc["conditions"]], [c[key] for c in doc["conditions"]],
                "ko", ms=4, label="conditions")  # fmt: skip
        for h in doc["provenance"]["metrics"]["held_out"].values():
            ax.plot(h["flow_m3h"], h["identified"][key], "r^", label="held out")
        ax.set(xlabel="Q (m³/h)", ylabel=label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    return _save(fig, path)


def _jobs(ident: Identified) -> list[tuple[str, Callable[[Path], Path]]]:
    jobs: list[tuple[str, Callable[[Path], Path]]] = []
    if "A" in ident.steps:
        jobs.append(("fig02_step_A.png", lambda p: step_all_gauges(ident, "A", p)))
    if {"A", "B"} <= set(ident.steps):
        jobs += [("fig03_fopdt_fit.png", lambda p: step_fit(ident, p)),
                 ("fig04_step_B.png", lambda p: step_all_gauges(ident, "B", p)),
                 ("fig05_A_vs_B.png", lambda p: step_compare(ident, p))]  # fmt: skip
    for i, cond in enumerate(("C", "D")):
        if cond in ident.prbs:
            jobs.append(
                (f"fig0{6 + i}_prbs_{cond}.png", lambda p, c=cond: prbs_record(ident, c, p))
            )
            jobs.append(
                (f"fig0{8 + i}_arx_{cond}.png", lambda p, c=cond: arx_prediction(ident, c, p))
            )
    if ident.prbs:
        jobs.append(("fig10_arx_residuals.png", lambda p: arx_residuals(ident, p)))
    jobs += [("fig11_static_H_vs_e.png", lambda p: static_level_vs_opening(ident, p)),
             ("fig12_static_H_vs_Q.png", lambda p: static_level_vs_flow(ident, p))]  # fmt: skip
    if f"fopdt_{GAUGE}" in ident.models:
        jobs.append(("schedule_3F.png", lambda p: schedule_plot(ident, p)))
    return jobs


CAPTIONS = {
    "fig02": "Step responses ΔH at the five gauges, condition A (as the paper's Figure 2)",
    "fig03": "Measured ΔH and the least-squares FOPDT at 3F, A and B (Figure 3)",
    "fig04": "Step responses ΔH at the five gauges, condition B (Figure 4)",
    "fig05": "ΔH at 3F, condition A against B (Figure 5)",
    "fig06": "PRBS opening and the level at 3F, condition C (Figure 6)",
    "fig07": "PRBS opening and the level at 3F, condition D (Figure 7)",
    "fig08": "Measured vs one-step-ahead ARX prediction, C (Figure 8)",
    "fig09": "Measured vs one-step-ahead ARX prediction, D (Figure 9)",
    "fig10": "One-step ARX residuals, C and D (Figure 10)",
    "fig11": "Rating relation: level at 3F against the opening (Figure 11)",
    "fig12": "Rating relation: level at 3F against the discharge (Figure 12)",
    "schedule": "K, T, L of the step conditions and the schedule on Q, with the held-out Q55",
}


def caption(path: Path) -> str:
    """The caption of a figure written by :func:`write_all`."""
    return CAPTIONS.get(path.stem.split("_")[0], path.stem.replace("_", " "))


def write_all(ident: Identified, folder: Path) -> list[Path]:
    """Write every figure the identified records support into ``folder``."""
    return [draw(folder / name) for name, draw in _jobs(ident)]
