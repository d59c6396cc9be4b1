"""Identify every model of a set of records: FOPDT schedules, ARX schedule, ratings.

The one function behind ``gatetwin models`` and the identification stage of
``gatetwin run``. Records are split by their sidecar's ``role``: ``fit`` records build the
models, ``held_out`` records only check them (the schedule's prediction of K, T, L and a
free run of the scheduled plant on the held-out record), ``validation`` records are read
but not identified at all: they take no part in any model file, whatever their test type,
and only the run's validation matrix uses them.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError
from gatetwin.identification.arx_envelope import envelope_arx, fit_condition
from gatetwin.identification.discrete_select import select_discrete
from gatetwin.identification.fopdt_driven import fit_fopdt_driven
from gatetwin.identification.physical import data_ranges, fit_physical
from gatetwin.identification.physical_start import gate_width_m
from gatetwin.identification.prbs import PrbsIdentification, identify_prbs
from gatetwin.identification.preprocess import reconstructed_opening
from gatetwin.identification.rating import RatingFit, fit_static_table
from gatetwin.identification.schedule import (
    ArxCondition,
    StepCondition,
    arx_schedule,
    fopdt_schedule,
    predict_condition,
)
from gatetwin.identification.step import StepIdentification, identify_step
from gatetwin.modelfile import model_document, physical_document
from gatetwin.noise import record_noise_floor
from gatetwin.plant.model import local_fopdt, plant_from_dict
from gatetwin.plant.simulate import simulate
from gatetwin.records import Record, detect_table_kind, read_record, read_static_table
from gatetwin.records.sidecar import VALIDATION_ROLE

__all__ = [
    "ARX_ORDERS",
    "OPENING_BAND_MM",
    "Identified",
    "arx_gauge_of",
    "arx_model",
    "fopdt_model",
    "free_run_fit",
    "gauge_fopdt",
    "gauge_models",
    "identify_folder",
    "identify_records",
    "load_folder",
    "load_records",
    "physical_model",
    "role_of",
    "signal_to_noise",
]

#: Validity band around the operating opening: the step (5 mm) or the PRBS amplitude
#: (±5 mm) the conditions were identified over, plus 5 mm.
OPENING_BAND_MM = 10.0
ARX_ORDERS = (2, 2, 1)


@dataclass
class Identified:
    """Everything identified from one records folder (inputs to models, figures, tables)."""

    records: dict[str, Record] = field(default_factory=dict)
    steps: dict[str, StepIdentification] = field(default_factory=dict)
    prbs: dict[str, PrbsIdentification] = field(default_factory=dict)
    ratings: dict[str, RatingFit] = field(default_factory=dict)
    static_sha256: str = ""
    static: Any = None
    models: dict[str, dict[str, Any]] = field(default_factory=dict)
    held_out: dict[str, dict[str, Any]] = field(default_factory=dict)
    arx_gauge: str = ""
    #: Models that could not be identified (name: why): a gauge whose physical fit fails
    #: keeps its FOPDT on the step conditions alone (:func:`gauge_models`).
    not_identified: dict[str, str] = field(default_factory=dict)


def signal_to_noise(level_mm: np.ndarray) -> float:
    """A level record's standard deviation over its noise's, the noise's from the first
    differences (``sd(Δy)/√2``: white noise dominates the differences of a slow pool)."""
    y = level_mm[np.isfinite(level_mm)]
    noise = float(np.std(np.diff(y))) / math.sqrt(2.0) if y.size > 2 else 0.0
    return float(np.std(y)) / noise if noise > 0 else 0.0


def arx_gauge_of(records: list[Record]) -> str:
    """The gauge the discrete model is identified at: the one every PRBS record has with the
    highest mean signal-to-noise ratio (:func:`signal_to_noise`) over them."""
    common = set.intersection(*(set(r.levels_mm) for r in records))
    if not common:
        raise IdentificationError("the PRBS records share no gauge for the discrete model")
    score = {g: float(np.mean([signal_to_noise(r.levels_mm[g]) for r in records]))
             for g in sorted(common)}  # fmt: skip
    return max(score, key=lambda g: (score[g], g))


def role_of(record: Record) -> str:
    """The sidecar's ``role`` (``fit``, ``held_out`` or ``validation``); ``fit`` without one."""
    return str(record.metadata.get("role", "fit"))


def load_folder(folder: Path, progress: Any = None) -> Identified:
    """Read every record and the static table of ``folder`` and identify each.

    Records of role ``validation`` are read (``records``) but not identified: they are in
    neither ``steps`` nor ``prbs``, so no model is fitted or checked on them here.
    """
    return load_records(sorted(folder.glob("*.csv")), str(folder), progress)


def _check_gauge_names(path: Path, gauges: Any) -> None:
    """Refuse a gauge no model file can name (the model schema's pattern: FMU variables and
    C identifiers are made of it) before anything is fitted."""
    from gatetwin.modelschema import model_schema

    pattern = model_schema()["$defs"]["gauge"]["pattern"]
    for gauge in gauges:
        if not re.fullmatch(pattern, gauge):
            raise IdentificationError(
                f"{path}: column level_{gauge}_mm: gauge name {gauge!r} does not match "
                f"{pattern} (a model names its FMU variables after it); rename the column"
            )


def load_records(paths: list[Path], where: str, progress: Any = None) -> Identified:
    """Like :func:`load_folder` on the CSV files ``paths`` (``where`` names them in errors)."""
    out = Identified()
    prbs: dict[str, Record] = {}
    for path in paths:
        if detect_table_kind(path) == "static":
            table = read_static_table(path)
            _check_gauge_names(path, table.gauges)
            out.static_sha256 = table.sha256
            out.static = table
            continue
        rec = read_record(path)
        _check_gauge_names(path, rec.levels_mm)
        out.records[path.stem] = rec
        if role_of(rec) == VALIDATION_ROLE:
            if progress:
                progress(f"      {path.name}: validation record, read and not fitted")
            continue
        if progress:
            progress(f"      identifying {path.name} ({rec.test})")
        if rec.test == "step":
            out.steps[path.stem] = identify_step(rec)
        elif rec.test == "prbs":
            prbs[path.stem] = rec
    _identify_prbs(out, prbs)
    if out.static is not None:
        fitted = {n: r for n, r in out.records.items() if role_of(r) != VALIDATION_ROLE}
        gauge = next(iter(out.static.gauges))
        width, _ = gate_width_m(out.static, fitted, gauge)
        out.ratings = fit_static_table(out.static, width)
    if not out.ratings:
        raise IdentificationError(f"{where}: no static rating table (static.csv) found")
    return out


def _identify_prbs(out: Identified, prbs: dict[str, Record]) -> None:
    """The PRBS records identified at the gauge :func:`arx_gauge_of` picks."""
    if prbs:
        out.arx_gauge = arx_gauge_of(list(prbs.values()))
        for name, rec in prbs.items():
            out.prbs[name] = identify_prbs(rec, gauge=out.arx_gauge, orders=ARX_ORDERS)


def _step_conditions(ident: Identified, gauge: str, role: str) -> list[StepCondition]:
    """Per-condition FOPDTs fitted with the reconstructed opening as input (the input an
    FMU, the harness and the MPC give the model; see
    :mod:`gatetwin.identification.fopdt_driven`)."""
    conds = []
    for name, step in ident.steps.items():
        rec = ident.records[name]
        if role_of(rec) != role or gauge not in step.gauges:
            continue
        paper, onset = step.gauges[gauge].paper, step.gauges[gauge].fit
        opening = reconstructed_opening(rec.time_s, rec.opening_mm, rec.hold)
        fit = fit_fopdt_driven(
            rec.time_s,
            opening,
            rec.levels_mm[gauge],
            initial=(onset.gain_mm_per_mm, onset.time_constant_s, 0.5),
        )
        conds.append(StepCondition(
            name, step.flow_m3h, step.opening_before_mm, step.delta_e_mm, paper.pre_mean_mm,
            fit.gain_mm_per_mm, fit.time_constant_s, fit.dead_time_s,
            fit.gain_se_mm_per_mm, fit.time_constant_se_s, fit.dead_time_se_s, rec.sha256,
        ))  # fmt: skip
    return conds


def _records_provenance(ident: Identified, names: list[str]) -> list[dict[str, str]]:
    rows = [{"name": n, "sha256": ident.records[n].sha256, "role": role_of(ident.records[n])}
            for n in names]  # fmt: skip
    rows.append({"name": "static", "sha256": ident.static_sha256, "role": "rating"})
    return rows


def free_run_fit(plant: Any, record: Record, gauge: str, grid: bool = False
                 ) -> dict[str, float]:  # fmt: skip
    """Free run of ``plant`` on ``record`` (reconstructed opening): fit %, RMSE, bias.

    ``grid``: on the record's nominal sample grid (as the FMU harness drives a discrete
    model), not its logged times."""
    e = reconstructed_opening(record.time_s, record.opening_mm, record.hold)
    y = record.levels_mm[gauge]
    t = np.arange(record.n_samples) * record.sample_period_s if grid else record.time_s
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        y_sim = simulate(plant, t, e, record.flow_m3h)
    ok = np.isfinite(y)
    err = y_sim[ok] - y[ok]
    fit = 100.0 * (1.0 - np.linalg.norm(err) / np.linalg.norm(y[ok] - np.mean(y[ok])))
    return {"fit_percent": float(fit), "rmse_mm": float(np.sqrt(np.mean(err**2))),
            "bias_mm": float(np.mean(err)), "flow_clamped": bool(caught)}  # fmt: skip


def fopdt_model(ident: Identified, gauge: str,
                physical: dict[str, Any] | None = None) -> dict[str, Any]:  # fmt: skip
    """The scheduled FOPDT model file of one gauge, with its held-out check.

    With ``physical`` (that gauge's physical model document) the FOPDT holds across the
    envelope: its steady level and time constant come from the physical model's gate law and
    storage (:class:`~gatetwin.plant.model.FopdtPlant`'s ``envelope``), its schedule keeps
    the step conditions' K, T, L on their operating line, and its validity is the physical
    model's envelope. The identified conditions are compared with the envelope's local K and
    T at their (Q, e) in ``provenance.metrics.envelope_at_conditions``.
    """
    conds = _step_conditions(ident, gauge, "fit")
    plant, report = fopdt_schedule(conds, ident.ratings[gauge], gauge=gauge)
    envelope_check: dict[str, Any] = {}
    validity: dict[str, Any] = {}
    if physical is not None:
        # the pool's seiche, where the physical model found one, is the same water's
        plant = replace(
            plant,
            envelope=dict(physical["plant"]["parameters"]),
            effects=tuple(physical["plant"]["effects"]),
        )
        validity = {k: physical["validity"][k] for k in ("opening_range_mm", "level_range_mm")}
        validity["flow_m3h"] = physical["validity"]["flow_m3h"]
        for key in ("sample_period_s", "level_noise_sd_mm"):
            if key in physical["validity"]:
                validity[key] = physical["validity"][key]
        for c in conds:
            middle = c.opening_mm + 0.5 * c.delta_e_mm  # the step's K is a secant over it
            local = local_fopdt(plant, c.flow_m3h, middle)
            envelope_check[c.name] = {
                "flow_m3h": c.flow_m3h, "opening_mm": middle,
                "identified": {"gain_mm_per_mm": c.gain_mm_per_mm,
                               "time_constant_s": c.time_constant_s},
                "envelope": {k: local[k] for k in ("gain_mm_per_mm", "time_constant_s")},
            }  # fmt: skip
    held = {}
    for c in _step_conditions(ident, gauge, "held_out"):
        predicted = predict_condition(plant, c.flow_m3h)
        held[c.name] = {
            "flow_m3h": c.flow_m3h,
            "identified": {k: getattr(c, k) for k in predicted},
            "predicted": predicted,
            "free_run": free_run_fit(plant, ident.records[c.name], gauge),
        }
    fits = {c.name: free_run_fit(plant, ident.records[c.name], gauge) for c in conds}
    others = {n: free_run_fit(plant, r, gauge) for n, r in ident.records.items()
              if role_of(r) == "validation" and gauge in r.levels_mm}  # fmt: skip
    doc = model_document(
        f"fopdt_{gauge}", plant,
        description=f"FOPDT of the level at gauge {gauge}, scheduled on discharge over "
        f"{len(conds)} step conditions (least-squares fit, continuous dead time)"
        + ("; across the envelope its steady level and time constant follow the gate law "
           "and storage of the physical model (and its seiche, if it has one)"
           if physical is not None else ""),
        conditions=[c.to_dict() for c in sorted(conds, key=lambda c: c.flow_m3h)],
        rating=ident.ratings[gauge].to_dict(),
        operating_openings_mm=[c.opening_mm for c in sorted(conds, key=lambda c: c.flow_m3h)],
        opening_band_mm=OPENING_BAND_MM,
        provenance={
            "method": "FOPDT least squares per step condition, driven by the opening "
            "reconstructed during gate motion; K, T, L smoothed by a "
            f"degree-{report['degree']} polynomial in Q; level from the rating relation"
            + ("; envelope (steady level, T) from the physical model" if physical else ""),
            "records": _records_provenance(ident, [c.name for c in conds] + list(held)),
            "metrics": {"free_run_fit": fits, "held_out": held, "smoothing": report,
                        "validation_records": others,
                        "envelope_at_conditions": envelope_check},
        },
    )  # fmt: skip
    doc["validity"].update(validity)
    if validity:
        doc["validity"]["outside"] = (
            "the gate law and storage are extrapolated; a warning is logged once when the "
            "discharge leaves the range"
        )
    return doc


def arx_model(ident: Identified, gauge: str | None = None,
              physical: dict[str, Any] | None = None) -> dict[str, Any]:  # fmt: skip
    """The discrete model file of ``gauge``, scheduled over the PRBS conditions.

    Beside the paper's equation-error ARX, output error, ARMAX and Box-Jenkins are fitted at
    every condition (:func:`~gatetwin.identification.discrete_select.select_discrete`); the file
    exports the one structure that simulates best over the conditions (mean hold-out
    free-run fit), its deterministic part in the ARX layout, and says which in
    ``structure``. One structure for every condition, so that the schedule interpolates
    like with like.
    """
    gauge = gauge or ident.arx_gauge
    selections = {name: select_discrete(ident.records[name], gauge, ARX_ORDERS)
                  for name in ident.prbs}  # fmt: skip
    structure, scores = _best_structure(selections)
    conds = []
    for name, res in ident.prbs.items():
        fit = next(c for c in selections[name].candidates
                   if c.structure == structure).fit.as_arx()  # fmt: skip
        conds.append(ArxCondition(
            name, res.flow_m3h, fit.opening_mean_mm, fit.level_mean_mm, tuple(fit.a),
            tuple(fit.b), fit.nk, fit.sample_period_s, ident.records[name].sha256,
        ))  # fmt: skip
    plant, report = arx_schedule(conds, ident.ratings[gauge], gauge=gauge)
    metrics = {name: {"one_step": res.to_dict()["one_step"],
                      "simulation": res.to_dict()["simulation"]}
               for name, res in ident.prbs.items()}  # fmt: skip
    if physical is not None:
        return _envelope_arx_model(ident, gauge, physical, metrics, scores)
    doc = model_document(
        f"arx_{gauge}", plant,
        description=f"Discrete model {ARX_ORDERS} of the level at gauge {gauge} "
        f"({structure.upper()} fit, ARX layout), coefficients interpolated over "
        f"{len(conds)} PRBS conditions",
        conditions=[c.to_dict() for c in sorted(conds, key=lambda c: c.flow_m3h)],
        rating=ident.ratings[gauge].to_dict(),
        operating_openings_mm=[c.opening_mm for c in sorted(conds, key=lambda c: c.flow_m3h)],
        opening_band_mm=OPENING_BAND_MM,
        provenance={"method": f"{structure.upper()}{ARX_ORDERS} prediction-error fit "
                    f"({_rows(ident)} rows), the structure of ARX, OE, ARMAX and BJ with the "
                    "best mean hold-out free-run fit over the conditions",
                    "records": _records_provenance(ident, list(ident.prbs)),
                    "metrics": {"per_condition": metrics, "schedule": report,
                                "structures": scores}},
    )  # fmt: skip
    doc["structure"] = structure
    return doc


def _envelope_arx_model(
    ident: Identified,
    gauge: str,
    physical: dict[str, Any],
    metrics: dict[str, Any],
    scores: dict[str, Any],
) -> dict[str, Any]:
    """The discrete model across the envelope (:mod:`gatetwin.identification.arx_envelope`), with
    the local structures' comparison kept in its provenance."""
    phys_plant = plant_from_dict(physical["plant"])
    nb, nk = ARX_ORDERS[1], ARX_ORDERS[2]
    conds = [fit_condition(name, ident.records[name], phys_plant, nb=nb, nk=nk)
             for name in ident.prbs]  # fmt: skip
    ts = ident.records[next(iter(ident.prbs))].sample_period_s
    plant = envelope_arx(conds, phys_plant, ts, nb=nb, nk=nk)
    fits = {n: free_run_fit(plant, r, gauge, grid=True) for n, r in ident.records.items()
            if role_of(r) != "fit" and gauge in r.levels_mm}  # fmt: skip
    doc = model_document(
        f"arx_{gauge}", plant,
        description=f"Discrete model of the level at gauge {gauge} across the envelope: "
        f"ARX(1,{nb},{nk}) on the gate law's steady level (a Hammerstein input) with unit "
        "gain, its pole following the pool's time constant; fitted by output error at "
        f"{len(conds)} PRBS conditions and scheduled on discharge between them",
        conditions=[c.to_dict() for c in sorted(conds, key=lambda c: c.flow_m3h)],
        rating=ident.ratings[gauge].to_dict(),
        operating_openings_mm=[c.opening_mm for c in sorted(conds, key=lambda c: c.flow_m3h)],
        opening_band_mm=OPENING_BAND_MM,
        provenance={"method": f"ARX(1,{nb},{nk}) by output error (simulation error) at each "
                    "PRBS condition on the physical model's steady level, unit gain, pole "
                    "scaled by the storage's time constant across the envelope; beside it the "
                    f"local ARX, OE, ARMAX and BJ {ARX_ORDERS} fits of each condition",
                    "records": _records_provenance(ident, list(ident.prbs)),
                    "metrics": {"per_condition": metrics, "structures": scores,
                                "envelope_conditions": [c.to_dict() for c in conds],
                                "validation_records": fits}},
    )  # fmt: skip
    doc["validity"].update(
        {k: physical["validity"][k] for k in ("flow_m3h", "opening_range_mm", "level_range_mm")}
    )
    doc["validity"]["outside"] = (
        "the gate law and storage are extrapolated; a warning is logged once when an input "
        "or the level leaves the range"
    )
    doc["structure"] = "oe"
    doc["form"] = "envelope"
    return doc


def _best_structure(selections: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """The structure with the best mean hold-out free-run fit over the conditions, and every
    structure's fits (percent, per condition)."""
    scores: dict[str, dict[str, float]] = {}
    for name, sel in selections.items():
        for cand in sel.candidates:
            scores.setdefault(cand.structure, {})[name] = float(cand.simulation.fit_percent)
    complete = {k: v for k, v in scores.items() if len(v) == len(selections)}
    if not complete:
        raise IdentificationError("no discrete structure could be fitted at every condition")
    best = max(complete, key=lambda k: (float(np.mean(list(complete[k].values()))), k == "arx"))
    return best, {k: {n: round(f, 3) for n, f in v.items()} for k, v in scores.items()}


def physical_model(ident: Identified, gauge: str) -> dict[str, Any]:
    """The physical model file of ``gauge``, identified from every fit record and the table."""
    fit_records = {n: r for n, r in ident.records.items() if role_of(r) == "fit"}
    ranges = data_ranges(ident.static, fit_records, gauge)
    fit = fit_physical(ident.static, fit_records, gauge, ranges["flow_m3h"])
    plant = fit.plant
    held = {n: free_run_fit(plant, r, gauge) for n, r in ident.records.items()
            if role_of(r) != "fit" and gauge in r.levels_mm}  # fmt: skip
    fits = {n: free_run_fit(plant, r, gauge) for n, r in fit_records.items()}
    doc = physical_document(
        f"physical_{gauge}",
        plant,
        ranges,
        description=f"Physical model of the level at gauge {gauge}: pool storage fed by the "
        "measured inflow and drained by the gate law, behind an actuator slowing under load",
        provenance={
            "method": "gate law and gauge offset from every steady point (static table and "
            "settled holds), actuator speed from the gate moves, storage area by simulation "
            "error on every dynamic record, then all hydraulic parameters jointly (each "
            "source weighted by its residual RMS); standard errors from the Jacobian",
            "records": _records_provenance(ident, list(fit_records)),
            "metrics": {"free_run_fit": fits, "held_out": held, "fit": fit.report()},
        },
    )
    # the records' sample period: what a controller or observer of this model samples at
    doc["validity"]["sample_period_s"] = min(r.sample_period_s for r in fit_records.values())
    # the gauge's noise: what an observer of this model weighs the readings by
    sigmas = [record_noise_floor(r, gauge).sigma_mm for r in fit_records.values()
              if gauge in r.levels_mm]  # fmt: skip
    sigmas = [s for s in sigmas if np.isfinite(s)]
    if sigmas:
        doc["validity"]["level_noise_sd_mm"] = round(float(np.median(sigmas)), 3)
    return doc


def _rows(ident: Identified) -> str:
    return "/".join(sorted({res.rows for res in ident.prbs.values()}))


def identify_folder(folder: Path, progress: Any = None, fleet: Any = None) -> Identified:
    """Identify every record of ``folder`` and build the model files."""
    return identify_records(sorted(folder.glob("*.csv")), str(folder), progress, fleet)


def identify_records(paths: list[Path], where: str, progress: Any = None,
                     fleet: Any = None) -> Identified:  # fmt: skip
    """Identify the records ``paths`` (one gate's records and its static table) and build
    the model files; ``where`` names them in errors. ``fleet``
    (:class:`~gatetwin.fleet.execute.FleetSettings`) fits each gauge's models as one task
    where it says; the models are the same."""
    from gatetwin.fleet.execute import map_tasks

    ident = load_records(paths, where, progress)
    gauges = sorted({g for s in ident.steps.values() for g in s.gauges})
    # the discrete model's gauge first: its task fits the discrete model too, the longest
    gauges.sort(key=lambda g: not (ident.prbs and g == ident.arx_gauge))
    if progress:
        for gauge in gauges:
            progress(f"      identifying physical_{gauge} and fopdt_{gauge} from every record")
    found = map_tasks(gauge_models, [(ident, g) for g in gauges], fleet,
                      lambda job: f"{where}: gauge {job[1]}'s models")  # fmt: skip
    docs = {name: doc for found_docs in found for name, doc in found_docs.items()}
    for gauge in sorted(gauges):
        fopdt = ident.models[f"fopdt_{gauge}"] = docs.pop(f"fopdt_{gauge}")
        metrics = fopdt["provenance"]["metrics"]
        if "physical_not_identified" in metrics:
            ident.not_identified[f"physical_{gauge}"] = metrics["physical_not_identified"]
        else:
            ident.models[f"physical_{gauge}"] = docs.pop(f"physical_{gauge}")
        ident.held_out[gauge] = metrics["held_out"]
    ident.models.update(docs)  # the discrete model
    if ident.prbs and ident.arx_gauge not in gauges:
        doc = arx_model(ident)
        ident.models[doc["name"]] = doc
    return ident


def gauge_fopdt(job: tuple[Identified, str]) -> dict[str, Any]:
    """The FOPDT model file of one gauge (a task), as :func:`gauge_models` fits it where the
    physical fit succeeds: on the gauge's physical model (the fit's
    :class:`~gatetwin.errors.IdentificationError` propagates)."""
    ident, gauge = job
    return fopdt_model(ident, gauge, physical_model(ident, gauge))


def gauge_models(job: tuple[Identified, str]) -> dict[str, dict[str, Any]]:
    """The model files of one gauge (a task): its physical model, the FOPDT across its
    envelope and, at the discrete model's gauge, the discrete model. Where the physical fit
    fails (:class:`~gatetwin.errors.IdentificationError`), the FOPDT on its step conditions
    alone, the reason in its ``provenance.metrics.physical_not_identified``
    (:func:`identify_records` lists it in ``Identified.not_identified``)."""
    ident, gauge = job
    try:
        physical: dict[str, Any] | None = physical_model(ident, gauge)
    except IdentificationError as exc:  # the FOPDT then holds on its step conditions alone
        physical, why = None, str(exc)
    fopdt = fopdt_model(ident, gauge, physical)
    docs = {fopdt["name"]: fopdt}
    if physical is None:
        fopdt["provenance"]["metrics"]["physical_not_identified"] = why
    else:
        docs[physical["name"]] = physical
    if ident.prbs and gauge == ident.arx_gauge:
        arx = arx_model(ident, physical=physical)
        docs[arx["name"]] = arx
    return docs
