"""Diagnosis parts: the grid rendering equals the reference, the record as the diagnosis reads
it, noise floor and windows, signatures, materiality, selection, the workflow's outputs (model
file, FMUs re-validated, figure) and the ``gatetwin diagnose`` command."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from diagnose_cases import draw_case
from effect_cases import EXAMPLES
from fmu_support import arx_plant, compiler, fopdt_plant
from gatetwin.bundled import bundled_records_dir
from gatetwin.cli import main
from gatetwin.diagnosis import DiagnosisSettings, diagnose_record
from gatetwin.diagnosis.baseline import identify_baseline
from gatetwin.diagnosis.candidates import CANDIDATES, Context
from gatetwin.diagnosis.data import commanded_opening, prepare
from gatetwin.diagnosis.grid_sim import grid_inputs, simulate_grid
from gatetwin.diagnosis.noise import noise_floor, windows
from gatetwin.diagnosis.select import CandidateResult, choose
from gatetwin.diagnosis.signatures import signatures
from gatetwin.errors import IdentificationError
from gatetwin.modelfile import model_document, read_model_file, write_model_file
from gatetwin.plant.effects import KINDS, effect_dict
from gatetwin.plant.simulate import simulate
from gatetwin.records import read_record, record_from_arrays

REQUIRED_KEYS = {"named_effect", "candidates", "rmse_before_mm", "rmse_after_mm", "windows",
                 "noise_floor_mm", "gap_mm", "rmse_mm"}  # fmt: skip


def _prepared(seed: int, effect: str, tmp_path: Path):
    case = draw_case(seed, effect)
    record = read_record(case.write(tmp_path))
    return case, record, prepare(record, "3F")


@pytest.mark.parametrize(("family", "kind"), [
    (family, kind) for family in ("fopdt", "arx") for kind in (*KINDS, "none")
    if family == "fopdt" or kind != "flow_dependent_gain"
])  # fmt: skip
def test_grid_rendering_equals_the_reference_simulation(family, kind):
    base = fopdt_plant() if family == "fopdt" else arx_plant()
    effects = () if kind == "none" else (effect_dict(kind, **EXAMPLES[kind]),)
    plant = replace(base, effects=effects)
    rng = np.random.default_rng(2)
    t = np.arange(900) * 1.2
    opening = np.repeat(20.0 + rng.integers(-8, 9, 45), 20)[: t.size].astype(float)
    lo, hi = plant.schedule.flow_range_m3h
    flow = np.repeat(rng.uniform(lo, hi, 15), 60)[: t.size]
    reference = simulate(plant, t, opening, flow)
    fast = simulate_grid(plant, grid_inputs(t, opening, flow, 1.2))
    assert np.max(np.abs(fast - reference)) < 1e-9


def test_grid_inputs_hold_across_gaps_and_refuse_crowded_samples():
    t = np.array([0.0, 1.21, 2.39, 6.0, 7.2])
    grid = grid_inputs(t, np.arange(5.0), np.full(5, 50.0), 1.2)
    assert grid.sample_point.tolist() == [0, 1, 2, 5, 6]
    assert grid.command_mm.tolist() == [0.0, 1.0, 2.0, 2.0, 2.0, 3.0]
    with pytest.raises(IdentificationError, match="two samples fall on one point"):
        grid_inputs(np.array([0.0, 0.5, 1.2]), np.zeros(3), np.zeros(3), 1.2)


def test_the_command_jumps_to_the_next_hold_at_the_first_open_sample():
    n = 120
    opening = np.full(n, 20.0)
    opening[60:] = 25.0
    hold = np.ones(n, dtype=bool)
    hold[60:64] = False
    opening[60:64] = np.nan
    record = record_from_arrays(np.arange(n) * 1.2, opening, hold, np.full(n, 50.0),
                                {"3F": np.full(n, 300.0)}, test="step")  # fmt: skip
    command = commanded_opening(record)
    assert command[59] == 20.0 and np.all(command[60:] == 25.0)
    data = prepare(record, "3F")
    (move,) = data.moves
    assert (move.index, move.open_samples, move.delta_mm, move.reversal) == (60, 4, 5.0, False)


def test_noise_floor_and_windows_on_a_clean_record(tmp_path):
    case, record, data = _prepared(1000, "none", tmp_path)
    nf = noise_floor(data)
    assert nf.sigma_mm == pytest.approx(case.sigma_mm, rel=0.15)
    assert nf.n_stretches >= 8
    residual = data.level_mm - simulate(case.truth, data.time_s, data.command_mm, data.flow_m3h)
    assert windows(data.time_s, residual, nf.sigma_mm, 1.2) == []
    residual[400:440] += 6.0 * case.sigma_mm
    (window,) = windows(data.time_s, residual, nf.sigma_mm, 1.2)
    assert window["t_start_s"] <= data.time_s[400] and window["t_end_s"] >= data.time_s[439]
    assert window["rms_mm"] > 3.0 * case.sigma_mm


@pytest.mark.parametrize(("effect", "name", "rel"), [
    ("seiche", "period_s", 0.3),  # the spectral peak
    ("actuator_rate_limit", "rate_mm_per_s", 0.3),  # the logger's open durations
    ("sensor_drift", "rate_mm_per_s", 1.0),  # the baseline absorbs part of a trend: sign only
])  # fmt: skip
def test_signatures_point_at_the_hidden_effect(tmp_path, effect, name, rel):
    case, record, data = _prepared(1003, effect, tmp_path)
    sig = signatures(data, identify_baseline(record, data).refit)[effect]
    assert sig.suggests
    assert sig.estimate[name] == pytest.approx(case.params[name], rel=rel)
    assert np.sign(sig.estimate[name]) == np.sign(case.params[name])


class _FakeFit:
    def __init__(self, **values: float) -> None:
        self.values = values

    def value(self, name: str) -> float:
        return self.values[name]


def test_physically_immaterial_fits_count_as_none(tmp_path):
    _, record, data = _prepared(1000, "none", tmp_path)
    base = identify_baseline(record, data)
    ctx = Context(data, base.plant, base.refit, 0.5, {})
    by_kind = {c.kind: c for c in CANDIDATES}
    move = ctx.typical_move_mm
    assert "less than one sample" in by_kind["actuator_rate_limit"].immaterial(
        _FakeFit(rate_mm_per_s=move / 0.5), ctx
    )
    assert "quarter sample" in by_kind["sensor_lag"].immaterial(_FakeFit(time_constant_s=0.2), ctx)
    assert "below the noise floor" in by_kind["seiche"].immaterial(
        _FakeFit(period_s=10.0, decay_time_s=20.0, amplitude_mm_per_mm=0.4 / move), ctx
    )
    assert "below the noise floor" in by_kind["sensor_drift"].immaterial(
        _FakeFit(rate_mm_per_s=1e-5), ctx
    )
    assert by_kind["sensor_lag"].immaterial(_FakeFit(time_constant_s=5.0), ctx) == ""


def test_the_winner_must_be_significant_and_material():
    assert choose([CandidateResult("seiche", True)]) is None
    fit = object()
    strong = CandidateResult("seiche", True, fit=fit, score=50.0, significant=True)  # type: ignore[arg-type]
    weak = CandidateResult("sensor_lag", True, fit=fit, score=20.0, significant=True)  # type: ignore[arg-type]
    immaterial = CandidateResult(
        "sensor_drift", True, fit=fit, score=90.0, significant=True, immaterial="too small"
    )  # type: ignore[arg-type]
    assert choose([weak, strong, immaterial]) is strong


@pytest.fixture(scope="module")
def backlash_diagnosis(tmp_path_factory):
    if compiler() is None:
        pytest.skip("no C compiler (cc/gcc) on PATH")
    folder = tmp_path_factory.mktemp("diagnose")
    case = draw_case(1002, "actuator_backlash")
    result = diagnose_record(case.write(folder), plots_dir=folder / "plots",
                             fmu_dir=folder / "fmus")  # fmt: skip
    return case, result


def test_the_workflow_names_adds_exports_and_revalidates(backlash_diagnosis):
    case, result = backlash_diagnosis
    assert REQUIRED_KEYS <= set(result)
    json.dumps(result, allow_nan=False)
    assert result["named_effect"] == "actuator_backlash"
    assert result["rmse_after_mm"] < result["rmse_before_mm"]
    assert result["gap_mm"]["after"]["holdout"] < 0.5 * result["gap_mm"]["before"]["holdout"]
    for row in result["candidates"]:
        assert {"effect", "params", "rmse_mm", "score", "significant"} <= set(row)
    model = read_model_file(result["augmented_model"])
    (block,) = model.plant.effects
    assert block["kind"] == "actuator_backlash"
    assert block["deadband_mm"] == pytest.approx(case.params["deadband_mm"], rel=0.25)
    assert model.content["diagnosis"]["parameters"]["deadband_mm"]["se"] > 0
    assert {f["backend"] for f in result["fmus"]} == {"c", "python"}
    for fmu in result["fmus"]:
        assert fmu["fmpy_validation_findings"] == []
        assert fmu["max_abs_diff_from_reference_mm"] <= 1e-9
        assert fmu["rmse_mm"] == pytest.approx(result["rmse_after_mm"], abs=1e-6)
    assert Path(result["plots"][0]).read_bytes()[:4] == b"\x89PNG"
    # the augmented model controls: its MPC compensates the backlash and holds the set-point
    # (a reversal of the plan under MpcSettings.backlash_hold_mm = 1e-6 mm is not made:
    # |K| x 1e-6 ~ 2e-5 mm of steady error; 1e-3 mm leaves room for the QP's tolerance),
    # and integrates the step's error faster than the MPC blind to the block
    control = result["control"]
    assert abs(control["augmented_mpc"]["final_error_mm"]) <= 1e-3
    assert control["augmented_mpc"]["iae"] < control["blind_mpc"]["iae"]


def test_a_model_file_baseline(tmp_path):
    case = draw_case(1007, "sensor_lag")
    bare = replace(case.truth, effects=())
    lo, hi = bare.schedule.flow_range_m3h
    doc = model_document("truth_3F", bare, description="truth without its lag", conditions=[],
                         rating={}, provenance={"method": "test", "records": []},
                         operating_openings_mm=[20.0, 20.0], opening_band_mm=20.0)  # fmt: skip
    model = write_model_file(tmp_path / "truth_3F.json", doc)
    result = diagnose_record(case.write(tmp_path), model)
    assert result["baseline"]["source"].startswith("model file")
    assert result["named_effect"] == "sensor_lag"


def test_reconstructed_input_offers_no_rate_limit(tmp_path):
    case = draw_case(1000, "none")
    settings = DiagnosisSettings(input="reconstructed")
    result = diagnose_record(case.write(tmp_path), settings=settings)
    (row,) = [c for c in result["candidates"] if c["effect"] == "actuator_rate_limit"]
    assert "reconstructed" in row["not_fitted"]
    assert result["input"] == "reconstructed"


def test_a_prbs_record_is_diagnosed_against_an_arx_baseline():
    result = diagnose_record(bundled_records_dir() / "D.csv")
    assert result["test"] == "prbs" and result["baseline"]["plant"]["kind"] == "arx"
    assert result["named_effect"] in {"none", *KINDS}
    assert result["rmse_after_mm"] <= result["rmse_before_mm"] + 1e-12
    assert math.isfinite(result["noise_floor_mm"])


def test_diagnose_command_writes_json_and_refuses_bad_input(tmp_path, capsys):
    record = draw_case(1004, "flow_dependent_gain").write(tmp_path)
    out = tmp_path / "out" / "diag.json"
    args = ["diagnose", str(record), "--json", str(out), "--fmu-dir", str(tmp_path / "f")]
    assert main(args) == 0
    result = json.loads(out.read_text())
    assert result["named_effect"] == "flow_dependent_gain"
    assert "named effect flow_dependent_gain" in capsys.readouterr().out
    assert main(["diagnose", str(tmp_path / "missing.csv"), "--json", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("gatetwin: error:") and err.count("\n") == 1


MODELS = Path(__file__).resolve().parents[2] / "models"


# ~20 s; the default run keeps the model-file baseline (test_a_model_file_baseline)
@pytest.mark.slow
def test_a_record_where_only_the_discharge_changes_is_diagnosed_against_a_model():
    """EflowLow: Q 30 -> 50 -> 35 m³/h with the gate fixed. Against fopdt_3F's local form
    (the level jumps with level_ref(Q)), the named effect is a discharge effect and it closes
    most of the gap; the envelope form itself already follows the inflow."""
    record = bundled_records_dir() / "EflowLow.csv"
    result = diagnose_record(record, MODELS / "fopdt_3F.json")
    assert "local form" in result["baseline"]["source"]
    assert result["named_effect"] in {"inflow_disturbance", "flow_dependent_gain"}
    assert result["gap_reduction"] >= 0.5
    skipped = {c["effect"]: c.get("not_fitted", "") for c in result["candidates"]}
    assert "never moves" in skipped["actuator_rate_limit"]
    with pytest.raises(IdentificationError, match="--model"):
        diagnose_record(record)


def test_a_record_where_nothing_changes_is_refused():
    n = 200
    level = 200.0 + np.random.default_rng(1).normal(0, 0.5, n)
    rec = record_from_arrays(np.arange(n) * 1.2, np.full(n, 25.0), np.full(n, True),
                             np.full(n, 40.0), {"3F": level}, sample_period_s=1.2)  # fmt: skip
    with pytest.raises(IdentificationError, match="neither the opening nor the discharge"):
        prepare(rec, "3F")


@pytest.mark.parametrize("ts", [0.1, 1.2, 10.0, 60.0, 600.0])
def test_the_seiche_candidates_bounds_hold_a_range_at_any_sample_period(ts) -> None:
    """A 60 s logger met a period range of [120 s, 120 s] (two samples up to a fixed two
    minutes) and least squares refused it: the longest period searched grows with the
    sample period, so each bound keeps its lower end below its upper and the spectrum's band
    (2.5 samples to the longest period) holds bins."""
    from types import SimpleNamespace

    from gatetwin.diagnosis.candidates.seiche import SeicheCandidate
    from gatetwin.diagnosis.signatures import seiche_longest_period_s

    ctx = SimpleNamespace(data=SimpleNamespace(sample_period_s=ts))
    lower, upper = SeicheCandidate().bounds(ctx)
    assert all(lo < hi for lo, hi in zip(lower, upper, strict=True)), (lower, upper)
    assert seiche_longest_period_s(ts) >= 2.5 * ts * 4  # a band of a few bins at least
