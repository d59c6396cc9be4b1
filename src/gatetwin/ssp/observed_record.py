"""Pack the observer on a measured record as an SSP 1.0 System Structure package (``.ssp``).

The package holds ``SystemStructure.ssd``, the observer FMU (``resources/observer.fmu``,
:mod:`gatetwin.fmu.observer_fmu`), the scenario FMU (``resources/scenario.fmu``,
:mod:`gatetwin.fmu.signal_source`) playing the record, and one parameter set
(``resources/observed_record.ssv``, the scenario's tables) bound to the system. The system
``observed_record`` has

* elements ``observer`` and ``scenario``, in that order, connected scenario
  ``level_<gauge>_mm``, ``opening_mm`` and ``flow_m3h`` → the observer's inputs of the same
  names; nothing reads the observer's outputs (a master logs them: :func:`gatetwin.ssp.
  simulate_ssp` does);
* the record's samples as the scenario's tables, held: sample ``i``'s value (``i`` from 0)
  holds from ``i·T`` on, ``T`` the record's nominal sample period, at which the observer
  samples (as ``observe`` runs it); a knot is written at ``i·T``
  only where the value changes. The values are what ``gatetwin observe`` feeds
  :class:`~gatetwin.mpc.online.OnlineObserver` (:func:`gatetwin.mpc.online.measured_inputs`):
  the level at the gauge and the discharge as logged, the opening as logged on ``hold``
  samples and, on a sample logged while the gate moves (its opening empty), the next logged
  opening (the command the gate is moving to);
* a default experiment from 0 to ``n·T`` for ``n`` samples: ``n`` communication steps of
  ``T``, the FMUs' own default step (SSP 1.0's ``DefaultExperiment`` has no step size).

The observer receives at each communication point ``i·T`` the scenario's value at that
point, sample ``i``, whether the elements are stepped in document order (Gauss-Seidel, the
scenario's outputs read at the end of its previous step) or together (Jacobi): so every
engine gives the observer's estimates of ``observe`` over the record, one per sample.

Like ``observe``, the observer takes the record's rows as consecutive samples of ``T``: the
time stamps' jitter is not replayed (the run's time is ``i·T``). A record which holds a
logging gap (after which the run's time would no longer be the record's), an empty level
(``observe`` refuses it too, the observer has no rule for a missing sample; a file's empty
discharge cells hold the last logged one when it is read, one left empty in a record made in
memory is refused the same way), or more
samples than :data:`~gatetwin.ssp.master.MAX_STEPS` or than the scenario FMU holds
(:data:`~gatetwin.fmu.signal_source.MAX_KNOTS` knots a signal) is refused before anything is
built.

The observer is the one ``observe`` runs by default (``linearisation`` ``auto``): the
schedule observer for a scheduled FOPDT, the envelope observer for a physical plant, each
without effect blocks; it starts at rest on the record's first sample, which are also its
inputs' start values (so an engine that sets no input before initialising it starts it there).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gatetwin.errors import ControlError, ExportError, RecordError
from gatetwin.fmu.description import output_name
from gatetwin.records.segments import GAP_FACTOR
from gatetwin.ssp.master import MAX_STEPS

if TYPE_CHECKING:
    from gatetwin.fmu.signal_source import TableSignal
    from gatetwin.modelfile import ModelFile
    from gatetwin.plant.model import Plant
    from gatetwin.records import Record

#: Relative difference allowed between a record's nominal sample period and an observer's
#: built at another (:func:`check_sample_period`; the package builds its observer at the
#: record's own): a record without a sidecar gets the median of its time steps, which the
#: logger's jitter (±0.02 s on 1.2 s in the bundled records) may move by a millisecond.
PERIOD_RTOL = 0.01
#: Name of the system in the package, and its parameter set's file.
SYSTEM_NAME = "observed_record"
PARAMETERS = f"resources/{SYSTEM_NAME}.ssv"


def record_tables(record: Record, gauge: str, sample_period_s: float) -> tuple[TableSignal, ...]:
    """The scenario's tables of ``record`` (see the module): the level at ``gauge``, the
    opening and the discharge, held from ``i·sample_period_s`` on, a knot where each changes.

    Raises
    ------
    RecordError
        No level at ``gauge``, no opening logged, an empty level or (in a record made in
        memory) discharge (named by its time), a discharge outside the observer's range,
        more samples than a run takes or more knots than the scenario FMU holds.
    """
    from gatetwin.fmu.signal_source import MAX_KNOTS, TableSignal
    from gatetwin.mpc.online import measured_inputs

    where = record.path or "record"
    if gauge not in record.levels_mm:
        raise RecordError(f"{where}: no level column for gauge {gauge} (it has "
                          f"{', '.join(f'level_{g}_mm' for g in record.levels_mm)})")  # fmt: skip
    n = len(record.time_s)
    if n > MAX_STEPS:
        raise RecordError(f"{where}: {n} samples; simulate-ssp runs at most {MAX_STEPS} steps")
    try:
        level, opening, flow = measured_inputs(record, gauge)
    except ControlError as exc:
        raise RecordError(str(exc)) from None
    _check_samples(record, level, flow, gauge)
    signals = []
    for name, unit, values in ((output_name(gauge), "mm", level), ("opening_mm", "mm", opening),
                               ("flow_m3h", "m3/h", flow)):  # fmt: skip
        knots = np.flatnonzero(np.r_[True, values[1:] != values[:-1]])
        if knots.size > MAX_KNOTS:
            raise RecordError(f"{where}: {name} changes at {knots.size} of its {n} samples; the "
                              f"scenario FMU holds at most {MAX_KNOTS} knots a signal")  # fmt: skip
        signals.append(TableSignal(name, unit, tuple(float(k * sample_period_s) for k in knots),
                                   tuple(float(values[k]) for k in knots),
                                   description=f"The record's {name}, held from each sample "
                                   "on"))  # fmt: skip
    return tuple(signals)


def _check_samples(record: Record, level: np.ndarray, flow: np.ndarray, gauge: str) -> None:
    """:class:`RecordError` at the first sample the observer cannot take (as ``observe``)."""
    from gatetwin.plant.model import FLOW_RANGE_M3H

    lo, hi = FLOW_RANGE_M3H
    bad_level = np.flatnonzero(~np.isfinite(level))
    bad_flow = np.flatnonzero(~((flow >= lo) & (flow <= hi)))
    where = record.path or "record"
    checks = (
        (bad_level, f"level_{gauge}_mm is empty"),
        (bad_flow, f"flow_m3h is empty or outside [{lo:g}, {hi:g}] m3/h"),
    )
    for bad, what in checks:
        if bad.size:
            t = float(record.time_s[bad[0]])
            raise RecordError(
                f"{where}: {what} at t = {t:.6g} s ({bad.size} sample(s)); the "
                "observer takes no gap (gatetwin observe refuses it too)"
            )


def check_sample_period(record: Record, sample_period_s: float | None = None) -> None:
    """:class:`RecordError` unless no logging gap (more than
    :data:`~gatetwin.records.segments.GAP_FACTOR` nominal periods between two samples) lies
    in the record and, for an observer built at another period (``sample_period_s``), the
    record's nominal period is that one within :data:`PERIOD_RTOL`."""
    period = float(record.sample_period_s)
    sample_period_s = period if sample_period_s is None else sample_period_s
    if not abs(period - sample_period_s) <= PERIOD_RTOL * sample_period_s:
        raise RecordError(f"{record.path or 'record'}: sample period {period:.6g} s; the "
                          f"observer samples every {sample_period_s:g} s")  # fmt: skip
    time_s = np.asarray(record.time_s, dtype=float)
    gaps = np.flatnonzero(np.diff(time_s) > GAP_FACTOR * period)
    if gaps.size:
        k = gaps[0]
        raise RecordError(f"{record.path or 'record'}: a logging gap of "
                          f"{time_s[k + 1] - time_s[k]:.6g} s after t = {time_s[k]:.6g} s "
                          f"({gaps.size} gap(s)); the package plays one sample per period, so "
                          "its time would no longer be the record's (split the record at its "
                          "gaps)")  # fmt: skip


def observed_plant(model: ModelFile, without_effects: bool) -> tuple[Plant, bool]:
    """The plant the observer is built on and whether it is the envelope observer (as
    ``observe`` picks it); :class:`ExportError` for a model it does not cover."""
    from dataclasses import replace

    from gatetwin.mpc.online import checked_plant, observer_linearisation

    plant = model.plant
    if without_effects and getattr(plant, "effects", ()):
        plant = replace(plant, effects=())
    envelope = observer_linearisation(plant) == "envelope"
    try:
        return checked_plant(plant, "the observer", envelope=envelope), envelope
    except ControlError as exc:
        effects = getattr(plant, "effects", ())
        hint = "; --without-effects drops them" if effects and "without" not in str(exc) else ""
        raise ExportError(f"{exc}{hint}") from None


def observed_record_ssd(name: str, gauge: str, parameters: list[tuple[str, float, str]],
                        stop_time_s: float, description: str,
                        outputs: tuple[tuple[str, str], ...]) -> bytes:  # fmt: skip
    """``SystemStructure.ssd`` of the observer on a record (see the module); ``outputs``:
    the observer FMU's (name, unit), :func:`gatetwin.fmu.observer_fmu.observer_outputs`."""
    from gatetwin.ssp.write import (
        OBSERVER_SOURCE,
        SCENARIO_SOURCE,
        component_element,
        connection_elements,
        finished_document,
        observer_connectors,
        scenario_connectors,
        system_document,
    )

    level = output_name(gauge)
    root, system, elements = system_document(name, SYSTEM_NAME, description, PARAMETERS)
    observer = observer_connectors(level, outputs)
    component_element(elements, "observer", OBSERVER_SOURCE, observer)
    signals = {level: "mm", "opening_mm": "mm", "flow_m3h": "m3/h"}
    component_element(elements, "scenario", SCENARIO_SOURCE,
                      scenario_connectors(signals, parameters))  # fmt: skip
    connection_elements(system, [(("scenario", s), ("observer", s)) for s in signals])
    units = {unit for _, _, unit in (*observer, *parameters)} | set(signals.values())
    return finished_document(root, units, stop_time_s)


def write_observer_ssp(
    model: ModelFile,
    record: Record | str | os.PathLike[str],
    out_path: str | os.PathLike[str],
    *,
    gauge: str | None = None,
    without_effects: bool = False,
) -> Path:
    """Write the observer of ``model`` on ``record`` as an SSP (see the module).

    Parameters
    ----------
    model : ModelFile
        A scheduled FOPDT (the schedule observer) or a physical model (the envelope observer).
    record : Record or path
        The measured record (``RECORD.csv``, read with its sidecar).
    out_path : path
        Target ``.ssp``, written atomically.
    gauge : str, optional
        The gauge whose level the observer reads; the model's gauge (the default) is the only
        one its observer covers.
    without_effects : bool
        Build the observer on the model with its effect blocks dropped (it does not cover
        them; a model with effect blocks is refused otherwise).

    Raises
    ------
    RecordError
        A record the observer cannot take (see the module).
    ExportError
        A model the observer does not cover, another gauge than the model's, a failed build.
    OutputError
        The package cannot be written where asked.
    """
    from gatetwin.fmu.signal_source import describe_signal_source, parameter_values
    from gatetwin.records import read_record
    from gatetwin.ssp.documents import parameter_set_xml
    from gatetwin.ssp.write import ssp_target, write_package

    target = ssp_target(out_path)
    plant, envelope = observed_plant(model, without_effects)
    gauge = plant.gauge if gauge is None else gauge
    if gauge != plant.gauge:
        raise ExportError(f"gauge {gauge}: the model {model.name} observes gauge {plant.gauge}")
    rec = record if hasattr(record, "levels_mm") else read_record(record)
    period = float(rec.sample_period_s)
    check_sample_period(rec)
    signals = record_tables(rec, gauge, period)
    name = Path(rec.path).stem if rec.path else "record"
    facts = {"model": model.name, "record_sha256": rec.sha256}
    scenario = describe_signal_source(signals, f"{model.name}_record", period, facts)
    parameters = [(f"scenario.{n}", v, u) for n, v, u in parameter_values(scenario)]
    n = len(rec.time_s)
    text = (f"The {'envelope' if envelope else 'schedule'} observer of {model.name} on the "
            f"record {name} ({n} samples of {period:g} s from 0 s, the record's "
            "first; the scenario component: X held at X_table.value[k] from X_table.time_s[k] "
            "on)")  # fmt: skip
    from gatetwin.fmu.observer_fmu import observer_outputs

    ssd = observed_record_ssd(f"{model.name}_observed_{name}", gauge, parameters,
                              n * period, text,
                              observer_outputs(plant, envelope))  # fmt: skip
    ssv = parameter_set_xml(SYSTEM_NAME, parameters)
    start = tuple(s.values[0] for s in signals)

    def members(work: Path, package: Path) -> None:
        from gatetwin.fmu.observer_fmu import export_observer
        from gatetwin.fmu.signal_source import build_signal_source
        from gatetwin.ssp.write import OBSERVER_SOURCE, SCENARIO_SOURCE

        export_observer(plant, package / OBSERVER_SOURCE, model_name=f"{model.name}_observer",
                        start_inputs=start, sample_period_s=period)  # fmt: skip
        (work / "scenario").mkdir()
        build_signal_source(scenario, work / "scenario", package / SCENARIO_SOURCE)

    return write_package(target, ssd, ssv, members, PARAMETERS)


__all__ = ["PARAMETERS", "PERIOD_RTOL", "SYSTEM_NAME", "check_sample_period", "observed_plant",
           "observed_record_ssd", "record_tables", "write_observer_ssp"]  # fmt: skip
