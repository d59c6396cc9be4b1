"""The diagnosis on generated records with a hidden effect (tests/diagnose_cases.py).

63 cases (7 of each effect and 7 ``none``, fixed seeds), about three minutes: marked slow
(CI runs it with the slow subset).
Thresholds:

* the right name (effect or ``none``) in at least 90 % of the cases;
* ``none`` wrongly flagged in at most 5 % of the ``none`` cases;
* where an effect was present: the gap ``sqrt(RMSE^2 - sigma^2)`` down by at least 50 % and
  every judged parameter of the effect within 25 % of the truth, in at least 90 % of those
  cases (and in every case whose effect was named right).

The measured rates are attached to the test report (``record_property``) and printed by
``benchmarks/bench_diagnose.py``.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from diagnose_cases import (
    GAP_REDUCTION,
    JUDGED,
    Outcome,
    case_plan,
    draw_case,
    rates,
    run_case,
)


def check(outcomes: list[Outcome]) -> dict[str, float]:
    r = rates(outcomes)
    wrong = [(o.seed, o.truth, o.named) for o in outcomes if not o.right]
    assert r["right_name"] >= 0.9, wrong
    assert r["none_flagged"] <= 0.05, wrong
    assert r["gap_down_50"] >= 0.9, r
    assert r["parameters_within_25"] >= 0.9, r
    for o in outcomes:
        if o.right and o.truth != "none":
            assert o.gap_reduction >= GAP_REDUCTION, o
            assert o.parameters_ok, o
    return r


def _run(n_cases: int, folder: Path, record_property) -> None:
    outcomes = [run_case(seed, effect, folder) for seed, effect in case_plan(n_cases)]
    measured = check(outcomes)
    for key, value in measured.items():
        record_property(key, value)


def test_every_effect_is_judged_on_its_physical_parameters():
    assert set(JUDGED) == {"none", *JUDGED} and len(JUDGED) == 9
    for seed, effect in case_plan(9):
        case = draw_case(seed, effect)
        assert set(case.params) == set(JUDGED[effect])
        assert (case.truth.effects == ()) == (effect == "none")


@pytest.mark.slow
def test_diagnosis_names_hidden_effects_in_63_generated_cases(tmp_path, record_property):
    _run(63, tmp_path, record_property)
