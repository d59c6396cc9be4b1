"""Static rating relation H(Q, e) per gauge, fitted from quasi-steady data.

A physically based gate relation rather than a black-box surface: free underflow

    Q = Cd · b · e · sqrt(2 g h),     H_g = 1000 · h − offset_g

with ``h`` the depth at the gate (m), ``b`` the channel width, and an effective discharge
coefficient that varies with the opening ratio ``r = e/h`` and with discharge,

    Cd = c∞ + (c0 + c1·q − c∞) · exp(−(k0 + k1·q)·r),     q = Q / Q_s,

(Cd falls from its small-opening value towards c∞ as the gate opens relative to the depth,
at a rate and from a level that depend on discharge — the shape the reference study's
levels imply),

and a per-gauge ``offset_g`` (mm) that carries the bed slope between the gate and the gauge
and the gauge's datum. The fit minimises level residuals (mm), with each point's depth
found from the implicit relation by bisection. The rating gives the operating point of a
model and its static gain ∂H/∂e at any (Q, e).

The channel width ``b``, the discharge unit ``Q_s`` (m³/h) and the depth bracket come from
the data (:mod:`gatetwin.identification.physical_start`: the sidecar's ``gate_width_m``, the power
of ten at or above the table's discharge span, a power of two above the highest level).

Not for: dynamics, submerged gates (no tailwater data in the reference study).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from gatetwin.errors import IdentificationError

__all__ = ["G", "N_CD", "RatingFit", "Scale", "fit_rating", "fit_static_table", "scale_of"]

G = 9.81
N_CD = 5


@dataclass(frozen=True)
class RatingFit:
    """Fitted rating relation of one gauge.

    Attributes
    ----------
    gauge : str
        Gauge name.
    width_m : float
        Channel width used in the relation, m.
    cd_coefficients : tuple[float, ...]
        ``c∞, c0, c1, k0, k1`` of the Cd law (dimensionless).
    offset_mm : float
        Depth at the gate minus level at the gauge, mm.
    rmse_mm : float
        Root-mean-square level residual over the fitted points, mm.
    n_points : int
        Number of steady points fitted.
    flow_range_m3h, opening_range_mm : tuple[float, float]
        Range of the data (the relation's validity range).
    """

    gauge: str
    width_m: float
    cd_coefficients: tuple[float, ...]
    offset_mm: float
    rmse_mm: float
    n_points: int
    flow_range_m3h: tuple[float, float]
    opening_range_mm: tuple[float, float]
    #: Discharge unit of the Cd slopes, m³/h, and the depth bracket's top, m (a rating
    #: written before they were recorded had 100 m³/h and 5 m built in).
    flow_scale_m3h: float = 100.0
    depth_max_m: float = 5.0

    def level_mm(self, flow_m3h: Any, opening_mm: Any) -> np.ndarray:
        """Steady level at the gauge, mm, for discharge (m³/h) and opening (mm)."""
        theta = np.array([*self.cd_coefficients, self.offset_mm])
        return _level_mm(theta, np.asarray(flow_m3h, float), np.asarray(opening_mm, float),
                         self.width_m, Scale(self.flow_scale_m3h, self.depth_max_m))  # fmt: skip

    def static_gain(self, flow_m3h: float, opening_mm: float, step_mm: float = 0.5) -> float:
        """∂H/∂e at (Q, e), mm/mm, by a central difference of ``step_mm``."""
        hi = self.level_mm(flow_m3h, opening_mm + step_mm)
        lo = self.level_mm(flow_m3h, opening_mm - step_mm)
        return float((hi - lo) / (2 * step_mm))

    def secant_gain(self, flow_m3h: float, before_mm: float, after_mm: float) -> float:
        """ΔH/Δe between two openings at one discharge, mm/mm (Table 5's static gain)."""
        d = self.level_mm(flow_m3h, after_mm) - self.level_mm(flow_m3h, before_mm)
        return float(d / (after_mm - before_mm))

    def to_dict(self) -> dict[str, Any]:
        return {
            "gauge": self.gauge,
            "relation": "Q = Cd*b*e*sqrt(2*g*h); H = 1000*h - offset_mm; "
            "Cd = c_inf + (c0 + c1*q - c_inf)*exp(-(k0 + k1*q)*r), r = e/h, q = Q/flow_scale_m3h",
            "width_m": self.width_m,
            "flow_scale_m3h": self.flow_scale_m3h,
            "depth_max_m": self.depth_max_m,
            "cd_coefficients": list(self.cd_coefficients),
            "offset_mm": self.offset_mm,
            "rmse_mm": self.rmse_mm,
            "n_points": self.n_points,
            "flow_range_m3h": list(self.flow_range_m3h),
            "opening_range_mm": list(self.opening_range_mm),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RatingFit:
        return cls(
            gauge=str(data["gauge"]),
            width_m=float(data["width_m"]),
            cd_coefficients=tuple(float(c) for c in data["cd_coefficients"]),
            offset_mm=float(data["offset_mm"]),
            rmse_mm=float(data["rmse_mm"]),
            n_points=int(data["n_points"]),
            flow_range_m3h=tuple(data["flow_range_m3h"]),  # type: ignore[arg-type]
            opening_range_mm=tuple(data["opening_range_mm"]),  # type: ignore[arg-type]
            flow_scale_m3h=float(data.get("flow_scale_m3h", 100.0)),
            depth_max_m=float(data.get("depth_max_m", 5.0)),
        )


def _cd(theta: np.ndarray, r: np.ndarray, qs: np.ndarray) -> np.ndarray:
    c_inf, c0, c1, k0, k1 = theta[:N_CD]
    return c_inf + (c0 + c1 * qs - c_inf) * np.exp(-(k0 + k1 * qs) * r)


def _gate_depth_m(theta: np.ndarray, flow_m3h: np.ndarray, opening_mm: np.ndarray,
                  width_m: float, scale: Scale) -> np.ndarray:  # fmt: skip
    """Depth h solving Q = Cd(e/h, Q)·b·e·sqrt(2gh) (bisection; the residual rises with h)."""
    q = flow_m3h / 3600.0
    e = opening_mm / 1000.0
    lo = np.maximum(e, 1e-3) * 0.5
    hi = np.full_like(q, scale.depth_max_m)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        cd = _cd(theta, e / mid, flow_m3h / scale.flow_m3h)
        passed = cd * width_m * e * np.sqrt(2 * G * mid)
        below = passed < q
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def _level_mm(theta: np.ndarray, flow_m3h: np.ndarray, opening_mm: np.ndarray,
              width_m: float, scale: Scale) -> np.ndarray:  # fmt: skip
    return 1000.0 * _gate_depth_m(theta, flow_m3h, opening_mm, width_m, scale) - theta[N_CD]


def fit_rating(
    flow_m3h: np.ndarray, opening_mm: np.ndarray, level_mm: np.ndarray, *, gauge: str,
    width_m: float, scale: Scale | None = None,
) -> RatingFit:  # fmt: skip
    """Fit the rating relation of one gauge to steady points (NaN levels skipped)."""
    q, e, h = (np.asarray(v, dtype=float) for v in (flow_m3h, opening_mm, level_mm))
    ok = np.isfinite(q) & np.isfinite(e) & np.isfinite(h) & (q > 0) & (e > 0)
    q, e, h = q[ok], e[ok], h[ok]
    if q.size < N_CD + 2:
        raise IdentificationError(
            f"rating {gauge}: {q.size} usable steady points; the relation needs at least {N_CD + 2}"
        )
    scale = scale or scale_of(q, h)
    # dimensionless Cd starts and bounds; the offset within the highest level either way
    # (a gauge datum farther than the depth itself is no offset)
    top = max(100.0, float(np.max(np.abs(h))))
    theta0 = np.array([0.55, 0.95, 0.0, 3.0, 0.0, 0.0])
    lower = [0.2, 0.3, -2.0, 0.0, -20.0, -top]
    upper = [1.2, 2.0, 2.0, 50.0, 50.0, top]
    result = least_squares(
        lambda th: _level_mm(th, q, e, width_m, scale) - h, theta0, bounds=(lower, upper),
        x_scale="jac",
    )  # fmt: skip
    resid = result.fun
    return RatingFit(
        gauge=gauge,
        width_m=width_m,
        cd_coefficients=tuple(float(c) for c in result.x[:N_CD]),
        offset_mm=float(result.x[N_CD]),
        rmse_mm=float(np.sqrt(np.mean(resid**2))),
        n_points=int(q.size),
        flow_range_m3h=(float(q.min()), float(q.max())),
        opening_range_mm=(float(e.min()), float(e.max())),
        flow_scale_m3h=scale.flow_m3h,
        depth_max_m=scale.depth_max_m,
    )


def fit_static_table(table: Any, width_m: float) -> dict[str, RatingFit]:
    """One :class:`RatingFit` per gauge of a :class:`~gatetwin.records.StaticTable`, with
    the gate's width ``width_m`` (m)."""
    return {
        g: fit_rating(
            table.flow_m3h, table.opening_mm, table.levels_mm[g], gauge=g, width_m=width_m
        )  # fmt: skip
        for g in table.gauges
    }


@dataclass(frozen=True)
class Scale:
    """The discharge unit of the Cd law's slopes (m³/h) and the depth bracket's top (m)."""

    flow_m3h: float
    depth_max_m: float


def scale_of(flow_m3h: np.ndarray, level_mm: np.ndarray) -> Scale:
    """The power of ten at or above the discharge span; a power of two at or above four
    times the highest level (as :mod:`gatetwin.identification.physical_start`)."""
    q = np.asarray(flow_m3h, float)
    span = float(q.max() - q.min()) if q.max() > q.min() else max(float(q.max()), 1.0)
    top = 4.0 * float(np.max(level_mm)) / 1000.0
    return Scale(10.0 ** math.ceil(math.log10(span)), 2.0 ** math.ceil(math.log2(max(top, 1e-3))))
