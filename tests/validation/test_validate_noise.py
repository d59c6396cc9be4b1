"""The noise floor: the level noise SD from steady holds, and the fit a perfect model can reach.

Synthetic record: the FOPDT test plant (gauge 3F, K = -12 mm/mm, T = 55 s, L = 7 s at
Q = 55 m³/h) driven through 20 -> 25 -> 20 -> 25 mm openings, four holds of
:data:`HOLD_SAMPLES` samples at 1.2 s with three ``open`` samples per move. Its noise-free
level is the FMU's own free-run output on those inputs (so the FMU is a perfect model of it);
white Gaussian noise of SD :data:`SIGMA_MM` is added with a fixed seed.

Tolerances, both four standard errors (a false failure is a 1-in-15 000 event for a fresh
seed; the seed is fixed, so the test is deterministic):

* the estimate is a pooled SD with ``dof`` degrees of freedom (samples minus 3 quadratic
  coefficients per stretch), so ``sigma_hat / sigma`` has relative SD ``1 / sqrt(2 dof)``;
  the transient left in the last half of a 600-sample hold (``exp(-360 s / 55 s)`` of a
  60 mm step, under 0.1 mm, and mostly taken out by the quadratic) biases it by far less;
* a perfect model's fit misses the floor ``100 (1 - sigma_hat / s)`` by
  ``100 (sigma_hat - rms(noise)) / s``: the two SD estimates' errors, relative SDs
  ``1 / sqrt(2 dof)`` and ``1 / sqrt(2 n)``, independent enough to add in quadrature.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from fmu_support import compiler, fopdt_plant
from gatetwin.cli import main
from gatetwin.fmu import export_fmu
from gatetwin.noise import record_noise_floor
from gatetwin.plant import FopdtPlant, Schedule
from gatetwin.records import Record, record_from_arrays
from gatetwin.validation import (
    Threshold,
    free_run_metrics,
    matrix_cells,
    matrix_markdown,
    noise_floor_fit_percent,
    parse_thresholds,
    validate_fmu,
)

BACKEND = "c" if compiler() else "python"
SIGMA_MM = 1.5
HOLD_SAMPLES, OPEN_SAMPLES, PERIOD_S, FLOW_M3H = 600, 3, 1.2, 55.0
OPENINGS_MM = (20.0, 25.0, 20.0, 25.0)
SEED = 20240611


def _inputs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time, logged opening (NaN while moving) and hold flag of the synthetic record."""
    opening, hold = [], []
    for k, e in enumerate(OPENINGS_MM):
        if k:
            opening += [math.nan] * OPEN_SAMPLES
            hold += [False] * OPEN_SAMPLES
        opening += [e] * HOLD_SAMPLES
        hold += [True] * HOLD_SAMPLES
    t = PERIOD_S * np.arange(len(opening))
    return t, np.array(opening), np.array(hold)


def _record(level_mm: np.ndarray, name: str) -> Record:
    t, opening, hold = _inputs()
    return record_from_arrays(t, opening, hold, np.full(t.size, FLOW_M3H), {"3F": level_mm},
                              sample_period_s=PERIOD_S, test="step", path=name)  # fmt: skip


@pytest.fixture(scope="module")
def perfect(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """The FMU, its noise-free output on the inputs, and a record of it with noise."""
    folder = tmp_path_factory.mktemp("noise")
    fmu = export_fmu(fopdt_plant(), folder / "perfect.fmu", backend=BACKEND,
                     model_name="perfect", provenance={"test": 1})  # fmt: skip
    t, *_ = _inputs()
    placeholder = _record(np.linspace(200.0, 201.0, t.size), "placeholder.csv")
    truth = validate_fmu(fmu, [placeholder]).records[0].trace.simulated_mm
    noise = np.random.default_rng(SEED).normal(0.0, SIGMA_MM, t.size)
    return {"fmu": fmu, "truth": truth, "noise": noise,
            "record": _record(truth + noise, "noisy.csv"), "folder": folder}  # fmt: skip


def _dof(n_samples: int, n_stretches: int) -> int:
    return n_samples - 3 * n_stretches


def test_noise_sd_of_a_synthetic_record_is_recovered(perfect: dict[str, object]) -> None:
    truth = perfect["truth"]
    assert np.ptp(truth) > 50.0, "the steps must move the level well beyond the noise"
    floor = record_noise_floor(perfect["record"], "3F")
    assert floor.n_stretches == len(OPENINGS_MM) and "quadratic" in floor.method
    dof = _dof(floor.n_samples, floor.n_stretches)
    assert dof > 1000
    assert abs(floor.sigma_mm / SIGMA_MM - 1.0) <= 4.0 / math.sqrt(2.0 * dof)
    doubled = record_noise_floor(_record(truth + 2.0 * perfect["noise"], "noisy2.csv"), "3F")
    assert doubled.sigma_mm == pytest.approx(2.0 * floor.sigma_mm, rel=0.02)
    clean = record_noise_floor(_record(truth, "clean.csv"), "3F")
    assert clean.sigma_mm < 0.05 * SIGMA_MM


def test_a_perfect_model_scores_at_the_floor(perfect: dict[str, object]) -> None:
    rec = validate_fmu(perfect["fmu"], [perfect["record"]]).records[0]
    floor = rec.noise_floor_dict()
    assert floor["fit_percent"] == pytest.approx(rec.noise_floor_fit_percent)
    s = float(np.std(perfect["truth"] + perfect["noise"]))
    assert floor["level_sd_mm"] == pytest.approx(s)
    assert floor["fit_percent"] == pytest.approx(100.0 * (1.0 - floor["sigma_mm"] / s))
    dof, n = _dof(floor["n_samples"], floor["n_stretches"]), rec.metrics.n
    tolerance = 100.0 * SIGMA_MM / s * 4.0 * math.sqrt(1.0 / (2 * dof) + 1.0 / (2 * n))
    assert abs(rec.fit_vs_floor) <= tolerance
    assert rec.to_dict()["fit_vs_floor"] == pytest.approx(rec.fit_vs_floor)
    assert rec.metrics.fit_percent < 100.0 - tolerance, "the noise must cost fit"


def test_fit_vs_floor_threshold_passes_perfect_and_fails_a_wrong_model(
    perfect: dict[str, object], tmp_path: Path
) -> None:
    limit = (Threshold("fit_vs_floor", -1.0),)
    assert validate_fmu(perfect["fmu"], [perfect["record"]], thresholds=limit).passed
    slow = FopdtPlant("3F", 20.0, Schedule((30.0, 55.0, 85.0), {
        **fopdt_plant().schedule.values, "time_constant_s": (142.0, 110.0, 84.0)}))  # fmt: skip
    fmu = export_fmu(slow, tmp_path / "slow.fmu", backend=BACKEND, model_name="slow",
                     provenance={})  # fmt: skip
    result = validate_fmu(fmu, [perfect["record"]], thresholds=limit)
    rec = result.records[0]
    assert not result.passed and rec.fit_vs_floor < -1.0
    assert rec.checks[0].value == pytest.approx(rec.fit_vs_floor)
    cell = matrix_cells(result)[0]
    assert cell["fit_vs_floor"] == pytest.approx(rec.fit_vs_floor)
    fit, floor = cell["fit_percent"], cell["noise_floor_fit_percent"]
    assert f"| {fit:.1f} / {floor:.1f} |" in matrix_markdown([cell])


def test_cli_fit_vs_floor_and_json_noise_floor(
    perfect: dict[str, object], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from gatetwin.records import read_record

    bundled = Path(__file__).resolve().parents[2] / "src" / "gatetwin" / "data" / "records"
    out = tmp_path / "v.json"
    args = ["validate", str(perfect["fmu"]), str(bundled / "Q55.csv"), "--json", str(out)]
    assert main([*args, "--fail-under", "fit_vs_floor=-100000"]) == 0
    doc = json.loads(out.read_text(encoding="utf-8"))["records"][0]
    assert set(doc["noise_floor"]) >= {"sigma_mm", "fit_percent", "method"}
    expected = record_noise_floor(read_record(bundled / "Q55.csv"), "3F")
    assert doc["noise_floor"]["sigma_mm"] == pytest.approx(expected.sigma_mm)
    assert doc["fit_vs_floor"] == pytest.approx(
        doc["metrics"]["fit_percent"] - doc["noise_floor"]["fit_percent"]
    )
    assert main([*args, "--fail-under", f"fit_vs_floor={doc['fit_vs_floor'] + 1:.6f}"]) == 1
    assert "fit_vs_floor" in capsys.readouterr().out


def test_floor_formula_and_threshold_side() -> None:
    y = np.array([0.0, 20.0, np.nan, 0.0, 20.0])  # SD 10 over the finite samples
    assert noise_floor_fit_percent(1.0, y) == pytest.approx((90.0, 10.0))
    assert math.isnan(noise_floor_fit_percent(math.nan, y)[0])
    assert math.isnan(noise_floor_fit_percent(1.0, np.full(4, 3.0))[0])
    # the floor is the fit of the noise-free truth: y = x + w, y_hat = x
    rng = np.random.default_rng(7)
    x = 30.0 * np.sin(np.linspace(0, 20, 20000))
    y = x + rng.normal(0.0, 2.0, x.size)
    floor, _ = noise_floor_fit_percent(2.0, y)
    # 4 standard errors: 100 * (2 / s) * 4 / sqrt(2 n) = 0.19 points
    assert free_run_metrics(y, x).fit_percent == pytest.approx(floor, abs=0.2)
    (under,) = parse_thresholds(["fit_vs_floor=-5"])
    assert under.fails_when == "below" and under.text == "fit_vs_floor >= -5"
    with pytest.raises(ValueError, match="use --fail-under fit_vs_floor=-5"):
        parse_thresholds([], ["fit_vs_floor=-5"])


def test_a_records_floor_is_computed_once_and_never_served_for_other_content():
    """The floor is kept per record content (validating many FMUs asks for the same records'
    floors again and again): a second read of the file gets the kept result, while a record
    whose levels differ, or another gauge, gets its own."""
    from dataclasses import replace

    from gatetwin.bundled import bundled_records_dir
    from gatetwin.records import read_record

    path = bundled_records_dir() / "A.csv"
    first, again = read_record(path), read_record(path)
    assert record_noise_floor(again, "3F") is record_noise_floor(first, "3F")
    doubled = 2.0 * np.asarray(first.levels_mm["3F"])  # twice the noise around the holds
    other = replace(first, levels_mm={**first.levels_mm, "3F": doubled})
    changed = record_noise_floor(other, "3F")
    # the floor scales with the level (quadratic fits, scale-free correlations): round-off
    assert changed.sigma_mm == pytest.approx(2 * record_noise_floor(first, "3F").sigma_mm, rel=1e-6)
    assert record_noise_floor(first, "2E") != record_noise_floor(first, "3F")
