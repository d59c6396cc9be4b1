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

from dataclasses import dataclass
from pathlib import Path

import pytest

from diagnose_cases import JUDGED, case_plan, draw_case
from gatetwin.diagnosis import diagnose_record

GAP_REDUCTION = 0.5
PARAMETER_TOLERANCE = 0.25


@dataclass(frozen=True)
class Outcome:
    seed: int
    truth: str
    named: str
    gap_reduction: float
    parameter_errors: dict[str, float]

    @property
    def right(self) -> bool:
        return self.named == self.truth

    @property
    def parameters_ok(self) -> bool:
        return bool(self.parameter_errors) and all(
            e <= PARAMETER_TOLERANCE for e in self.parameter_errors.values()
        )


def run_case(seed: int, effect: str, folder: Path) -> Outcome:
    case = draw_case(seed, effect)
    result = diagnose_record(case.write(folder))
    errors: dict[str, float] = {}
    if result["named_effect"] == effect and effect != "none":
        fitted = result["effect_fit"]["parameters"]
        errors = {k: abs(fitted[k]["value"] - v) / abs(v) for k, v in case.params.items()}
    return Outcome(seed, effect, result["named_effect"], result["gap_reduction"], errors)


def rates(outcomes: list[Outcome]) -> dict[str, float]:
    none = [o for o in outcomes if o.truth == "none"]
    present = [o for o in outcomes if o.truth != "none"]
    return {
        "cases": len(outcomes),
        "right_name": sum(o.right for o in outcomes) / len(outcomes),
        "none_flagged": sum(o.named != "none" for o in none) / max(len(none), 1),
        "false_positive_overall": sum(o.named not in ("none", o.truth) for o in outcomes)
        / len(outcomes),
        "missed": sum(o.named == "none" for o in present) / max(len(present), 1),
        "gap_down_50": sum(o.gap_reduction >= GAP_REDUCTION for o in present)
        / max(len(present), 1),
        "parameters_within_25": sum(o.parameters_ok for o in present) / max(len(present), 1),
        "median_gap_reduction": sorted(o.gap_reduction for o in present)[len(present) // 2],
        "worst_parameter_error": max(
            (e for o in present for e in o.parameter_errors.values()), default=0.0
        ),
    }


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
