"""Residual signatures: what each missing effect leaves in the baseline's free-run residual.

Each signature is a statistic of the residual (on the fitted part) with a *strength* -- a
``|t|``- or ``z``-like number, about 1 for pure noise and growing with the evidence -- and
estimates of the block's parameters used as start values. The candidates whose signature
is at least :data:`SUGGEST_STRENGTH` strong are the ones the residual points at; they are
fitted first and flagged ``suggested`` in the output.

* ``sensor_drift`` -- slope of the residual against time.
* ``seiche`` -- peak of the residual's spectrum (Welch, high-passed at the longest period
  searched) between 2.5 samples and :func:`seiche_longest_period_s` (a minute, or 24 samples
  where those are longer), against the spectrum's median; amplitude by regression on the
  unit oscillation.
* ``inflow_disturbance`` -- regression of the residual on first-order filtered discharge
  changes (time constants 10-100 s).
* Per move ``i`` the residual is regressed on the baseline's response to that move, its
  time derivative and its second derivative: a gain error ``g_i``, a time shift ``d_i`` and a
  curvature ``c_i``. Then ``opening_nonlinearity``: ``log(1 + g_i)`` against the move's mid
  opening; ``flow_dependent_gain``: against the discharge at the move; ``actuator_backlash``:
  ``g_i |de_i|`` smaller on reversals; ``actuator_rate_limit``: ``d_i`` growing with ``|de_i|``
  (a ramp of ``|de| / r`` delays by half of it), with the logger's ``open`` durations giving
  the rate directly; ``sensor_lag``: a positive curvature ``c ~ lag^2 / 2`` common to all moves.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy import signal

from gatetwin.diagnosis.data import DiagnosisData
from gatetwin.diagnosis.fitting import Fit, effective_n
from gatetwin.diagnosis.grid_sim import GridInputs, simulate_grid
from gatetwin.plant.effects import effect_dict

__all__ = ["SEICHE_LONGEST_SAMPLES", "SEICHE_MIN_LONGEST_S", "SUGGEST_STRENGTH", "Signature",
           "move_coefficients", "seiche_longest_period_s", "signatures"]  # fmt: skip

SUGGEST_STRENGTH = 2.0


@dataclass(frozen=True)
class Signature:
    """One effect's residual signature.

    Attributes
    ----------
    effect : str
        Block kind.
    statistic : str
        What was measured, in words with its unit.
    value : float
        The measured value.
    strength : float
        Evidence, about 1 for noise.
    estimate : dict
        Block parameter estimates (start values).
    """

    effect: str
    statistic: str
    value: float
    strength: float
    estimate: dict[str, float]

    @property
    def suggests(self) -> bool:
        return bool(self.strength >= SUGGEST_STRENGTH)

    def to_dict(self) -> dict[str, Any]:
        return {"statistic": self.statistic, "value": _finite(self.value),
                "strength": _finite(self.strength), "suggests": self.suggests,
                "estimate": {k: _finite(v) for k, v in self.estimate.items()}}  # fmt: skip


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _ols(x: np.ndarray, y: np.ndarray, n_eff: float | None = None) -> tuple[float, float]:
    """Slope of ``y`` on ``x`` (with intercept) and its |t| (``n_eff`` for the SE)."""
    if x.size < 3 or np.ptp(x) == 0:
        return 0.0, 0.0
    design = np.column_stack([np.ones_like(x), x])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    resid = y - design @ coef
    n = x.size if n_eff is None else max(n_eff, 3.0)
    s2 = float(resid @ resid) / max(x.size - 2, 1) * x.size / n
    se = np.sqrt(s2 / float(np.sum((x - x.mean()) ** 2)))
    return float(coef[1]), float(abs(coef[1]) / se) if se > 0 else 0.0


def _drift(t: np.ndarray, r: np.ndarray) -> Signature:
    slope, strength = _ols(t, r, effective_n(r))
    return Signature("sensor_drift", "residual slope, mm/s", slope, strength,
                     {"rate_mm_per_s": slope})  # fmt: skip


#: Longest seiche period the spectrum is searched for, s, at least: one minute (the flume's
#: pools ring at 11.5 s; a canal pool of a kilometre at tens of minutes).
SEICHE_MIN_LONGEST_S = 60.0
#: ... and in samples: a sampling that resolves only slow oscillations is searched as far out
#: as 24 samples (4 minutes at 10 s, 24 minutes at 60 s), where the band still holds the
#: five spectral bins of a peak against its median.
SEICHE_LONGEST_SAMPLES = 24


def seiche_longest_period_s(sample_period_s: float) -> float:
    """The longest seiche period diagnosis looks for at ``sample_period_s``, s."""
    return max(SEICHE_MIN_LONGEST_S, SEICHE_LONGEST_SAMPLES * sample_period_s)


def _seiche(data: DiagnosisData, fit: Fit, r_full: np.ndarray) -> Signature:
    if any(e["kind"] == "seiche" for e in fit.plant.effects):
        return Signature("seiche", "the baseline already carries a seiche", np.nan, 0.0, {})
    ts = data.sample_period_s
    r = np.where(np.isfinite(r_full) & data.fit_mask, r_full, 0.0)[data.fit_mask.nonzero()[0]]
    longest = seiche_longest_period_s(ts)
    w = max(3, int(round(longest / ts)) | 1)
    r = r - np.convolve(r, np.ones(w) / w, mode="same")
    nperseg = min(256, r.size)
    f, pxx = signal.welch(r, fs=1.0 / ts, nperseg=nperseg)
    band = (f >= 1.0 / longest) & (f <= 1.0 / (2.5 * ts))
    if np.count_nonzero(band) < 5:
        return Signature("seiche", "spectral peak / median", np.nan, 0.0, {})
    k = int(np.argmax(np.where(band, pxx, -np.inf)))
    ratio = float(pxx[k] / np.median(pxx[band]))
    strength = (ratio - 1.0) * np.sqrt(max(r.size / nperseg, 1.0)) / 3.0
    period = float(1.0 / f[k])
    unit = _seiche_unit(data, fit, period)
    amp = float(unit @ np.nan_to_num(r_full * data.fit_mask) / max(unit @ unit, 1e-12))
    return Signature("seiche", "spectral peak / median of the residual", ratio, max(strength, 0.0),
                     {"period_s": period, "decay_time_s": 2.0 * period,
                      "amplitude_mm_per_mm": amp})  # fmt: skip


def _seiche_unit(data: DiagnosisData, fit: Fit, period: float) -> np.ndarray:
    osc = effect_dict("seiche", period_s=period, decay_time_s=2.0 * period,
                      amplitude_mm_per_mm=1.0)  # fmt: skip
    plant = replace(fit.plant, effects=(*fit.plant.effects, osc))
    return (simulate_grid(plant, data.grid) - fit.simulated_mm) * data.fit_mask


def _inflow(data: DiagnosisData, r_full: np.ndarray) -> Signature:
    lo, hi = data.flow_range_m3h
    if hi - lo < 1.0:
        return Signature("inflow_disturbance", "discharge constant", 0.0, 0.0, {})
    mask = data.fit_mask
    q = data.flow_m3h - data.flow_m3h[0]
    best = (0.0, 0.0, 30.0)
    for tau in (10.0, 25.0, 50.0, 100.0):
        a = np.exp(-data.sample_period_s / tau)
        filtered = signal.lfilter([1.0 - a], [1.0, -a], q, zi=[a * q[0]])[0]
        gain, strength = _ols(filtered[mask], r_full[mask], effective_n(r_full[mask]))
        if strength > best[1]:
            best = (gain, strength, tau)
    return Signature("inflow_disturbance", "residual gain on filtered discharge, mm/(m3/h)",
                     best[0], best[1], {"gain_mm_per_m3h": best[0],
                                        "time_constant_s": best[2]})  # fmt: skip


def _move_responses(data: DiagnosisData, fit: Fit, moves: list[Any]) -> list[np.ndarray]:
    """Baseline response to each move alone, at the samples."""
    g = data.grid
    t_grid = np.arange(g.n_intervals) * g.step_s + data.time_s[0]
    base_cmd = np.full(g.n_intervals, data.moves[0].opening_before_mm)
    rest = simulate_grid(fit.plant, GridInputs(base_cmd, g.flow_m3h, g.step_s, g.sample_point))
    out = []
    for move in moves:
        cmd = np.where(t_grid >= move.time_s - 1e-9, base_cmd + move.delta_mm, base_cmd)
        sim = simulate_grid(fit.plant, GridInputs(cmd, g.flow_m3h, g.step_s, g.sample_point))
        out.append(sim - rest)
    return out


def move_coefficients(data: DiagnosisData, fit: Fit, r_full: np.ndarray
                      ) -> tuple[list[Any], np.ndarray]:  # fmt: skip
    """Moves in the fitted part and their ``(g_i, d_i, c_i)`` (gain, shift s, curvature s²)."""
    split = data.split_time_s
    moves = [m for m in data.moves if m.time_s < split - 30.0]
    if not moves:
        return [], np.zeros((0, 3))
    mask = data.fit_mask
    t = data.time_s
    columns = [np.ones(int(mask.sum()))]
    for resp in _move_responses(data, fit, moves):
        d1 = np.gradient(resp, t)
        d2 = np.gradient(d1, t)
        columns += [resp[mask], -d1[mask], d2[mask]]
    coef, *_ = np.linalg.lstsq(np.column_stack(columns), r_full[mask], rcond=None)
    return moves, coef[1:].reshape(-1, 3)


def _per_move(data: DiagnosisData, fit: Fit, r_full: np.ndarray) -> list[Signature]:
    moves, coef = move_coefficients(data, fit, r_full)
    if len(moves) < 3:
        return []
    gain = np.log(np.clip(1.0 + coef[:, 0], 0.05, None))
    size = np.array([abs(m.delta_mm) for m in moves])
    mid = np.array([0.5 * (m.opening_before_mm + m.opening_after_mm) for m in moves])
    flow = np.array([m.flow_m3h for m in moves])
    slope_e, t_e = _ols(mid, gain)
    slope_q, t_q = _ols(flow, gain)
    return [
        Signature("opening_nonlinearity", "slope of log move gain on opening, 1/mm", slope_e, t_e,
                  {"gain_slope_per_mm": slope_e}),
        Signature("flow_dependent_gain", "slope of log move gain on discharge, h/m3", slope_q,
                  t_q, {"gain_slope_per_m3h": slope_q}),
        _backlash(moves, coef[:, 0] * size),
        _rate(data, moves, size, coef[:, 1]),
        _lag(coef[:, 2]),
    ]  # fmt: skip


def _backlash(moves: list[Any], shortfall: np.ndarray) -> Signature:
    weight = np.array([1.0 if m.reversal else 0.0 for m in moves])
    weight[0] = 0.5
    slope, strength = _ols(weight, shortfall)
    band = max(-slope, 0.0)
    return Signature("actuator_backlash", "move shortfall on reversals, mm of opening", -slope,
                     strength if slope < 0 else 0.0, {"deadband_mm": band})  # fmt: skip


def _rate(data: DiagnosisData, moves: list[Any], size: np.ndarray, shift: np.ndarray
          ) -> Signature:  # fmt: skip
    slope, strength = _ols(size, shift)
    rate = 1.0 / (2.0 * slope) if slope > 0 else np.nan
    opened = np.array([m.open_samples for m in data.moves], dtype=float)
    sizes = np.array([abs(m.delta_mm) for m in data.moves])
    if np.median(opened) >= 2:
        rate = float(np.median(sizes / ((opened - 0.5) * data.sample_period_s)))
        strength = max(strength, float(np.median(opened)))
    return Signature("actuator_rate_limit", "apparent delay per mm of move, s/mm", slope,
                     strength if slope > 0 or np.median(opened) >= 2 else 0.0,
                     {"rate_mm_per_s": rate})  # fmt: skip


def _lag(curvature: np.ndarray) -> Signature:
    mean = float(np.mean(curvature))
    se = float(np.std(curvature, ddof=1) / np.sqrt(curvature.size)) if curvature.size > 1 else 0.0
    strength = mean / se if se > 0 and mean > 0 else 0.0
    lag = float(np.sqrt(2.0 * mean)) if mean > 0 else np.nan
    return Signature("sensor_lag", "mean response curvature, s^2", mean, strength,
                     {"time_constant_s": lag})  # fmt: skip


def signatures(data: DiagnosisData, fit: Fit) -> dict[str, Signature]:
    """Every effect's signature in the residual of the refitted baseline ``fit``."""
    r_full = data.level_mm - fit.simulated_mm
    r_full = np.where(np.isfinite(r_full), r_full, 0.0)
    mask = data.fit_mask
    found = [_drift(data.time_s[mask], r_full[mask]), _seiche(data, fit, r_full),
             _inflow(data, r_full), *_per_move(data, fit, r_full)]  # fmt: skip
    return {s.effect: s for s in found}
