"""The twin judged on records it has never seen: fresh flume scenarios inside the envelope
(other discharges, other seeds, gate moves and inflow steps), every model of the repository.

Criterion of the envelope work: free-run fit >= 90 %, or within 5 points of the record's
noise-floor fit where that is lower, with |bias| <= 3 mm. The models run in the Python
reference simulator, which the FMUs of both backends equal within 1e-9 mm
(tests/fmu/test_fmu_bundled.py).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from gatetwin.flume.envelope import flow_steps_scenario, moves_scenario, random_moves_scenario
from gatetwin.flume.experiments import run_scenario
from gatetwin.identification.suite import free_run_fit
from gatetwin.modelfile import read_model_file
from gatetwin.noise import record_noise_floor
from gatetwin.records import read_record
from gatetwin.validation import noise_floor_fit_percent

MODELS = sorted((Path(__file__).resolve().parents[2] / "models").glob("*_*.json"))
SCENARIOS = [
    moves_scenario("Umoves50", 50.0, [20.0, 30.0, 40.0, 30.0, 20.0], 300.0, 903),
    flow_steps_scenario("Uflow", 35.0, [40.0, 60.0, 45.0, 70.0], 300.0, 904),
    random_moves_scenario("Urandom45", 45.0, 901),
    random_moves_scenario("Urandom70", 70.0, 902),
]


def _check(scenario, tmp_path: Path) -> list[str]:
    record = read_record(run_scenario(scenario).write(tmp_path / f"{scenario.name}.csv"))
    failures = []
    for path in MODELS:
        model = read_model_file(path)
        gauge = model.plant.gauge
        got = free_run_fit(model.plant, record, gauge, grid=True)
        sigma = record_noise_floor(record, gauge).sigma_mm
        floor, _ = noise_floor_fit_percent(sigma, record.levels_mm[gauge])
        fit_ok = got["fit_percent"] >= min(90.0, floor - 5.0)
        if not (fit_ok and abs(got["bias_mm"]) <= 3.0):
            failures.append(f"{model.name} on {scenario.name}: fit {got['fit_percent']:.1f} % "
                            f"(floor {floor:.1f} %), bias {got['bias_mm']:+.2f} mm")  # fmt: skip
    return failures


@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda s: s.name)
def test_every_model_holds_on_an_unseen_envelope_record(scenario, tmp_path):
    assert _check(scenario, tmp_path) == []
