"""Pass/fail thresholds on validation metrics, and the checks they produce.

Metrics where higher is better (``fit_percent``, ``fit_vs_floor``, ``r2``, ``ljung_box_p``)
take a lower limit: ``--fail-under fit_percent=85`` fails a record whose fit is below 85 %;
``--fail-under fit_vs_floor=-5`` fails one whose fit is more than 5 percentage points below
its noise floor's fit (the best fit a perfect model can expect on that record's noise; an
undefined floor fails the check). Error
metrics (``rmse_mm``, ``mae_mm``, ``max_abs_error_mm``, ``abs_bias_mm`` and the step
comparison's ``*_abs_diff_*``) take an upper limit: ``--fail-over rmse_mm=4`` fails a record
whose RMSE is above 4 mm. Putting a metric on the wrong side is refused, so that a
threshold can never silently mean the opposite of what was written.

This module decides nothing about *which* thresholds apply; the caller chooses them.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from gatetwin.errors import ValidationError
from gatetwin.identification.serial import finite_or_none
from gatetwin.validation.compare import STEP_METRICS

__all__ = [
    "FAILED",
    "HIGHER_IS_BETTER",
    "LOWER_IS_BETTER",
    "NOT_APPLICABLE",
    "PASSED",
    "Check",
    "Threshold",
    "parse_threshold",
    "parse_thresholds",
]

#: Metrics where a higher value is better: a threshold on them is a lower limit.
HIGHER_IS_BETTER = ("fit_percent", "fit_vs_floor", "r2", "ljung_box_p")
#: Metrics where a lower value is better: a threshold on them is an upper limit.
LOWER_IS_BETTER = ("rmse_mm", "mae_mm", "max_abs_error_mm", "abs_bias_mm", *STEP_METRICS)

PASSED, FAILED, NOT_APPLICABLE = "passed", "failed", "not_applicable"


@dataclass(frozen=True)
class Threshold:
    """A limit on one metric.

    Attributes
    ----------
    metric : str
        One of :data:`HIGHER_IS_BETTER` or :data:`LOWER_IS_BETTER`.
    limit : float
        The limit, in the metric's unit (its name says which).
    """

    metric: str
    limit: float

    def __post_init__(self) -> None:
        if self.metric not in HIGHER_IS_BETTER + LOWER_IS_BETTER:
            raise ValidationError(
                f"unknown metric {self.metric!r}; expected one of "
                f"{', '.join(HIGHER_IS_BETTER + LOWER_IS_BETTER)}"
            )
        if not math.isfinite(self.limit):
            raise ValidationError(f"threshold on {self.metric}: limit {self.limit} is not finite")

    @property
    def fails_when(self) -> str:
        """``"below"`` for higher-is-better metrics, else ``"above"``."""
        return "below" if self.metric in HIGHER_IS_BETTER else "above"

    @property
    def text(self) -> str:
        """The passing condition, e.g. ``fit_percent >= 85``."""
        return f"{self.metric} {'>=' if self.fails_when == 'below' else '<='} {self.limit:g}"

    def check(self, metrics: Mapping[str, float]) -> Check:
        """Apply to one record's flat metrics (a missing metric is not applicable)."""
        if self.metric not in metrics:
            why = "needs a step record" if self.metric in STEP_METRICS else "not computed"
            return Check(self, math.nan, NOT_APPLICABLE, f"{self.metric}: not applicable ({why})")
        value = float(metrics[self.metric])
        if math.isnan(value):
            return Check(self, value, FAILED, f"{self.metric} is undefined; required {self.text}")
        ok = value >= self.limit if self.fails_when == "below" else value <= self.limit
        if ok:
            return Check(self, value, PASSED, f"{self.metric} = {value:.6g} ({self.text})")
        return Check(self, value, FAILED, f"{self.metric} = {value:.6g} fails {self.text}")

    def to_dict(self) -> dict[str, Any]:
        return {"metric": self.metric, "limit": self.limit, "fails_when": self.fails_when}


@dataclass(frozen=True)
class Check:
    """One threshold applied to one record.

    Attributes
    ----------
    threshold : Threshold
    value : float
        The metric's value (NaN when not applicable or undefined).
    status : str
        ``"passed"``, ``"failed"`` or ``"not_applicable"`` (e.g. a step metric on a PRBS
        record; not a failure).
    message : str
        One line saying what was found.
    """

    threshold: Threshold
    value: float
    status: str
    message: str

    @property
    def failed(self) -> bool:
        return self.status == FAILED

    def to_dict(self) -> dict[str, Any]:
        return {
            **self.threshold.to_dict(),
            "value": finite_or_none(self.value),
            "status": self.status,
            "message": self.message,
        }


def parse_threshold(text: str, fails_when: str) -> Threshold:
    """Parse ``METRIC=VALUE`` from ``--fail-under`` (``"below"``) or ``--fail-over``.

    Raises
    ------
    ValidationError
        Not ``METRIC=VALUE``, an unknown metric, a value that is not a finite number, or a
        metric on the wrong side (an error metric after ``--fail-under``, say).
    """
    option = "--fail-under" if fails_when == "below" else "--fail-over"
    metric, sep, value = text.partition("=")
    metric = metric.strip()
    if not sep or not metric:
        raise ValidationError(f"{option} {text!r}: expected METRIC=VALUE, e.g. fit_percent=85")
    try:
        limit = float(value)
    except ValueError:
        raise ValidationError(f"{option} {text!r}: {value!r} is not a number") from None
    try:
        threshold = Threshold(metric, limit)
    except ValidationError as exc:
        raise ValidationError(f"{option} {text!r}: {exc}") from None
    if threshold.fails_when != fails_when:
        if fails_when == "below":
            hint = f"{metric} is an error metric (lower is better); use --fail-over {text}"
        else:
            hint = f"{metric} is a score (higher is better); use --fail-under {text}"
        raise ValidationError(f"{option} {text!r}: {hint}")
    return threshold


def parse_thresholds(
    fail_under: Iterable[str] = (), fail_over: Iterable[str] = ()
) -> tuple[Threshold, ...]:
    """All ``--fail-under`` then all ``--fail-over`` thresholds, parsed."""
    return tuple(parse_threshold(t, "below") for t in fail_under) + tuple(
        parse_threshold(t, "above") for t in fail_over
    )
