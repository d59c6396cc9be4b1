"""First-order-plus-dead-time (FOPDT) identification of one level series from a step.

Model: ``G(s) = K exp(-L s) / (T s + 1)`` from gate opening (mm) to upstream level (mm).
Two estimators, on plain arrays:

* :func:`paper_step_method` -- the reference study's graphical method, exactly: windows of
  40 valid samples, ``K = dH_ss / de``, ``L`` = first ``|dH| > 3 sigma_pre`` (a
  *detectability* delay, at sample times), ``T`` = time from ``L`` to 63.2 % of ``dH_ss``.
* :func:`fit_fopdt` -- nonlinear least squares of the step response on the whole
  transient with a continuous dead time and standard errors from the Jacobian: the
  *model* dead time and time constant.

Record-level wrappers are in :mod:`gatetwin.identification.step`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from scipy import linalg, optimize

from gatetwin.errors import IdentificationError
from gatetwin.identification.serial import finite_or_none, none_to_nan

__all__ = ["ROUND_OFF", "FopdtFit", "PaperStepResult", "fit_fopdt", "paper_step_method"]

#: Threshold floor relative to the level, so that noise-free data (sigma_pre = 0) are
#: not triggered by floating-point round-off of the pre-window mean.
ROUND_OFF = 1e-9


@dataclass(frozen=True)
class PaperStepResult:
    """The reference study's step-response analysis of one gauge.

    Attributes
    ----------
    pre_mean_mm, pre_sd_mm : float
        Mean and sample SD (``ddof=1``) of the pre-step window, mm.
    post_mean_mm, post_sd_mm : float
        Mean and sample SD (``ddof=1``) of the post-step window, mm.
    delta_level_mm : float
        ``dH_ss = post_mean - pre_mean``, mm (``"dH_mm"`` in JSON).
    gain_mm_per_mm : float
        ``K = dH_ss / delta_e``.
    dead_time_s : float
        ``L``: onset to the first valid sample with ``|H - pre_mean| > threshold``, s.
    time_constant_s : float
        ``T``: from ``onset + L`` to the 63.2 % crossing (linearly interpolated), s.
    n_pre, n_post : int
        Samples in the windows (the window length, 40, when accepted).
    delta_e_mm : float
        Opening step, mm.
    onset_time_s : float
        Step onset, s (t = 0 of the analysis).
    threshold_mm : float
        Detection threshold ``3 * pre_sd`` (floored at round-off), mm.
    pre_start_index : int
        Index of the first sample of the pre window.
    post_start_index, post_stop_index : int
        First sample of the post window and the exclusive end of the post hold.
    detect_index : int
        Index of the sample that defines ``L``.
    """

    pre_mean_mm: float
    pre_sd_mm: float
    post_mean_mm: float
    post_sd_mm: float
    delta_level_mm: float
    gain_mm_per_mm: float
    dead_time_s: float
    time_constant_s: float
    n_pre: int
    n_post: int
    delta_e_mm: float
    onset_time_s: float
    threshold_mm: float
    pre_start_index: int
    post_start_index: int
    post_stop_index: int
    detect_index: int

    def to_dict(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> PaperStepResult:
        try:
            return cls(
                **{
                    f.name: (int if f.name in _INT_FIELDS else float)(data[f.name])
                    for f in fields(cls)
                }
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise IdentificationError(f"paper step result: malformed ({exc})") from None


_INT_FIELDS = frozenset(
    {"n_pre", "n_post", "pre_start_index", "post_start_index", "post_stop_index", "detect_index"}
)


def _check_arrays(*arrays: np.ndarray) -> None:
    sizes = {np.asarray(a).shape for a in arrays}
    if len(sizes) != 1 or len(next(iter(sizes))) != 1:
        raise IdentificationError("step analysis needs 1-D arrays of equal length")


def _check_step(onset_time_s: float, delta_e_mm: float) -> None:
    if not np.isfinite(onset_time_s):
        raise IdentificationError(f"step onset time must be finite, got {onset_time_s}")
    if not (np.isfinite(delta_e_mm) and delta_e_mm != 0.0):
        raise IdentificationError(f"opening step must be finite and non-zero, got {delta_e_mm}")


def _windows(
    t: np.ndarray,
    valid: np.ndarray,
    onset: float,
    pre_start: int,
    post_stop: int,
    n_window: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the pre window (last valid samples before onset) and post window."""
    before = valid & (t < onset)
    before[: max(pre_start, 0)] = False
    after = valid & (t >= onset)
    after[post_stop:] = False
    pre = np.flatnonzero(before)[-n_window:]
    post = np.flatnonzero(after)[-n_window:]
    if pre.size < n_window:
        raise IdentificationError(
            f"step analysis needs {n_window} valid hold samples before the onset at "
            f"t = {onset:g} s, found {pre.size}"
        )
    if post.size < n_window:
        raise IdentificationError(
            f"step analysis needs {n_window} valid hold samples in the hold after the step, "
            f"found {post.size}"
        )
    return pre, post


def _crossing_time(t: np.ndarray, frac: np.ndarray, start: int, level: float) -> float:
    """Time ``frac`` first reaches ``level`` at or after position ``start``.

    Linear interpolation between that sample and the previous one, never earlier than
    ``t[start]``.
    """
    reach = np.flatnonzero(frac[start:] >= level)
    if reach.size == 0:
        raise IdentificationError(
            f"the response never reaches {100 * level:.1f} % of its steady change"
        )
    j = start + int(reach[0])
    if j == 0:
        return float(t[0])
    f0, f1 = frac[j - 1], frac[j]
    t_cross = t[j - 1] + (level - f0) / (f1 - f0) * (t[j] - t[j - 1]) if f1 != f0 else t[j]
    return float(max(t_cross, t[start]))


def _detect(
    t: np.ndarray, dev: np.ndarray, d_ss: float, threshold: float, fraction: float
) -> tuple[int, float]:
    """Position of the first ``|dev| > threshold`` and the time ``dev`` reaches ``fraction``."""
    above = np.flatnonzero(np.abs(dev) > threshold)
    if above.size == 0:
        raise IdentificationError(
            f"the response never exceeds the detection threshold ({threshold:.3g} mm)"
        )
    i_l = int(above[0])
    return i_l, _crossing_time(t, dev / d_ss, i_l, fraction)


def paper_step_method(
    time_s: np.ndarray,
    level_mm: np.ndarray,
    hold: np.ndarray,
    onset_time_s: float,
    post_stop_index: int,
    delta_e_mm: float,
    *,
    opening_mm: np.ndarray | None = None,
    pre_start_index: int = 0,
    n_window: int = 40,
    threshold_sd: float = 3.0,
    fraction: float = 0.632,
) -> PaperStepResult:
    """The reference study's step-response method for one level series.

    * t = 0 at ``onset_time_s``. *Valid* samples have a finite level and are ``hold``
      samples; when ``opening_mm`` is given, ``open`` samples whose opening was logged are
      valid for the transient too (the paper removes transition records with a *missing*
      opening). The windows use valid hold samples only.
    * Pre window: the ``n_window`` (40) valid hold samples immediately before the onset
      (not before ``pre_start_index``). Post window: the last 40 valid hold samples before
      ``post_stop_index`` (the end of the constant-opening hold after the step).
    * ``sigma_pre`` is the sample SD of the pre window (``ddof=1``); ``dH(t) = H(t) -
      pre_mean``; ``dH_ss = post_mean - pre_mean``; ``K = dH_ss / delta_e``.
    * ``L`` = time from the onset to the first valid sample with ``|dH| > 3 sigma_pre``
      (at a sample time; so on noise-free data ``L`` exceeds the true delay by up to one
      sample).
    * ``T`` = time from ``onset + L`` until ``dH / dH_ss`` first reaches 0.632, the
      crossing linearly interpolated between the two samples around it (never before
      ``onset + L``).

    Parameters
    ----------
    time_s : ndarray
        Sample times, s.
    level_mm : ndarray
        Level of one gauge, mm (NaN = missing).
    hold : ndarray of bool
        True where the actuator is still.
    onset_time_s : float
        Step onset (start of gate motion), s.
    post_stop_index : int
        Exclusive end index of the hold after the step.
    delta_e_mm : float
        Opening step, mm (either sign).
    opening_mm : ndarray, optional
        Logged opening, mm; see *valid* above.
    pre_start_index : int, optional
        Earliest sample the pre window may use (e.g. the previous step's onset).
    n_window : int, optional
        Window length, samples (40).
    threshold_sd : float, optional
        Detection threshold in pre-window SDs (3).
    fraction : float, optional
        Share of the steady change that ends ``T`` (0.632).

    Returns
    -------
    PaperStepResult

    Raises
    ------
    IdentificationError
        Fewer than ``n_window`` samples in a window, or a steady change not larger than
        the detection threshold (``|dH_ss| <= 3 sigma_pre``; this also covers a response
        that never crosses the threshold: a post mean beyond it has a sample beyond it,
        and reaches 100 % of ``dH_ss``, so the later checks are only defensive).
    """
    t = np.asarray(time_s, dtype=float)
    h = np.asarray(level_mm, dtype=float)
    hold = np.asarray(hold, dtype=bool)
    _check_arrays(t, h, hold)
    _check_step(onset_time_s, delta_e_mm)
    finite = np.isfinite(h)
    pre, post = _windows(t, hold & finite, onset_time_s, pre_start_index, post_stop_index, n_window)
    pre_mean, pre_sd = float(np.mean(h[pre])), float(np.std(h[pre], ddof=1))
    post_mean, post_sd = float(np.mean(h[post])), float(np.std(h[post], ddof=1))
    d_ss = post_mean - pre_mean
    threshold = max(threshold_sd * pre_sd, ROUND_OFF * max(1.0, abs(pre_mean)))
    if not abs(d_ss) > threshold:
        raise IdentificationError(
            f"step too small to detect: |dH_ss| = {abs(d_ss):.3g} mm is not above "
            f"{threshold_sd:g} x pre-step SD = {threshold:.3g} mm"
        )
    usable = hold if opening_mm is None else hold | np.isfinite(opening_mm)
    trans = np.flatnonzero(usable & finite & (t >= onset_time_s))
    trans = trans[trans < post_stop_index]
    i_l, t_63 = _detect(t[trans], h[trans] - pre_mean, d_ss, threshold, fraction)
    t_l = float(t[trans[i_l]])
    return PaperStepResult(
        pre_mean_mm=pre_mean,
        pre_sd_mm=pre_sd,
        post_mean_mm=post_mean,
        post_sd_mm=post_sd,
        delta_level_mm=d_ss,
        gain_mm_per_mm=d_ss / delta_e_mm,
        dead_time_s=t_l - onset_time_s,
        time_constant_s=t_63 - t_l,
        n_pre=int(pre.size),
        n_post=int(post.size),
        delta_e_mm=float(delta_e_mm),
        onset_time_s=float(onset_time_s),
        threshold_mm=threshold,
        pre_start_index=int(pre[0]),
        post_start_index=int(post[0]),
        post_stop_index=int(post_stop_index),
        detect_index=int(trans[i_l]),
    )


@dataclass(frozen=True)
class FopdtFit:
    """Least-squares FOPDT step-response fit.

    ``H(t) = H0 + K de (1 - exp(-(t - t_on - L) / T))`` for ``t > t_on + L``, else ``H0``.

    Attributes
    ----------
    gain_mm_per_mm, time_constant_s, dead_time_s, baseline_mm : float
        ``K``, ``T``, ``L`` (continuous, not whole samples) and ``H0``.
    gain_se_mm_per_mm, time_constant_se_s, dead_time_se_s, baseline_se_mm : float
        Standard errors from ``sigma^2 (J^T J)^-1`` at the optimum (NaN if singular).
    rmse_mm : float
        Root-mean-square residual, mm.
    n : int
        Samples fitted.
    onset_time_s, delta_e_mm : float
        The step the model refers to.
    converged : bool
        Whether the optimiser reported convergence.
    """

    gain_mm_per_mm: float
    time_constant_s: float
    dead_time_s: float
    baseline_mm: float
    gain_se_mm_per_mm: float
    time_constant_se_s: float
    dead_time_se_s: float
    baseline_se_mm: float
    rmse_mm: float
    n: int
    onset_time_s: float
    delta_e_mm: float
    converged: bool = True

    def curve(self, time_s: np.ndarray) -> np.ndarray:
        """Model level at ``time_s`` (s), mm."""
        return _model(
            np.asarray(time_s, dtype=float) - self.onset_time_s,
            self.delta_e_mm,
            np.array(
                [self.baseline_mm, self.gain_mm_per_mm, self.dead_time_s, self.time_constant_s]
            ),
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "K": self.gain_mm_per_mm,
            "L_s": self.dead_time_s,
            "T_s": self.time_constant_s,
            "K_se": finite_or_none(self.gain_se_mm_per_mm),
            "L_se": finite_or_none(self.dead_time_se_s),
            "T_se": finite_or_none(self.time_constant_se_s),
            "H0_mm": self.baseline_mm,
            "H0_se_mm": finite_or_none(self.baseline_se_mm),
            "rmse_mm": self.rmse_mm,
            "n": self.n,
            "onset_time_s": self.onset_time_s,
            "delta_e_mm": self.delta_e_mm,
            "converged": self.converged,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> FopdtFit:
        try:
            return cls(
                gain_mm_per_mm=float(data["K"]),
                time_constant_s=float(data["T_s"]),
                dead_time_s=float(data["L_s"]),
                baseline_mm=float(data["H0_mm"]),
                gain_se_mm_per_mm=none_to_nan(data["K_se"]),
                time_constant_se_s=none_to_nan(data["T_se"]),
                dead_time_se_s=none_to_nan(data["L_se"]),
                baseline_se_mm=none_to_nan(data["H0_se_mm"]),
                rmse_mm=float(data["rmse_mm"]),
                n=int(data["n"]),
                onset_time_s=float(data["onset_time_s"]),
                delta_e_mm=float(data["delta_e_mm"]),
                converged=bool(data.get("converged", True)),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise IdentificationError(f"FOPDT fit: malformed dictionary ({exc})") from None


def _model(tau: np.ndarray, de: float, p: np.ndarray) -> np.ndarray:
    """Step response at ``tau = t - t_on`` for ``p = (H0, K, L, T)``."""
    h0, k, dead, tc = p
    s = np.maximum(tau - dead, 0.0)
    return h0 + k * de * -np.expm1(-s / tc)


def _jacobian(tau: np.ndarray, de: float, p: np.ndarray) -> np.ndarray:
    _, k, dead, tc = p
    s = tau - dead
    on = s > 0
    e = np.where(on, np.exp(-np.maximum(s, 0.0) / tc), 1.0)
    jac = np.zeros((tau.size, 4))
    jac[:, 0] = 1.0
    jac[:, 1] = de * (1.0 - e)
    jac[:, 2] = np.where(on, -k * de * e / tc, 0.0)
    jac[:, 3] = np.where(on, -k * de * e * s / tc**2, 0.0)
    return jac


def _grid_start(
    tau: np.ndarray, h: np.ndarray, de: float, h0: float, dt: float
) -> tuple[float, float, float]:
    """Best ``(K, L, T)`` on a grid, ``H0`` fixed, ``K`` solved linearly at each node."""
    span = float(tau.max())
    t_grid = np.geomspace(max(dt / 2.0, 1e-3), max(span, dt), 40)
    l_grid = np.linspace(0.0, span / 2.0, 41)
    r = h - h0
    best = (-np.inf, 0.0, 0.0, 0.0)
    for dead in l_grid:  # one row of the grid at a time: memory 40 x n
        g = de * -np.expm1(-np.maximum(tau - dead, 0.0)[None, :] / t_grid[:, None])
        gr, gg = g @ r, np.einsum("ij,ij->i", g, g)
        ok = gg > 0
        if not np.any(ok):
            continue
        score = np.where(ok, gr**2 / np.where(ok, gg, 1.0), -np.inf)
        j = int(np.argmax(score))
        if score[j] > best[0]:
            best = (float(score[j]), float(gr[j] / gg[j]), float(dead), float(t_grid[j]))
    return best[1], best[2], best[3]


def _standard_errors(jac: np.ndarray, ssr: float, n: int) -> np.ndarray:
    sigma2 = ssr / (n - 4)
    try:
        cov = linalg.solve(jac.T @ jac, np.eye(4), assume_a="pos")
    except (linalg.LinAlgError, ValueError):
        return np.full(4, np.nan)
    return np.sqrt(np.clip(np.diag(cov) * sigma2, 0.0, None))


def fit_fopdt(
    time_s: np.ndarray,
    level_mm: np.ndarray,
    valid_mask: np.ndarray,
    onset_time_s: float,
    delta_e_mm: float,
    pre_mean_mm: float,
    *,
    initial: tuple[float, float, float] | None = None,
) -> FopdtFit:
    """Least-squares FOPDT fit of a step response with a continuous dead time.

    Fits ``p = (H0, K, L, T)`` of
    ``H(t) = H0 + K de (1 - exp(-(t - t_on - L) / T))`` for ``t > t_on + L``, else ``H0``,
    to every sample selected by ``valid_mask`` (normally from the pre window through the
    end of the post hold), by :func:`scipy.optimize.least_squares` (trust-region
    reflective, analytic Jacobian) with bounds ``L >= 0``, ``T > 0`` (``T >= 1 ms``).
    Starting values: ``initial`` ``(K, L, T)`` if given, else the best node of a 41 x 40
    grid over ``L`` and ``T`` with ``H0 = pre_mean_mm`` and ``K`` solved linearly.
    Standard errors are ``sqrt(diag(sigma^2 (J^T J)^-1))``,
    ``sigma^2 = SSR / (n - 4)``, with ``J`` the Jacobian at the optimum.

    Parameters
    ----------
    time_s : ndarray
        Sample times, s.
    level_mm : ndarray
        Level, mm.
    valid_mask : ndarray of bool
        Samples to fit (non-finite levels are dropped in addition).
    onset_time_s : float
        Step onset, s.
    delta_e_mm : float
        Opening step, mm.
    pre_mean_mm : float
        Pre-step level, mm: start value of ``H0``.
    initial : (float, float, float), optional
        Start values ``(K mm/mm, L s, T s)``.

    Returns
    -------
    FopdtFit

    Raises
    ------
    IdentificationError
        Too few samples before or after the onset, or a failed optimisation.
    """
    t = np.asarray(time_s, dtype=float)
    h = np.asarray(level_mm, dtype=float)
    mask = np.asarray(valid_mask, dtype=bool)
    _check_arrays(t, h, mask)
    _check_step(onset_time_s, delta_e_mm)
    mask = mask & np.isfinite(h) & np.isfinite(t)
    tau, hv = t[mask] - onset_time_s, h[mask]
    if np.count_nonzero(tau < 0) < 2 or np.count_nonzero(tau > 0) < 6:
        raise IdentificationError(
            "FOPDT fit needs at least 2 samples before and 6 after the step onset"
        )
    if not np.isfinite(pre_mean_mm):
        raise IdentificationError("FOPDT fit needs a finite pre-step level")
    dt = float(np.median(np.diff(tau)))
    k0, l0, t0 = (
        initial if initial is not None else _grid_start(tau, hv, delta_e_mm, pre_mean_mm, dt)
    )
    span = float(tau.max())
    x0 = np.array([pre_mean_mm, k0, min(max(l0, 0.0), span), max(t0, 1e-3)])
    res = optimize.least_squares(
        lambda p: _model(tau, delta_e_mm, p) - hv,
        x0,
        jac=lambda p: _jacobian(tau, delta_e_mm, p),
        bounds=([-np.inf, -np.inf, 0.0, 1e-3], [np.inf, np.inf, span, np.inf]),
        x_scale="jac",
        method="trf",
    )
    if not np.all(np.isfinite(res.x)):
        raise IdentificationError(f"FOPDT fit failed: {res.message}")
    ssr = float(res.fun @ res.fun)
    se = _standard_errors(_jacobian(tau, delta_e_mm, res.x), ssr, tau.size)
    return FopdtFit(
        gain_mm_per_mm=float(res.x[1]),
        time_constant_s=float(res.x[3]),
        dead_time_s=float(res.x[2]),
        baseline_mm=float(res.x[0]),
        gain_se_mm_per_mm=float(se[1]),
        time_constant_se_s=float(se[3]),
        dead_time_se_s=float(se[2]),
        baseline_se_mm=float(se[0]),
        rmse_mm=float(np.sqrt(ssr / tau.size)),
        n=int(tau.size),
        onset_time_s=float(onset_time_s),
        delta_e_mm=float(delta_e_mm),
        converged=bool(res.success),
    )
