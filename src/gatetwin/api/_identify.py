"""Identify a model from one record, or every model of a records folder.

One record gives one model of one gauge, valid at that record's discharge: an FOPDT from a
step test (:func:`gatetwin.identification.identify_step`, refined driven by the reconstructed
opening as in ``gatetwin run``), an ARX model from a PRBS test
(:func:`gatetwin.identification.identify_prbs`), or a physical model from any record together
with a static rating table (:func:`gatetwin.identification.physical.fit_physical`). A folder
gives the models ``gatetwin run`` builds (:func:`gatetwin.identification.suite.identify_folder`).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin.api._model import Model, ModelSet, model_from_document
from gatetwin.errors import IdentificationError
from gatetwin.records import Record, StaticTable, read_record, read_static_table

__all__ = ["AUTO_FAMILY", "FAMILIES", "identify", "identify_folder"]

#: Families :func:`identify` fits from one record (``auto``: by the record's test type).
FAMILIES = ("auto", "fopdt", "arx", "physical")
#: The family ``auto`` picks per test type.
AUTO_FAMILY = {"step": "fopdt", "prbs": "arx"}


def _record(record: Record | str | os.PathLike[str]) -> Record:
    return record if isinstance(record, Record) else read_record(os.fspath(record))


def _where(record: Record) -> str:
    return record.path or "record"


def _stem(record: Record) -> str:
    return Path(record.path).stem if record.path else "record"


def _flow_knots(record: Record) -> tuple[float, ...]:
    """Knots at the record's lowest and highest discharge (to 0.1 m³/h, outwards), one if
    the discharge is constant: the model holds over the whole record without clamping."""
    q = np.asarray(record.flow_m3h, dtype=float)
    q = q[np.isfinite(q)]
    if q.size == 0:
        raise IdentificationError(f"{_where(record)}: no discharge logged (flow_m3h empty)")
    lo, hi = math.floor(q.min() * 10) / 10, math.ceil(q.max() * 10) / 10
    return (lo, hi) if hi > lo else (lo,)


def _flat_schedule(knots: tuple[float, ...], values: dict[str, float]) -> Any:
    from gatetwin.plant.model import Schedule

    return Schedule(knots, {k: (float(v),) * len(knots) for k, v in values.items()})


def _with_level_range(doc: dict[str, Any], record: Record, gauge: str) -> dict[str, Any]:
    """State the level range the record spans at ``gauge`` (mm, whole) as validity."""
    level = np.asarray(record.levels_mm[gauge], dtype=float)
    level = level[np.isfinite(level)]
    doc["validity"]["level_range_mm"] = [float(np.floor(level.min())),
                                         float(np.ceil(level.max()))]  # fmt: skip
    return doc


def _provenance(record: Record, method: str, metrics: dict[str, Any]) -> dict[str, Any]:
    from gatetwin.identification.suite import role_of

    return {"method": method,
            "records": [{"name": _stem(record), "sha256": record.sha256,
                         "role": role_of(record)}],
            "metrics": metrics}  # fmt: skip


def _fopdt(record: Record, gauge: str, name: str) -> dict[str, Any]:
    from gatetwin.identification import identify_step, reconstructed_opening
    from gatetwin.identification.fopdt_driven import fit_fopdt_driven
    from gatetwin.identification.schedule import DIGITS, StepCondition
    from gatetwin.identification.suite import OPENING_BAND_MM, free_run_fit
    from gatetwin.modelfile import model_document
    from gatetwin.plant.model import FopdtPlant

    step = identify_step(record, gauge)
    onset = step.gauges[gauge]
    opening = reconstructed_opening(record.time_s, record.opening_mm, record.hold)
    fit = fit_fopdt_driven(
        record.time_s,
        opening,
        record.levels_mm[gauge],
        initial=(onset.fit.gain_mm_per_mm, onset.fit.time_constant_s, 0.5),
    )
    cond = StepCondition(
        _stem(record), step.flow_m3h, step.opening_before_mm, step.delta_e_mm,
        onset.paper.pre_mean_mm, fit.gain_mm_per_mm, fit.time_constant_s, fit.dead_time_s,
        fit.gain_se_mm_per_mm, fit.time_constant_se_s, fit.dead_time_se_s, record.sha256,
    )  # fmt: skip
    values = {"gain_mm_per_mm": fit.gain_mm_per_mm, "time_constant_s": fit.time_constant_s,
              "dead_time_s": fit.dead_time_s, "level_ref_mm": fit.baseline_mm}  # fmt: skip
    values = {k: round(v, DIGITS[k]) + 0.0 for k, v in values.items()}
    plant = FopdtPlant(gauge, round(fit.opening_ref_mm, 3),
                       _flat_schedule(_flow_knots(record), values))  # fmt: skip
    return model_document(
        name, plant,
        description=f"FOPDT of the level at gauge {gauge} from the step test {_stem(record)} "
        "(least-squares fit, continuous dead time), valid at its discharge",
        conditions=[cond.to_dict()], rating={}, operating_openings_mm=[plant.opening_ref_mm]
        * len(plant.schedule.flow_m3h), opening_band_mm=OPENING_BAND_MM,
        provenance=_provenance(
            record, "FOPDT least squares driven by the opening reconstructed during gate "
            "motion, started from the step's onset fit; level_ref_mm is the fitted level at "
            "opening_ref_mm (no rating relation)",
            {"free_run_fit": {_stem(record): free_run_fit(plant, record, gauge)}}),
    )  # fmt: skip


def _arx(record: Record, gauge: str, name: str, orders: tuple[int, int, int]) -> dict[str, Any]:
    from gatetwin.identification import identify_prbs
    from gatetwin.identification.suite import OPENING_BAND_MM
    from gatetwin.modelfile import model_document
    from gatetwin.plant.model import ArxPlant

    res = identify_prbs(record, gauge, orders)
    fit = res.fit
    values = {f"a{i + 1}": a for i, a in enumerate(fit.a)}
    values |= {f"b{j + 1}": b for j, b in enumerate(fit.b)}
    values["level_ref_mm"] = fit.level_mean_mm
    knots = _flow_knots(record)
    plant = ArxPlant(gauge, float(fit.opening_mean_mm), float(fit.sample_period_s), fit.na,
                     fit.nb, fit.nk, _flat_schedule(knots, values))  # fmt: skip
    summary = res.to_dict()
    return model_document(
        name, plant,
        description=f"ARX{(fit.na, fit.nb, fit.nk)} of the level at gauge {gauge} from the "
        f"PRBS test {_stem(record)}, valid at its discharge",
        conditions=[{"name": _stem(record), "flow_m3h": res.flow_m3h,
                     "opening_mm": fit.opening_mean_mm, "level_mm": fit.level_mean_mm,
                     "record_sha256": record.sha256}],
        rating={}, operating_openings_mm=[plant.opening_ref_mm] * len(knots),
        opening_band_mm=OPENING_BAND_MM,
        provenance=_provenance(record, f"ARX{(fit.na, fit.nb, fit.nk)} least squares "
                               f"({res.rows} rows: {res.rows_reason})",
                               {"one_step": summary["one_step"],
                                "simulation": summary["simulation"]}),
    )  # fmt: skip


def _static(record: Record, static: StaticTable | str | os.PathLike[str] | None) -> StaticTable:
    if isinstance(static, StaticTable):
        return static
    if static is None:
        beside = Path(record.path).with_name("static.csv") if record.path else None
        if beside is None or not beside.is_file():
            raise IdentificationError(
                f"{_where(record)}: a physical model needs a static rating table; pass "
                "static=PATH or put static.csv next to the record"
            )
        static = beside
    return read_static_table(os.fspath(static))


def _physical(record: Record, gauge: str, name: str, static: Any) -> dict[str, Any]:
    from gatetwin.identification.physical import data_ranges, fit_physical
    from gatetwin.identification.suite import free_run_fit
    from gatetwin.modelfile import physical_document

    table = _static(record, static)
    records = {_stem(record): record}
    ranges = data_ranges(table, records, gauge)
    fit = fit_physical(table, records, gauge, ranges["flow_m3h"])
    return physical_document(
        name, fit.plant, ranges,
        description=f"Physical model of the level at gauge {gauge} (storage, gate law, "
        f"actuator) from {_stem(record)} and the static table",
        provenance=_provenance(record, "gate law from the steady points, actuator from the "
                               "gate moves, storage by simulation error, then jointly",
                               {"free_run_fit": {_stem(record): free_run_fit(fit.plant, record,
                                                                             gauge)},
                                "fit": fit.report(), "static_sha256": table.sha256}),
    )  # fmt: skip


def _family(record: Record, family: str) -> str:
    if family not in FAMILIES:
        raise IdentificationError(f"family must be one of {', '.join(FAMILIES)} (got "
                                  f"{family!r})")  # fmt: skip
    if family != "auto":
        return family
    if record.test not in AUTO_FAMILY:
        raise IdentificationError(
            f"{_where(record)}: a {record.test!r} record has no default family; pass "
            "family='physical' (with a static table) or read it with test='step' or 'prbs'"
        )
    return AUTO_FAMILY[record.test]


def identify(record: Record | str | os.PathLike[str], family: str = "auto",
             gauge: str | None = None, *, name: str | None = None,
             orders: tuple[int, int, int] = (2, 2, 1),
             static: StaticTable | str | os.PathLike[str] | None = None) -> Model:  # fmt: skip
    """Identify a model of one gauge from one record.

    Parameters
    ----------
    record : Record, str or PathLike
        A read record, or the path of its CSV (sidecar beside it).
    family : {"auto", "fopdt", "arx", "physical"}
        ``fopdt`` needs a step test, ``arx`` a PRBS test; ``physical`` takes any record
        plus a static rating table. ``auto``: ``fopdt`` for a step test, ``arx`` for PRBS.
    gauge : str, optional
        Gauge to model; default for an ARX model the gauge with the highest signal-to-noise
        ratio (as :func:`identify_folder` picks the discrete model's), else ``3F`` if the
        record has it, else its first gauge.
    name : str, optional
        Model name (a C identifier: it names the FMU); default ``<family>_<gauge>``.
    orders : (na, nb, nk)
        ARX orders (default the reference study's ARX(2,2,1)).
    static : StaticTable, str or PathLike, optional
        Static rating table of a physical model; default ``static.csv`` beside the record.

    Returns
    -------
    Model
        Valid at the record's discharge (its schedule has knots at the record's lowest and
        highest discharge, with the same parameters) and, for FOPDT and ARX, within
        ±10 mm of the opening it was identified around.

    Raises
    ------
    RecordError
        The record breaks the data-format contract.
    IdentificationError
        Unknown family or gauge, or a record that cannot support the family.

    Examples
    --------
    >>> from gatetwin import bundled_records_dir, identify
    >>> model = identify(bundled_records_dir() / "C.csv")  # a PRBS test: ARX(2,2,1)
    >>> model.family, model.plant.na, model.plant.sample_period_s
    ('arx', 2, 1.2)
    """
    rec = _record(record)
    kind = _family(rec, family)
    if gauge is None and kind == "arx":
        from gatetwin.identification.suite import arx_gauge_of

        gauge = arx_gauge_of([rec])
    g = gauge or ("3F" if "3F" in rec.levels_mm else rec.gauges[0])
    if g not in rec.levels_mm:
        raise IdentificationError(f"{_where(rec)}: no gauge {g}; it has {', '.join(rec.gauges)}")
    label = name or f"{kind}_{g}"
    if kind == "fopdt":
        doc = _with_level_range(_fopdt(rec, g, label), rec, g)
    elif kind == "arx":
        doc = _with_level_range(_arx(rec, g, label, orders), rec, g)
    else:
        doc = _physical(rec, g, label, static)
    return model_from_document(doc)


def identify_folder(path: str | os.PathLike[str], progress: Any = None) -> ModelSet:
    """Identify every model of a records folder (the models ``gatetwin run`` builds).

    Parameters
    ----------
    path : str or PathLike
        A folder of records (``*.csv`` with sidecars) and one static rating table.
    progress : callable, optional
        Receives one line of text per record identified.

    Returns
    -------
    ModelSet
        ``fopdt_<G>`` (envelope FOPDT) and ``physical_<G>`` per gauge of the step tests,
        ``arx_<G>`` at the PRBS tests' gauge of the highest signal-to-noise ratio when there
        are PRBS tests. A gauge whose physical fit fails has no ``physical_<G>``; its FOPDT
        holds on the step conditions alone and says why in
        ``provenance.metrics.physical_not_identified``.

    Raises
    ------
    RecordError, IdentificationError
        A bad record, a gauge name no model can carry, no static table, too little data
        for the step tests.

    Examples
    --------
    >>> import shutil
    >>> from pathlib import Path
    >>> from gatetwin import bundled_records_dir, identify_folder
    >>> folder = Path("records")
    >>> folder.mkdir()
    >>> for name in ("A", "B", "Q50", "static"):  # three step tests and the rating table
    ...     for ext in (".csv", ".json"):
    ...         _ = shutil.copy(bundled_records_dir() / f"{name}{ext}", folder)
    >>> models = identify_folder(folder)
    >>> sorted(models)[:3], models["fopdt_3F"].validity["flow_m3h"]
    (['fopdt_1D', 'fopdt_2E', 'fopdt_3F'], [20.0, 90.0])
    """
    from gatetwin.identification.suite import identify_folder as identify_all

    folder = Path(os.fspath(path))
    if not folder.is_dir():
        raise IdentificationError(f"{folder}: not a folder (expected a folder of records)")
    ident = identify_all(folder, progress)
    return ModelSet({n: model_from_document(doc) for n, doc in ident.models.items()}, folder)
