"""The discrete model across the envelope: an ARX on the gate law's steady level whose pole
follows the pool's time constant (``ArxPlant`` with ``envelope``)."""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np
import pytest

from gatetwin.bundled import bundled_records_dir
from gatetwin.errors import ModelFileError
from gatetwin.identification.arx_envelope import envelope_arx, fit_condition
from gatetwin.identification.preprocess import reconstructed_opening
from gatetwin.modelfile import read_model_file
from gatetwin.plant.model import envelope_point, plant_from_dict, plant_to_dict
from gatetwin.plant.simulate import simulate
from gatetwin.records import read_record, record_from_arrays

MODELS = Path(__file__).resolve().parents[2] / "models"


@pytest.fixture(scope="module")
def physical():
    plant = read_model_file(MODELS / "physical_3F.json").plant
    return dataclasses.replace(plant, effects=())  # no seiche: the ARX's own dynamics alone


def _run(plant, t, e, q):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return simulate(plant, t, e, q)


def _known(physical, a1=0.97, b=(0.07, -0.04)):
    b = np.array(b) * (1.0 - a1) / sum(b)  # unit gain
    cond = dataclasses.replace(_condition_template(), a1=a1, b=tuple(b), time_constant_ref_s=40.0)
    return envelope_arx([cond], physical, 1.2)


def _condition_template():
    from gatetwin.identification.arx_envelope import EnvelopeArxCondition

    return EnvelopeArxCondition("X", 41.5, 35.0, 150.0, 0.97, (0.05, -0.02), 40.0, 0.0, 0.0, 0.0)


def test_a_large_move_lands_where_the_gate_law_says(physical):
    plant = _known(physical)
    t = np.arange(0.0, 1200.0, 1.2)
    e = np.where(t < 60.0, 15.0, 30.0)  # 15 -> 30 mm at Q 35
    level = _run(plant, t, e, np.full(t.size, 35.0))
    for opening, at in ((15.0, 0), (30.0, -1)):
        # the envelope's steady level; the residual of 1100 s of decay (T <= 80 s) is < 1e-5
        assert level[at] == pytest.approx(envelope_point(opening, 35.0, physical.vector)[0],
                                          abs=1e-5)  # fmt: skip


def test_the_pole_follows_the_pool_time_constant(physical):
    """After a small step the level closes on its new steady value geometrically, by the
    factor a1^(T_ref / T) with T the envelope's time constant at the new opening: slower
    where the pool is slow."""
    plant = _known(physical)
    t = np.arange(0.0, 600.0, 1.2)
    factors = []
    for opening in (20.0, 60.0):
        e = np.where(t < 12.0, opening, opening + 0.5)
        level = _run(plant, t, e, np.full(t.size, 50.0))
        final = envelope_point(opening + 0.5, 50.0, physical.vector)
        gap = final[0] - level
        k = np.searchsorted(t, 30.0)  # past the input's two lags
        expected = 0.97 ** (40.0 / final[1])
        assert gap[k + 1] / gap[k] == pytest.approx(expected, rel=1e-9), opening
        factors.append(expected)
    assert factors[0] != pytest.approx(factors[1], rel=1e-3)  # the two openings differ


def test_identification_recovers_a_known_envelope_arx(physical):
    truth = _known(physical, a1=0.965, b=(0.09, -0.05))
    rec = read_record(bundled_records_dir() / "C.csv")
    e = reconstructed_opening(rec.time_s, rec.opening_mm, rec.hold)
    t = np.arange(rec.n_samples) * rec.sample_period_s
    truth = dataclasses.replace(truth, opening_ref_mm=float(np.nanmean(rec.opening_mm)))
    y = _run(truth, t, e, rec.flow_m3h)
    synthetic = record_from_arrays(t, rec.opening_mm, rec.hold, rec.flow_m3h, {"3F": y},
                                   test="prbs", sample_period_s=rec.sample_period_s)  # fmt: skip
    cond = fit_condition("synthetic", synthetic, physical)
    # noise-free data: recovered to the optimiser's tolerance (relative steps of 1e-8)
    assert cond.a1 == pytest.approx(0.965 ** (40.0 / cond.time_constant_ref_s), abs=1e-5)
    assert cond.rmse_mm < 0.01  # a hundredth of the gauges' 0.1 mm resolution


def test_model_checks_and_round_trip(physical):
    plant = _known(physical)
    assert plant_from_dict(plant_to_dict(plant)) == plant
    with pytest.raises(ModelFileError, match="needs 0 < a1 < 1"):
        dataclasses.replace(
            plant,
            schedule=dataclasses.replace(
                plant.schedule, values={**plant.schedule.values, "a1": (1.2,)}
            ),
        )
    with pytest.raises(ModelFileError, match="schedule lacks column"):
        values = {k: v for k, v in plant.schedule.values.items() if k != "time_constant_ref_s"}
        dataclasses.replace(plant, schedule=dataclasses.replace(plant.schedule, values=values))


def test_the_bundled_arx_holds_across_the_envelope():
    plant = read_model_file(MODELS / "arx_3F.json").plant
    assert plant.envelope is not None and plant.na == 1
