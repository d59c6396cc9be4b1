"""Compare a free-running FMU output with a measured level: the validation metrics.

* :func:`free_run_metrics` -- R², NRMSE fit %, MAE, RMSE, largest error and bias;
* :func:`noise_floor_fit_percent` -- the best fit a free run can expect given the noise;
* :func:`compare_steps` -- least-squares FOPDT fits (K, T, L) of the measured and the
  simulated step responses of a step record, and their differences;
* residual whiteness comes from :func:`gatetwin.identification.residual_whiteness`.

Pure functions on arrays and records; thresholds and pass/fail live in
:mod:`gatetwin.validation.thresholds`.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from gatetwin.errors import IdentificationError, ValidationError
from gatetwin.identification import identify_step
from gatetwin.identification.serial import finite_or_none
from gatetwin.records import Record
from gatetwin.records.record import per_record_memo

__all__ = [
    "STEP_METRICS",
    "FreeRunMetrics",
    "StepComparison",
    "compare_steps",
    "free_run_metrics",
    "noise_floor_fit_percent",
    "worst_step_differences",
]


@dataclass(frozen=True)
class FreeRunMetrics:
    """How well a free-run simulation ``y_hat`` follows the measurement ``y``.

    Computed over the samples where the measured level is finite. A simulation that is not
    finite there (a model that blew up) scores ``fit_percent = r2 = -inf`` and infinite
    errors.

    Attributes
    ----------
    n : int
        Samples compared.
    fit_percent : float
        NRMSE fit ``100 (1 - ||y - y_hat|| / ||y - mean(y)||)``, %: 100 is perfect, 0 is
        no better than the measured mean, negative is worse.
    r2 : float
        ``1 - SSE / SST`` (free run, not one-step-ahead).
    mae_mm, rmse_mm, max_abs_error_mm : float
        Mean absolute, root-mean-square and largest absolute error, mm.
    bias_mm : float
        ``mean(y_hat - y)``, mm: positive when the model sits above the measurement.
    """

    n: int
    fit_percent: float
    r2: float
    mae_mm: float
    rmse_mm: float
    max_abs_error_mm: float
    bias_mm: float

    @property
    def abs_bias_mm(self) -> float:
        return abs(self.bias_mm)

    def to_dict(self) -> dict[str, Any]:
        return {
            "n": self.n,
            "fit_percent": finite_or_none(self.fit_percent),
            "r2": finite_or_none(self.r2),
            "mae_mm": finite_or_none(self.mae_mm),
            "rmse_mm": finite_or_none(self.rmse_mm),
            "max_abs_error_mm": finite_or_none(self.max_abs_error_mm),
            "bias_mm": finite_or_none(self.bias_mm),
        }


def free_run_metrics(measured_mm: np.ndarray, simulated_mm: np.ndarray) -> FreeRunMetrics:
    """Metrics of a free-run simulation against a measured level.

    Parameters
    ----------
    measured_mm : ndarray
        Measured level, mm; NaN samples are skipped.
    simulated_mm : ndarray
        Simulated level on the same samples, mm.

    Raises
    ------
    ValidationError
        Fewer than 2 finite measured samples, or arrays of different shapes.
    """
    y = np.asarray(measured_mm, dtype=float)
    y_hat = np.asarray(simulated_mm, dtype=float)
    if y.shape != y_hat.shape:
        raise ValidationError(f"measured {y.shape} and simulated {y_hat.shape} differ in shape")
    ok = np.isfinite(y)
    n = int(np.count_nonzero(ok))
    if n < 2:
        raise ValidationError("fewer than 2 measured levels to compare the FMU output with")
    y, y_hat = y[ok], y_hat[ok]
    if not np.all(np.isfinite(y_hat)):
        inf = math.inf
        return FreeRunMetrics(n, -inf, -inf, inf, inf, inf, math.nan)
    err = y_hat - y
    sse = float(err @ err)
    sst = float((y - y.mean()) @ (y - y.mean()))
    fit = 100.0 * (1.0 - math.sqrt(sse / sst)) if sst > 0 else math.nan
    return FreeRunMetrics(
        n=n,
        fit_percent=fit,
        r2=1.0 - sse / sst if sst > 0 else math.nan,
        mae_mm=float(np.mean(np.abs(err))),
        rmse_mm=math.sqrt(sse / n),
        max_abs_error_mm=float(np.max(np.abs(err))),
        bias_mm=float(np.mean(err)),
    )


def noise_floor_fit_percent(sigma_mm: float, measured_mm: np.ndarray) -> tuple[float, float]:
    """The fit % a perfect model scores on a level measured with noise of SD ``sigma``.

    ``100 (1 - sigma / s)``, ``s`` the SD (normalised by ``n``) of the measured level over the
    compared samples (the finite ones, as in :func:`free_run_metrics`).

    Why this is the bound of the NRMSE fit ``100 (1 - ||y - y_hat|| / ||y - mean(y)||)``:
    write the measurement ``y = x + w``, ``x`` the true level and ``w`` noise of SD ``sigma``
    that the inputs do not cause. A free-run output ``y_hat`` depends on the inputs only,
    never on ``w``, so ``E ||y - y_hat||^2 = ||x - y_hat||^2 + n sigma^2 >= n sigma^2`` (the
    cross term has mean zero), with equality for ``y_hat = x``; and ``||y - mean(y)|| =
    sqrt(n) s`` exactly, noise included. Hence the expected fit is at most
    ``100 (1 - sigma / s)``, reached by the noise-free truth. One realisation can beat it by
    the sampling error of the noise's RMS (relative SD ``1 / sqrt(2 n)`` for white noise) and
    of ``sigma``'s estimate. Noise slower than the estimator sees (it detrends each hold with a
    quadratic, :mod:`gatetwin.noise`) is not in ``sigma``: the floor is then optimistic, still
    an upper bound.

    Parameters
    ----------
    sigma_mm : float
        Noise SD of the level, mm.
    measured_mm : ndarray
        Measured level, mm; NaN samples are skipped.

    Returns
    -------
    fit_percent : float
        The floor, % (NaN when ``sigma`` is not finite or the level is constant).
    level_sd_mm : float
        ``s``, mm.
    """
    y = np.asarray(measured_mm, dtype=float)
    y = y[np.isfinite(y)]
    s = float(np.std(y)) if y.size else math.nan
    if not (math.isfinite(sigma_mm) and s > 0):
        return math.nan, s
    return 100.0 * (1.0 - sigma_mm / s), s


@dataclass(frozen=True)
class StepComparison:
    """FOPDT parameters of the measured and the simulated response to one step.

    Both are least-squares FOPDT fits (:func:`gatetwin.identification.fit_fopdt` through
    :func:`gatetwin.identification.identify_step`) over the same samples, so the gate's motion
    (reconstructed as a ramp) affects both alike. A fit that cannot be made leaves its
    parameters NaN and says why in ``note``.

    Attributes
    ----------
    step_index : int
        Which step of the record.
    onset_time_s : float
        Step onset, s.
    delta_e_mm : float
        Opening step, mm.
    measured, simulated : dict[str, float]
        ``gain_mm_per_mm`` (K), ``time_constant_s`` (T), ``dead_time_s`` (L).
    note : str
        Why a fit is missing ("" when both exist).
    """

    step_index: int
    onset_time_s: float
    delta_e_mm: float
    measured: dict[str, float]
    simulated: dict[str, float]
    note: str = ""

    @property
    def differences(self) -> dict[str, float]:
        """Simulated minus measured, per parameter (NaN where a fit is missing)."""
        return {k: self.simulated[k] - self.measured[k] for k in _PARAMETERS}

    def to_dict(self) -> dict[str, Any]:
        return {
            "step_index": self.step_index,
            "onset_time_s": self.onset_time_s,
            "delta_e_mm": self.delta_e_mm,
            "measured": {k: finite_or_none(v) for k, v in self.measured.items()},
            "fmu": {k: finite_or_none(v) for k, v in self.simulated.items()},
            "difference": {k: finite_or_none(v) for k, v in self.differences.items()},
            "note": self.note,
        }


_PARAMETERS = ("gain_mm_per_mm", "time_constant_s", "dead_time_s")
_NAN_PARAMETERS = dict.fromkeys(_PARAMETERS, math.nan)


def _fopdt_parameters(record: Record, gauge: str, step_index: int) -> tuple[dict[str, float], str]:
    """K, T, L of one step's least-squares FOPDT fit, and a note on what went wrong.

    Numerical warnings of the fit (e.g. an ill-conditioned Jacobian on the output of a
    model that blew up) are caught and returned in the note, not printed.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            fit = identify_step(record, gauge, step_index).gauges[gauge].fit
        except IdentificationError as exc:
            return dict(_NAN_PARAMETERS), " ".join(str(exc).split())
    note = "; ".join(sorted({" ".join(str(w.message).split()) for w in caught}))
    return {
        "gain_mm_per_mm": fit.gain_mm_per_mm,
        "time_constant_s": fit.time_constant_s,
        "dead_time_s": fit.dead_time_s,
    }, (f"fit warning: {note}" if note else "")


#: The measured side of :func:`compare_steps`: the same for every FMU validated against the
#: record, so fitted once per record content in a process.
_measured_parameters = per_record_memo(_fopdt_parameters)


def compare_steps(
    record: Record, gauge: str, simulated_mm: np.ndarray
) -> tuple[StepComparison, ...]:
    """FOPDT fits of measured and simulated responses to every step of a step record.

    Parameters
    ----------
    record : Record
        The record (its ``test`` must be ``"step"``; other records give ``()``).
    gauge : str
        The gauge compared.
    simulated_mm : ndarray
        The FMU's output at every sample of the record, mm.

    Returns
    -------
    tuple of StepComparison
        One per step; empty for PRBS and free records.
    """
    if record.test != "step":
        return ()
    simulated = np.array(simulated_mm, dtype=float)
    simulated.flags.writeable = False
    as_simulated = replace(record, levels_mm={gauge: simulated})
    out = []
    for k, step in enumerate(record.steps):
        measured, why_measured = _measured_parameters(record, gauge, k)
        measured = dict(measured)
        fmu, why_fmu = _fopdt_parameters(as_simulated, gauge, k)
        notes = [f"measured: {why_measured}" if why_measured else "",
                 f"FMU: {why_fmu}" if why_fmu else ""]  # fmt: skip
        out.append(
            StepComparison(
                step_index=k,
                onset_time_s=float(step.time_s),
                delta_e_mm=float(step.delta_e_mm),
                measured=measured,
                simulated=fmu,
                note="; ".join(n for n in notes if n),
            )
        )
    return tuple(out)


def worst_step_differences(steps: tuple[StepComparison, ...]) -> dict[str, float]:
    """Largest absolute difference of each FOPDT parameter over the steps.

    Keys ``gain_abs_diff_mm_per_mm``, ``time_constant_abs_diff_s``, ``dead_time_abs_diff_s``;
    NaN when no step has both fits (and always NaN without steps).
    """
    out = {}
    for param, key in zip(_PARAMETERS, STEP_METRICS, strict=True):
        values = [abs(s.differences[param]) for s in steps]
        finite = [v for v in values if math.isfinite(v)]
        out[key] = max(finite) if finite else math.nan
    return out


#: Threshold-able step metrics, in the order of the FOPDT parameters.
STEP_METRICS = ("gain_abs_diff_mm_per_mm", "time_constant_abs_diff_s", "dead_time_abs_diff_s")
