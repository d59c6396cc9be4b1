"""``diagnose_record``: where the twin and the measurements disagree, which physical effect is
missing, and how much adding it closes the gap.

1. **Where.** The baseline (a model file's plant, or one identified from the record:
   :mod:`gatetwin.diagnosis.baseline`) runs free on the record; its residual is compared with
   the noise floor (:mod:`gatetwin.diagnosis.noise`) by time window and operating region.
2. **What.** Every candidate effect (:mod:`gatetwin.diagnosis.candidates`) is fitted jointly
   with the baseline's adjustments on the first part of the record; the residual signatures
   (:mod:`gatetwin.diagnosis.signatures`) say which the residual points at and give start
   values; the selection (:mod:`gatetwin.diagnosis.select`) names the one that earns its
   parameters -- or ``none``.
3. **Name and add.** The winner's block joins the plant: a model file, FMUs re-validated
   through fmpy (:mod:`gatetwin.diagnosis.artifacts`), a figure; RMSE and the gap
   ``sqrt(RMSE^2 - sigma^2)`` before and after, on the fitted and the held-out part.
   "Before" is the baseline with its adjustments refitted on the same data (what the
   candidates are scored against), so before/after isolates the named block; the baseline
   as given is reported beside it. With FMUs exported, a closed-loop check runs the MPC
   built from the augmented model and one blind to the block on the augmented plant
   (:mod:`gatetwin.diagnosis.control`).

Reported levels before and after come from the Python reference simulation, stepped like the
FMU validation harness steps an FMU (nominal sample period, several steps across a logging
gap; time-stamp jitter ignored); the fits use its exact grid rendering
(:mod:`gatetwin.diagnosis.grid_sim`).
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin._io import write_bytes_atomic
from gatetwin.diagnosis import artifacts
from gatetwin.diagnosis.baseline import Baseline, identify_baseline, model_baseline
from gatetwin.diagnosis.candidates import CANDIDATES, Context
from gatetwin.diagnosis.control import control_check
from gatetwin.diagnosis.data import DiagnosisData, prepare
from gatetwin.diagnosis.noise import noise_floor, regions, windows
from gatetwin.diagnosis.select import CandidateResult, choose, evaluate, rmse_parts
from gatetwin.diagnosis.signatures import signatures
from gatetwin.modelfile import read_model_file
from gatetwin.plant.model import Plant, plant_to_dict
from gatetwin.records import Record, read_record


@dataclass(frozen=True)
class DiagnosisSettings:
    """Settings of :func:`diagnose_record`.

    Attributes
    ----------
    gauge : str or None
        Gauge to diagnose; default the model's, else ``3F`` if logged, else the first.
    input : {"command", "reconstructed"}
        What drives the models (:mod:`gatetwin.diagnosis.data`); default the command.
    holdout_fraction : float
        Share of the record, by time, held out at its end (0.3).
    backends : tuple of str
        FMU backends exported when ``fmu_dir`` is given.
    """

    gauge: str | None = None
    input: str = "command"
    holdout_fraction: float = 0.3
    backends: tuple[str, ...] = ("c", "python")


def _gauge(record: Record, plant: Plant | None, settings: DiagnosisSettings) -> str:
    if settings.gauge:
        return settings.gauge
    if plant is not None:
        return plant.gauge
    return "3F" if "3F" in record.levels_mm else record.gauges[0]


def _reference(plant: Plant, data: DiagnosisData, findings: list[str]) -> np.ndarray:
    """Free run of the reference simulation on the FMU harness's communication grid."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        out = artifacts.reference_on_grid(plant, data)
    findings += [str(w.message) for w in caught if str(w.message) not in findings]
    return out


def _gap(rmse_mm: float, sigma_mm: float) -> float:
    return math.sqrt(max(rmse_mm * rmse_mm - sigma_mm * sigma_mm, 0.0))


def _before_after(ctx: Context, before: np.ndarray, after: np.ndarray) -> dict[str, Any]:
    b, a = rmse_parts(ctx, before), rmse_parts(ctx, after)
    gap_b = {k: _gap(v, ctx.sigma_mm) for k, v in b.items()}
    gap_a = {k: _gap(v, ctx.sigma_mm) for k, v in a.items()}
    reduction = 1.0 - gap_a["all"] / gap_b["all"] if gap_b["all"] > 0 else 0.0
    return {
        "rmse_before_mm": b["all"], "rmse_after_mm": a["all"],
        "rmse_mm": {"before": b, "after": a},
        "gap_mm": {"before": gap_b, "after": gap_a},
        "gap_reduction": reduction,
    }  # fmt: skip


def _effect_fit(winner: CandidateResult | None) -> dict[str, Any] | None:
    if winner is None or winner.fit is None:
        return None
    candidate = next(c for c in CANDIDATES if c.kind == winner.effect)
    return {"effect": winner.effect, "parameters": winner.block_parameters(candidate),
            "all_parameters": winner.fit.parameters(), "score": winner.score,
            "n_effective": winner.fit.n_effective}  # fmt: skip


def _load(record_path: str | os.PathLike[str], model_path: str | os.PathLike[str] | None,
          settings: DiagnosisSettings) -> tuple[Record, DiagnosisData, Baseline]:  # fmt: skip
    record = read_record(record_path)
    model = read_model_file(model_path) if model_path is not None else None
    gauge = _gauge(record, model.plant if model else None, settings)
    data = prepare(record, gauge, input_kind=settings.input,
                   holdout_fraction=settings.holdout_fraction)  # fmt: skip
    if model is not None:
        return record, data, model_baseline(model.plant, data, str(model_path))
    return record, data, identify_baseline(record, data)


def _baseline_dict(baseline: Baseline, ctx: Context, findings: list[str]) -> dict[str, Any]:
    as_given = _reference(baseline.plant, ctx.data, findings)
    return {"source": baseline.source, "plant_as_given": plant_to_dict(baseline.plant),
            "rmse_as_given_mm": rmse_parts(ctx, as_given),
            "plant": plant_to_dict(baseline.refit.plant),
            "refit_adjustments": dict(zip(baseline.refit.names, map(float, baseline.refit.theta),
                                          strict=True))}  # fmt: skip


def diagnose_record(
    record_path: str | os.PathLike[str],
    model_path: str | os.PathLike[str] | None = None,
    *,
    plots_dir: str | os.PathLike[str] | None = None,
    fmu_dir: str | os.PathLike[str] | None = None,
    model_out: str | os.PathLike[str] | None = None,
    settings: DiagnosisSettings | None = None,
) -> dict[str, Any]:
    """Diagnose one record against a model file's plant or a baseline identified from it.

    Parameters
    ----------
    record_path : path
        The record (CSV and optional sidecar).
    model_path : path, optional
        Model file of the baseline; default identify it from the record (FOPDT fitted to
        all moves jointly for step and free records, ARX for PRBS records).
    plots_dir : path, optional
        Folder for the figure ``<record>_<gauge>_diagnosis.png``.
    fmu_dir : path, optional
        Folder for the augmented model's FMUs (``<name>_c.fmu``, ``<name>_python.fmu``),
        re-validated through fmpy; also its model file unless ``model_out`` is given.
    model_out : path, optional
        Where to write the augmented model file.
    settings : DiagnosisSettings, optional

    Returns
    -------
    dict
        JSON-ready: ``named_effect``, ``candidates``, ``rmse_before_mm``, ``rmse_after_mm``,
        ``windows``, the noise floor, RMSE and gap on the fitted and held-out parts, and more.

    Raises
    ------
    GatetwinError
        Bad record or model file, or a record the diagnosis cannot use.
    """
    settings = settings or DiagnosisSettings()
    record, data, baseline = _load(record_path, model_path, settings)
    findings: list[str] = []
    noise = noise_floor(data)
    ctx = Context(data, baseline.plant, baseline.refit, noise.sigma_mm,
                  signatures(data, baseline.refit))  # fmt: skip
    results = evaluate(ctx)
    winner = choose(results)
    before = _reference(baseline.refit.plant, data, findings)
    after = _reference(winner.fit.plant, data, findings) if winner and winner.fit else before
    summary = _summary(record, ctx, baseline, results, winner, (before, after), findings)
    summary["noise_floor"] = noise.to_dict()
    summary["split"]["holdout_fraction"] = settings.holdout_fraction
    _write_outputs(summary, record, data, winner, (before, after),
                   (plots_dir, fmu_dir, model_out), settings)  # fmt: skip
    return summary


def _summary(record: Record, ctx: Context, baseline: Baseline, results: list[CandidateResult],
             winner: CandidateResult | None, levels: tuple[np.ndarray, np.ndarray],
             findings: list[str]) -> dict[str, Any]:  # fmt: skip
    """The JSON-ready findings (outputs are added by :func:`_write_outputs`)."""
    data, sigma = ctx.data, ctx.sigma_mm
    residual = data.level_mm - levels[0]
    settle = 3.0 * ctx.time_constant_s + data.sample_period_s
    return {
        "record": Path(record.path).name, "record_sha256": record.sha256, "gauge": data.gauge,
        "test": record.test, "input": data.input_kind,
        "named_effect": winner.effect if winner else "none",
        "noise_floor_mm": sigma, "noise_floor": None,
        "split": {"holdout_from_s": data.split_time_s},
        "baseline": _baseline_dict(baseline, ctx, findings),
        **_before_after(ctx, *levels),
        "windows": windows(data.time_s, residual, sigma, data.sample_period_s),
        "regions": regions(data, residual, sigma, settle),
        "signatures": {k: s.to_dict() for k, s in ctx.signatures.items()},
        "candidates": [r.to_dict(c) for r, c in zip(results, CANDIDATES, strict=True)],
        "effect_fit": _effect_fit(winner), "augmented_model": None, "fmus": [], "control": None,
        "plots": [],
        "findings": findings,
    }  # fmt: skip


def _write_outputs(summary: dict[str, Any], record: Record, data: DiagnosisData,
                   winner: CandidateResult | None, levels: tuple[np.ndarray, np.ndarray],
                   places: tuple[Any, Any, Any], settings: DiagnosisSettings) -> None:  # fmt: skip
    plots_dir, fmu_dir, model_out = places
    named = summary["named_effect"]
    if plots_dir is not None:
        name = f"{Path(record.path).stem}_{data.gauge}_diagnosis.png"
        title = (f"{summary['record']} gauge {data.gauge}: {named}; RMSE "
                 f"{summary['rmse_before_mm']:.2f} → {summary['rmse_after_mm']:.2f} mm, "
                 f"σ = {summary['noise_floor_mm']:.2f} mm")  # fmt: skip
        png = _figure(data, levels, winner is not None, summary, title)
        summary["plots"].append(str(write_bytes_atomic(Path(plots_dir) / name, png)))
    if winner is None or winner.fit is None or (fmu_dir is None and model_out is None):
        return
    name = artifacts.model_name(record, data.gauge, named)
    target = Path(model_out) if model_out is not None else Path(fmu_dir) / f"{name}.json"
    path = artifacts.write_augmented_model(target, name, winner.fit.plant, data, record, summary)
    summary["augmented_model"] = str(path)
    if fmu_dir is not None:
        provenance = {"model_name": name, "diagnosis_of": summary["record"],
                      "named_effect": named, "record_sha256": record.sha256}  # fmt: skip
        summary["fmus"] = artifacts.export_and_validate(
            winner.fit.plant, data, name, Path(fmu_dir), provenance, settings.backends
        )
        summary["control"] = control_check(winner.fit.plant, data)


def _figure(data: DiagnosisData, levels: tuple[np.ndarray, np.ndarray], named: bool,
            summary: dict[str, Any], title: str) -> bytes:  # fmt: skip
    from gatetwin.diagnosis.plots import diagnosis_png

    before, after = levels
    return diagnosis_png(data, before, after if named else None,
                         sigma_mm=summary["noise_floor_mm"], windows=summary["windows"],
                         title=title)  # fmt: skip


__all__ = ["DiagnosisSettings", "diagnose_record"]
