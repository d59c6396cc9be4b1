"""Effect blocks in the Python reference: checks, known responses, step-size independence,
and the MPC renderings (state-spaces, constraint, inverse) against the reference."""

from __future__ import annotations

import ast
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from effect_cases import EXAMPLES
from fmu_support import arx_plant, fopdt_plant
from gatetwin.errors import ModelFileError
from gatetwin.plant import blocks
from gatetwin.plant.effects import (
    KINDS,
    ActuatorBacklash,
    ActuatorRateLimit,
    OpeningNonlinearity,
    effect_dict,
    parse_effects,
)
from gatetwin.plant.model import FopdtPlant, Schedule, plant_from_dict, plant_to_dict
from gatetwin.plant.simulate import simulate


def plain_plant(gain=-12.0, tau=50.0, delay=2.0) -> FopdtPlant:
    values = {"gain_mm_per_mm": (gain,) * 2, "time_constant_s": (tau,) * 2,
              "dead_time_s": (delay,) * 2, "level_ref_mm": (250.0,) * 2}  # fmt: skip
    return FopdtPlant("3F", 20.0, Schedule((0.0, 200.0), values))


def with_effects(plant, *kinds, **overrides):
    effects = tuple(effect_dict(k, **{**EXAMPLES[k], **overrides.get(k, {})}) for k in kinds)
    return replace(plant, effects=effects)


def test_every_kind_has_an_example_and_round_trips_through_the_model_file():
    assert set(EXAMPLES) == set(KINDS)
    plant = with_effects(fopdt_plant(), *reversed(KINDS))
    assert [e["kind"] for e in plant.effects] == list(KINDS)  # stored in evaluation order
    assert plant.effects[0]["substep_s"] == 0.1  # default filled in
    assert plant_from_dict(plant_to_dict(plant)) == plant


@pytest.mark.parametrize(
    ("effects", "message"),
    [
        (({"kind": "wobble"},), "unknown kind 'wobble'"),
        (({"kind": "seiche", "period_s": 5.0, "decay_time_s": 9.0},), "amplitude_mm_per_mm miss"),
        (({"kind": "sensor_lag", "time_constant_s": 0.0},), r"time_constant_s = 0.0 must be > 0"),
        (({"kind": "sensor_lag", "time_constant_s": float("nan")},), "must be finite"),
        (({"kind": "sensor_lag", "time_constant_s": 1.0, "gain": 2},), "unknown parameter"),
        (({"kind": "sensor_drift", "rate_mm_per_s": 0.1},) * 2, "given twice"),
        (({"kind": "actuator_backlash", "deadband_mm": "wide"},), "must be a number"),
        (("seiche",), "must be an object"),
    ],
)
def test_bad_effects_are_refused_with_a_clear_message(effects, message):
    with pytest.raises(ModelFileError, match=message):
        replace(plain_plant(), effects=effects)


def test_flow_dependent_gain_is_refused_for_arx():
    with pytest.raises(ModelFileError, match="applies to fopdt plants, not arx"):
        with_effects(arx_plant(), "flow_dependent_gain")


def test_blocks_module_uses_the_standard_library_only():
    """The pythonfmu slave embeds gatetwin/plant/blocks.py verbatim."""
    tree = ast.parse(Path(blocks.__file__).read_text())
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    for node in (n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)):
        imported |= {f"{node.module}.{a.name}" for a in node.names}
    allowed = {"math", "__future__.annotations"}
    assert imported == allowed


def _run(plant, times, opening, flow=None):
    flow = np.full(len(times), 50.0) if flow is None else flow
    return simulate(plant, np.asarray(times, float), np.asarray(opening, float), flow)


def test_rate_limited_gate_follows_a_ramp_sampled_on_its_grid():
    plant = with_effects(plain_plant(delay=0.0, tau=1e-3), "actuator_rate_limit")  # level = K u
    t = np.arange(0.0, 30.0, 0.1)
    opening = np.where(t >= 1.0, 25.0, 20.0)
    level = _run(plant, t, opening)
    # the gate leaves 20 mm at t = 1 s and reaches 25 mm 10 s later (0.5 mm/s)
    gate = 20.0 + np.clip((t - 1.0) * 0.5, 0.0, 5.0)
    expected = 250.0 - 12.0 * (np.concatenate([[20.0], gate[:-1]]) - 20.0)
    assert np.allclose(level, expected, atol=1e-6 * 60)


def test_backlash_loses_the_band_on_reversal_and_half_of_it_on_the_first_move():
    plant = with_effects(plain_plant(delay=0.0, tau=1e-3), "actuator_backlash")
    t = np.arange(0.0, 40.0, 1.0)
    opening = np.select([t < 10, t < 20, t < 30], [20.0, 25.0, 22.0], 26.0)
    level = _run(plant, t, opening)
    gate = (250.0 - level) / 12.0 + 20.0
    assert gate[15] == pytest.approx(24.25)  # first move: half band lost
    assert gate[25] == pytest.approx(22.75)  # reversal: 3 mm command, gate moves 1.5 mm
    assert gate[35] == pytest.approx(25.25)  # reversal again


def test_seiche_step_response_is_the_documented_damped_sine():
    plant = with_effects(plain_plant(gain=0.0), "seiche")
    t = np.arange(0.0, 60.0, 0.6)
    level = _run(plant, t, np.where(t >= 0.6, 22.0, 20.0))
    s = t[1:] - 0.6
    expected = 2.0 * 0.8 * np.exp(-s / 25.0) * np.sin(2 * np.pi * s / 9.0)
    assert np.allclose(level[1:] - 250.0, expected, atol=1e-9)


def test_opening_nonlinearity_gives_a_local_gain_exp_s_v():
    plant = with_effects(plain_plant(tau=1e-3, delay=0.0), "opening_nonlinearity")
    level = _run(plant, [0.0, 1.0, 2.0], [30.0, 30.0, 30.0])
    assert level[-1] - 250.0 == pytest.approx(-12.0 * math.expm1(-0.03 * 10.0) / -0.03)
    nl = OpeningNonlinearity(-0.03)
    assert nl.inverse_mm(nl.forward_mm(7.5)) == pytest.approx(7.5, abs=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_results_do_not_depend_on_how_the_steps_are_cut(kind):
    """Inputs held over 1.2 s give the same levels whether stepped at 1.2 s or 0.3 s."""
    plant = with_effects(plain_plant(), kind)
    rng = np.random.default_rng(7)
    coarse_t = np.arange(0.0, 600.0, 1.2)
    opening = np.repeat(20.0 + rng.integers(-8, 9, 25), 20)[: coarse_t.size]
    flow = np.repeat(50.0 + rng.integers(-15, 16, 10), 50)[: coarse_t.size]
    coarse = _run(plant, coarse_t, opening, flow)
    fine_t = np.arange(0.0, 600.0, 0.3)
    fine = _run(plant, fine_t, np.repeat(opening, 4), np.repeat(flow, 4))
    assert np.max(np.abs(fine[::4] - coarse)) < 1e-9
    assert np.ptp(coarse) > 30.0


def _zoh_response(a, b, c, inputs, x0):
    x, out = np.array(x0, float), []
    for u in inputs:
        out.append(float((c @ x)[0]))
        x = a @ x + b @ np.atleast_1d(u)
    out.append(float((c @ x)[0]))
    return np.array(out)


def test_seiche_state_space_reproduces_the_reference():
    plant = with_effects(plain_plant(gain=0.0), "seiche")
    rng = np.random.default_rng(3)
    opening = 20.0 + rng.integers(-5, 6, 200).astype(float)
    t = np.arange(201) * 1.2
    level = _run(plant, t, np.append(opening, opening[-1]))
    a, b, c, _ = plant.effect_set.seiche.state_space(1.2)
    x0 = [(opening[0] - 20.0) / ((1 / 25.0) ** 2 + (2 * np.pi / 9.0) ** 2), 0.0]
    assert np.allclose(level - 250.0, _zoh_response(a, b, c, opening - 20.0, x0), atol=1e-9)


def test_inflow_and_drift_state_spaces_reproduce_the_reference():
    plant = with_effects(plain_plant(gain=0.0), "inflow_disturbance", "sensor_drift")
    rng = np.random.default_rng(4)
    flow = 50.0 + rng.integers(-20, 21, 150).astype(float)
    t = np.arange(151) * 1.2
    level = _run(plant, t, np.full(151, 20.0), np.append(flow, flow[-1]))
    fx = plant.effect_set
    a, b, c, _ = fx.inflow.state_space(1.2)
    inflow = _zoh_response(a, b, c, flow - 50.0, [2.0 * (flow[0] - 50.0)])
    a, b, c, _ = fx.drift.state_space(1.2)
    drift = _zoh_response(a, b, c, np.zeros((150, 0)), [0.0, 0.01])
    assert np.allclose(level - 250.0, inflow + drift, atol=1e-9)


def test_sensor_lag_state_space_reproduces_the_reference_on_an_arx_plant():
    plant = with_effects(arx_plant(), "sensor_lag")
    bare = arx_plant()
    rng = np.random.default_rng(5)
    opening = 20.0 + rng.integers(-5, 6, 120).astype(float)
    t, flow = np.arange(121) * 1.2, np.full(121, 41.5)
    sensed = _run(plant, t, np.append(opening, opening[-1]), flow)
    level = _run(bare, t, np.append(opening, opening[-1]), flow)
    a, b, c, _ = plant.effect_set.lag.state_space(1.2)
    # the ARX lag's input over sample k is the level at its end (documented)
    expected = _zoh_response(a, b, c, level[1:], [level[0]])
    assert np.allclose(sensed, expected, atol=1e-9)


def test_nonlinear_blocks_describe_their_mpc_handling():
    assert ActuatorRateLimit(0.5).rate_constraint_mm(1.2) == pytest.approx(0.6)
    assert ActuatorBacklash(2.0).compensate_mm(25.0, +1.0) == 26.0
    assert ActuatorBacklash(2.0).compensate_mm(25.0, -1.0) == 24.0
    for kind in ("actuator_rate_limit", "actuator_backlash", "opening_nonlinearity"):
        block = parse_effects((effect_dict(kind, **EXAMPLES[kind]),), "fopdt").blocks[0]
        assert block.mpc.split(":")[0] in {"constraint", "inverse"}
        with pytest.raises(NotImplementedError, match="nonlinear"):
            block.state_space(1.2)
