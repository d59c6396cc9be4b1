"""The observer on a measured record as an SSP (``gatetwin ssp --observe``): the package
follows the SSP 1.0 schemas, gatetwin's master, fmpy's SSP runner and ecos run it to the same
bits, and what they give is ``gatetwin observe`` on the same record; records and models the
observer cannot take are refused in one line without output."""

from __future__ import annotations

import dataclasses
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from fmu_support import compiler, fmpy_ssp_runner_from_start_values
from gatetwin.bundled import bundled_records_dir
from gatetwin.cli import main
from gatetwin.errors import RecordError
from gatetwin.modelfile import read_model_file
from gatetwin.mpc.online import OUTPUTS, OnlineObserver, measured_inputs
from gatetwin.records import read_record
from gatetwin.ssp import simulate_ssp, write_observer_ssp
from gatetwin.ssp.documents import SSD_SCHEMA, SSV_SCHEMA, read_parameter_set, schema_problems
from gatetwin.ssp.master import read_ssd
from gatetwin.ssp.observed_record import PARAMETERS
from gatetwin.ssp.write import OBSERVER_SOURCE, SCENARIO_SOURCE, SSD_NAME
from test_observer_fmu import TOL as OBSERVER_TOL

pytestmark = pytest.mark.skipif(compiler() is None, reason="no C compiler (cc/gcc) on PATH")

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "models" / "fopdt_3F.json"
#: A short record whose gate moves (217 of its 865 samples logged while moving: the opening
#: the observer takes there is the next logged one) and whose discharge changes.
RECORD = bundled_records_dir() / "D.csv"
GAUGE = "3F"
STEP_S = 1.2
#: ``gatetwin observe`` prints each value with 10 significant digits (``{v:.10g}``): rounding
#: moves a value by at most half a unit in its tenth digit, 5e-10 of its size.
PRINTED_RTOL = 5e-10


@pytest.fixture(scope="module")
def package(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("ssp_observer") / "observed.ssp"
    assert main(["ssp", str(MODEL), "--observe", str(RECORD), "--gauge", GAUGE,
                 "--without-effects", "--out", str(out)]) == 0  # fmt: skip
    return out


@pytest.fixture(scope="module")
def run(package):
    return simulate_ssp(package)


def _read(package: Path, name: str) -> bytes:
    with zipfile.ZipFile(package) as zf:
        return zf.read(name)


def _python_observer() -> tuple[tuple[np.ndarray, ...], dict[str, np.ndarray]]:
    """``OnlineObserver`` on the record as ``gatetwin observe`` feeds it: (inputs, outputs)."""
    inputs = measured_inputs(read_record(RECORD), GAUGE)
    plant = dataclasses.replace(read_model_file(MODEL).plant, effects=())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # as observe: Q beyond the knots clamped
        return inputs, OnlineObserver(plant).run(*inputs)


def test_the_package_follows_the_ssp_1_0_schemas_and_holds_the_record(package):
    """SSD and SSV pass the SSP 1.0 schemas; the system is the observer and the scenario, run
    for one step of 1.2 s per sample; every value of the parameter set is the scenario FMU's
    own start value (an engine that applies no parameter set runs the same system)."""
    from fmpy import read_model_description

    ssd = _read(package, SSD_NAME)
    assert schema_problems(ssd, SSD_SCHEMA) == []
    assert schema_problems(_read(package, PARAMETERS), SSV_SCHEMA) == []
    system = read_ssd(ssd, "test")
    assert [c.name for c in system.components] == ["observer", "scenario"]
    signals = (f"level_{GAUGE}_mm", "opening_mm", "flow_m3h")
    assert set(system.connections) == {("scenario", s, "observer", s) for s in signals}
    n = len(read_record(RECORD).time_s)
    assert (system.start_time_s, system.stop_time_s) == (0.0, n * STEP_S)
    parameters = read_parameter_set(_read(package, PARAMETERS), "ssv")
    folder = package.parent / "unpacked"
    with zipfile.ZipFile(package) as zf:
        zf.extractall(folder)
    scenario = read_model_description(str(folder / SCENARIO_SOURCE))
    starts = {f"scenario.{v.name}": float(v.start) for v in scenario.modelVariables
              if v.start is not None}  # fmt: skip
    assert parameters and all(starts[k] == v for k, v in parameters.items())
    observer = read_model_description(str(folder / OBSERVER_SOURCE))
    first = {v.name: float(v.start) for v in observer.modelVariables if v.causality == "input"}
    (level, opening, flow), _ = _python_observer()
    assert first == {signals[0]: level[0], "opening_mm": opening[0], "flow_m3h": flow[0]}


def test_simulate_ssp_gives_what_observe_gives_on_the_record(package, run, tmp_path, capsys):
    """``gatetwin simulate-ssp`` on the package against ``gatetwin observe`` on the record.

    The observer receives at ``k·1.2 s`` the record's sample ``k`` as ``observe`` feeds it
    (the same doubles: equal). Its outputs are the observer FMU's, which agree with
    ``OnlineObserver`` to ``test_observer_fmu.TOL`` = 1e-9 in each output's unit (the same
    arithmetic generated by casadi, without FMA; round-off ~1e-13 mm): against the Python
    observer's doubles that bound, against ``observe``'s CSV that bound plus its printing to
    10 significant digits (:data:`PRINTED_RTOL` of each value)."""
    csv, est = tmp_path / "result.csv", tmp_path / "est.csv"
    assert main(["simulate-ssp", str(package), "--out", str(csv)]) == 0
    assert "anomaly flag rose" in capsys.readouterr().out
    assert main(["observe", str(MODEL), str(RECORD), "--gauge", GAUGE, "--without-effects",
                 "--out", str(est)]) == 0  # fmt: skip
    ours = np.genfromtxt(csv, delimiter=",", names=True, deletechars="")
    observed = np.genfromtxt(est, delimiter=",", names=True)
    (level, opening, flow), python = _python_observer()
    n = level.size
    assert ours.size == n and observed.size == n
    assert np.array_equal(ours["time_s"], np.arange(n) * STEP_S)
    for name, fed in ((f"level_{GAUGE}_mm", level), ("opening_mm", opening), ("flow_m3h", flow)):
        assert np.array_equal(ours[f"observer.{name}"], fed), name
    assert np.ptp(opening) > 5.0 and np.ptp(flow) > 0.0  # the gate moved, the discharge changed
    for name in OUTPUTS:
        got = ours[f"observer.{name}"]
        assert np.array_equal(got, run.columns[f"observer.{name}"]), name  # the CSV's repr
        assert np.max(np.abs(got - python[name])) <= OBSERVER_TOL, name
        bound = OBSERVER_TOL + PRINTED_RTOL * np.abs(observed[name])
        assert np.all(np.abs(got - observed[name]) <= bound), name
    assert np.ptp(ours["observer.innovation_mm"]) > 1.0  # the estimates move over the record


def test_the_jacobi_scheme_gives_the_same_run(package, run):
    """Nothing reads the observer: stepped in document order or all together, it receives
    the scenario's value at the point it steps from, so the runs are equal to the bit."""
    jacobi = simulate_ssp(package, scheme="jacobi")
    assert list(jacobi.columns) == list(run.columns)
    for name, values in run.columns.items():
        assert np.array_equal(jacobi.columns[name], values), name


def test_fmpys_ssp_runner_gives_the_same_estimates(package, run, monkeypatch):
    """fmpy's runner reads the package with its path, the stop time and the step. It sets
    every connector to 0.0 before the first step (``fmpy/ssp/simulation.py``, "initialize
    the connectors") and exchanges nothing in initialisation, so its first step gives the
    observer a level, opening and discharge of 0; given there the start values the package
    sets (the observer's inputs start at the record's first sample), its run is gatetwin's
    to the bit: the same FMU binaries given the same doubles (equal, not within a tolerance:
    a system without a feedback loop has no other source of difference; the scenario's
    knots are in force on fmpy's running-sum time as on k·h)."""
    import fmpy.ssp.simulation as runner

    n = run.time_s.size
    plain = runner.simulate_ssp(str(package), stop_time=n * STEP_S, step_size=STEP_S)
    assert plain["observer.filtered_level_mm"][0] != run.columns["observer.filtered_level_mm"][0]

    fmpy_ssp_runner_from_start_values(monkeypatch)
    out = runner.simulate_ssp(str(package), stop_time=n * STEP_S, step_size=STEP_S)
    assert len(out) == n
    for name in OUTPUTS:
        assert np.array_equal(out[f"observer.{name}"], run.columns[f"observer.{name}"]), name
    # fmpy's row k holds an input as it goes into the step from t_(k+1)
    level = f"observer.level_{GAUGE}_mm"
    assert np.array_equal(out[level][:-1], run.columns[level][1:])


def test_ecos_gives_the_same_estimates(package, run):
    """ecos runs the package as it is (it gives the observer its inputs before it
    initialises): every input and every observer output equal to gatetwin's run."""
    from test_ssp import _compare_ecos

    _compare_ecos(package, run)


def _record_copy(tmp_path: Path, name: str, change, sidecar: dict | None = None) -> Path:
    """The record's CSV with each data line passed through ``change(index, cells)``, and its
    sidecar (``sidecar`` replacing fields)."""
    import json

    lines = RECORD.read_text(encoding="utf-8").splitlines()
    header = lines[0].split(",")
    rows = [change(i, dict(zip(header, line.split(","), strict=True)))
            for i, line in enumerate(lines[1:])]  # fmt: skip
    out = tmp_path / f"{name}.csv"
    kept = [h for h in header if h in rows[0]]
    out.write_text("\n".join([",".join(kept)] + [",".join(r[h] for h in kept) for r in rows])
                   + "\n", encoding="utf-8")  # fmt: skip
    meta = json.loads(RECORD.with_suffix(".json").read_text(encoding="utf-8"))
    out.with_suffix(".json").write_text(json.dumps({**meta, **(sidecar or {})}), "utf-8")
    return out


def _without_rows(tmp_path: Path, dropped: range) -> Path:
    """The record with the data lines ``dropped`` (0-based) left out: a logging gap."""
    lines = RECORD.read_text(encoding="utf-8").splitlines()
    kept = [line for i, line in enumerate(lines[1:]) if i not in dropped]
    out = tmp_path / "gapped.csv"
    out.write_text("\n".join([lines[0], *kept]) + "\n", encoding="utf-8")
    out.with_suffix(".json").write_bytes(RECORD.with_suffix(".json").read_bytes())
    return out


def _set(column: str, at: int, value: str):
    def change(i: int, row: dict) -> dict:
        return {**row, column: value} if i == at else row

    return change


def _without(column: str):
    def change(_i: int, row: dict) -> dict:
        return {k: v for k, v in row.items() if k != column}

    return change


def _refused(argv: list[str], tmp_path: Path, capsys) -> str:
    out = tmp_path / "m.ssp"
    assert main(["ssp", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("gatetwin: error:"), (argv, err)
    assert not out.exists() and not list(tmp_path.glob(".m.ssp*")), argv
    return err[0]


def test_what_the_observer_cannot_take_is_refused_in_one_line_without_output(
    tmp_path, capsys, monkeypatch
):
    """A record without the gauge, with an empty level (``observe`` refuses it) or, made in
    memory, discharge, too long for simulate-ssp or for the scenario FMU; a model the
    observer does not cover, another gauge, the loop's options: one line, exit 2, no
    package."""
    import gatetwin.fmu.signal_source as signal_source
    import gatetwin.ssp.observed_record as observed_record

    model, effects = str(MODEL), "--without-effects"
    no_gauge = _record_copy(tmp_path, "no3F", _without("level_3F_mm"))
    gap = _record_copy(tmp_path, "gap", _set("level_3F_mm", 40, ""))
    cases = [
        ([model, "--observe", str(no_gauge), effects],
         "no level column for gauge 3F"),
        ([model, "--observe", str(gap), effects],
         "level_3F_mm is empty at t = 48"),
        ([model, "--observe", str(RECORD)], "effect blocks are not covered"),
        ([str(ROOT / "models" / "arx_3F.json"), "--observe", str(RECORD)],
         "needs a scheduled FOPDT plant"),
        ([model, "--observe", str(RECORD), "--gauge", "2E", effects],
         "gauge 2E: the model fopdt_3F observes gauge 3F"),
        ([model, "--observe", str(RECORD), effects, "--controller", "pi"],
         "--controller applies to the closed loop"),
        ([model, "--observe", str(RECORD), effects, "--observer"], "--observer applies"),
        ([model, "--observe", str(RECORD), effects, "--minutes", "0"], "--minutes applies"),
        ([model, "--observe", str(RECORD), effects, "--horizon", "0"], "--horizon applies"),
        ([model, "--observe", str(_without_rows(tmp_path, range(100, 200))), effects],
         "a logging gap of 121.198 s after t = 118.801 s"),
        ([model, "--gauge", GAUGE], "--gauge applies to --observe"),
    ]  # fmt: skip
    for argv, reason in cases:
        assert reason in _refused(argv, tmp_path, capsys), argv
    n = len(read_record(RECORD).time_s)
    monkeypatch.setattr(observed_record, "MAX_STEPS", n - 1)
    line = _refused([model, "--observe", str(RECORD), effects], tmp_path, capsys)
    assert f"{n} samples; simulate-ssp runs at most {n - 1} steps" in line
    monkeypatch.undo()
    monkeypatch.setattr(signal_source, "MAX_KNOTS", 100)
    line = _refused([model, "--observe", str(RECORD), effects], tmp_path, capsys)
    assert "level_3F_mm changes at" in line and "at most 100 knots a signal" in line
    # the reader holds an empty discharge cell of a CSV at the last logged one and refuses a
    # negative one; a record made in memory meets the same check as the level
    record = read_record(RECORD)
    flow = np.array(record.flow_m3h)
    flow[7] = np.nan
    with pytest.raises(RecordError, match=r"flow_m3h is empty or outside \[0, 3.6e\+07\] m3/h "
                       r"at t = 8\.\d+ s \(1 sample"):  # fmt: skip
        write_observer_ssp(read_model_file(MODEL), dataclasses.replace(record, flow_m3h=flow),
                           tmp_path / "m.ssp", without_effects=True)  # fmt: skip
    assert not (tmp_path / "m.ssp").exists()


def _every(tmp_path: Path, k: int, source: Path = RECORD) -> Path:
    """The record with one data line in ``k`` kept, its sidecar's sample period ``k`` times
    the record's (a free test): a slower logger."""
    import json

    lines = source.read_text(encoding="utf-8").splitlines()
    out = tmp_path / f"{source.stem}_every{k}.csv"
    out.write_text("\n".join([lines[0], *lines[1::k]]) + "\n", encoding="utf-8")
    meta = json.loads(source.with_suffix(".json").read_text(encoding="utf-8"))
    meta["sample_period_s"] = k * meta["sample_period_s"]
    meta["test"] = "free"  # too few samples left for a PRBS test's checks
    out.with_suffix(".json").write_text(json.dumps(meta), encoding="utf-8")
    return out


def test_the_observer_samples_at_the_records_period(tmp_path, capsys):
    """A record logged every 9.6 s (one sample in 8 of the 1.2 s record) is observed at
    9.6 s by ``observe`` and by the package: the observer FMU steps 9.6 s, its forecast
    horizon is the default's nearest whole number of samples (6, 57.6 s), and the run equals
    ``OnlineObserver`` at that period within the observer FMU's bound
    (``test_observer_fmu.TOL``) and ``observe``'s CSV within that bound plus its printing."""
    from fmpy import read_model_description

    slow = _every(tmp_path, 8)
    out, est = tmp_path / "slow.ssp", tmp_path / "slow.csv"
    assert main(["ssp", str(MODEL), "--observe", str(slow), "--without-effects",
                 "--out", str(out)]) == 0  # fmt: skip
    assert main(["observe", str(MODEL), str(slow), "--gauge", GAUGE, "--without-effects",
                 "--out", str(est)]) == 0  # fmt: skip
    capsys.readouterr()
    with zipfile.ZipFile(out) as zf:
        zf.extractall(tmp_path / "unpacked")
    md = read_model_description(str(tmp_path / "unpacked" / OBSERVER_SOURCE))
    assert md.defaultExperiment.stepSize == "9.6"
    horizon = next(v for v in md.modelVariables if v.name == "horizon_s")
    assert float(horizon.start) == 6 * 9.6
    run = simulate_ssp(out)
    inputs = measured_inputs(read_record(slow), GAUGE)
    plant = dataclasses.replace(read_model_file(MODEL).plant, effects=())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        python = OnlineObserver(plant, sample_period_s=9.6).run(*inputs)
    observed = np.genfromtxt(est, delimiter=",", names=True)
    assert np.array_equal(run.time_s, np.arange(inputs[0].size) * 9.6)
    for name in OUTPUTS:
        got = run.columns[f"observer.{name}"]
        assert np.max(np.abs(got - python[name])) <= OBSERVER_TOL, name
        bound = OBSERVER_TOL + PRINTED_RTOL * np.abs(observed[name])
        assert np.all(np.abs(got - observed[name]) <= bound), name
    # not the 1.2 s observer on the same samples: its prediction spans another time
    fast = OnlineObserver(plant).run(*inputs)
    assert np.max(np.abs(fast["predicted_level_mm"] - python["predicted_level_mm"])) > 1.0


def test_observes_gauge_drift_rule_runs_at_the_records_period(tmp_path, capsys):
    """``observe --reference-gauges`` on a record logged every 4.8 s (Erandom60, one sample in
    four): the drift rule's slope is per second of the record (its window spans 400 samples
    of 4.8 s), as the rule run at that period gives it, to the CSV's 10 significant digits
    (it was the 1.2 s rule's, four times too steep)."""
    from gatetwin.mpc.gauge_drift import GaugeDriftMonitor

    slow = _every(tmp_path, 4, bundled_records_dir() / "Erandom60.csv")
    est = tmp_path / "drift.csv"
    assert main(["observe", str(MODEL), str(slow), "--gauge", GAUGE, "--without-effects",
                 "--reference-gauges", "2E", "--out", str(est)]) == 0  # fmt: skip
    capsys.readouterr()
    record = read_record(slow)
    rule = GaugeDriftMonitor(sample_period_s=4.8).run(
        measured_inputs(record, GAUGE)[0], [measured_inputs(record, "2E")[0]]
    )
    got = np.genfromtxt(est, delimiter=",", names=True)["gauge_slope_mm_per_s"]
    expected = rule["gauge_slope_mm_per_s"]
    full = np.isfinite(expected)  # NaN until the window is full
    assert np.array_equal(np.isfinite(got), full) and 0 < full.sum() < full.size
    assert np.ptp(expected[full]) > 0.0
    assert np.all(np.abs(got - expected)[full] <= 1e-12 + PRINTED_RTOL * np.abs(expected[full]))


def test_export_observer_samples_at_the_model_files_period(tmp_path, capsys):
    """``export-observer`` takes the sample period the model file states (the records'
    ``validity.sample_period_s``, as ``export-controller`` does): a model identified on 10 s
    records gets an observer that steps 10 s."""
    import json

    from fmpy import read_model_description

    doc = json.loads(MODEL.read_text(encoding="utf-8"))
    doc["validity"]["sample_period_s"] = 10.0
    model = tmp_path / "fopdt_3F.json"
    model.write_text(json.dumps(doc), encoding="utf-8")
    fmu = tmp_path / "observer.fmu"
    assert main(["export-observer", str(model), "--without-effects", "--out", str(fmu)]) == 0
    capsys.readouterr()
    md = read_model_description(str(fmu))
    assert md.defaultExperiment.stepSize == "10.0"
    assert float(next(v for v in md.modelVariables if v.name == "horizon_s").start) == 60.0


def test_a_physical_model_gets_the_envelope_observer(tmp_path):
    """As ``observe`` by default, a physical model is observed by the envelope observer (its
    slow rule's ``slow_cusum`` logged too), to the observer FMU's bound of ``OnlineObserver``
    (``test_observer_fmu.TOL``)."""
    model = read_model_file(ROOT / "models" / "physical_3F.json")
    out = write_observer_ssp(model, RECORD, tmp_path / "physical.ssp", without_effects=True)
    run = simulate_ssp(out)
    inputs = measured_inputs(read_record(RECORD), GAUGE)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        python = OnlineObserver(dataclasses.replace(model.plant, effects=())).run(*inputs)
    assert python.keys() == {*OUTPUTS, "slow_cusum"}
    for name, values in python.items():
        assert np.max(np.abs(run.columns[f"observer.{name}"] - values)) <= OBSERVER_TOL, name
    assert np.ptp(run.columns["observer.slow_cusum"]) > 0.0
    # the system declares the observer's outputs as its FMU describes them
    from xml.etree import ElementTree as ET

    from fmpy import read_model_description

    fmu = tmp_path / "observer.fmu"
    fmu.write_bytes(_read(out, OBSERVER_SOURCE))
    described = [v.name for v in read_model_description(str(fmu)).modelVariables
                 if v.causality == "output"]  # fmt: skip
    ssd = ET.fromstring(_read(out, SSD_NAME))
    observer = next(e for e in ssd.iter() if e.tag.endswith("}Component")
                    and e.get("name") == "observer")  # fmt: skip
    declared = [c.get("name") for c in observer.iter() if c.tag.endswith("}Connector")
                and c.get("kind") == "output"]  # fmt: skip
    assert declared == described and "slow_cusum" in declared


def test_simulate_ssp_counts_the_anomaly_flag_rises_that_observe_counts(tmp_path, capsys):
    """The count ``simulate-ssp`` prints for an observer package is ``observe``'s on the same
    record, on one where the flag does rise: the level shifted by +30 mm from sample 400 on
    (a gauge that jumped; ~40 innovation standard deviations of this record)."""
    import re

    def shifted(i, row):
        if i >= 400 and row[f"level_{GAUGE}_mm"]:
            row[f"level_{GAUGE}_mm"] = repr(float(row[f"level_{GAUGE}_mm"]) + 30.0)
        return row

    record = _record_copy(tmp_path, "jumped", shifted)
    package, csv = tmp_path / "jumped.ssp", tmp_path / "result.csv"
    assert main(["ssp", str(MODEL), "--observe", str(record), "--without-effects",
                 "--out", str(package)]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["simulate-ssp", str(package), "--out", str(csv)]) == 0
    ours = re.search(r"anomaly flag rose (\d+) times", capsys.readouterr().out)
    assert main(["observe", str(MODEL), str(record), "--gauge", GAUGE, "--without-effects",
                 "--out", str(tmp_path / "est.csv")]) == 0  # fmt: skip
    theirs = re.search(r"anomaly flag rose (\d+) times", capsys.readouterr().out)
    assert ours and theirs and int(theirs[1]) >= 1
    assert int(ours[1]) == int(theirs[1])
