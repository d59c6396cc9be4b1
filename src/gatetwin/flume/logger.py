"""The data logger of the virtual flume: what the instruments would have written.

Turns a noise-free :class:`~gatetwin.flume.simulate.FlumeRun` into a record in the users'
format (``docs/record_format.md``): gauge datums, surface fluctuations and sensor noise, 0.1 mm
resolution, occasional spikes, the actuator's ``hold``/``open`` flag with the opening left
empty while it moves, the flow meter's noise, and small timestamp jitter.

Noise model (calibrated to the standard deviations of Tables 2–3): each gauge reads
``depth + datum + f_g·σ(Fr)·n(t) + w(t)`` where ``n`` is unit-variance AR(1) noise with a
correlation time of a few seconds (surface waves), ``σ(Fr) = sigma0·exp(growth·(Fr − fr0))``
grows with the local Froude number (the paper's SDs are 0.3–0.4 mm in calm condition A
before the step and 1.4–2.4 mm after it, when the faster, shallower flow is rougher),
``f_g`` a per-gauge factor that varies with Q, and ``w`` white sensor noise.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gatetwin._io import write_json_atomic, write_text_atomic
from gatetwin.flume.config import FlumeConfig
from gatetwin.flume.gate import G
from gatetwin.flume.simulate import FlumeRun

__all__ = ["FLUME_VERSION", "LoggedRecord", "LoggerConfig", "froude", "log_run"]

FLUME_VERSION = "1.0"


@dataclass(frozen=True)
class LoggerConfig:
    """Instrument and noise settings of the logger (see module docstring).

    Attributes
    ----------
    sigma0_mm, fr0, growth : float
        Surface-fluctuation SD ``sigma0_mm`` at Froude number ``fr0``, and its growth rate.
    sigma_max_mm : float
        Cap on the fluctuation SD, 2.5 mm: the largest SD published (2.43 mm); beyond the
        Froude numbers of Tables 2–3 the exponential is not extrapolated.
    correlation_s : float
        Correlation time of the fluctuations, s.
    gauge_factor : dict[str, float]
        Per-gauge multiplier of the fluctuation SD at the two flows
        ``gauge_factor_flow_m3h`` (linear in Q between them, clamped outside): each gauge's
        published pre-step SD over the mean of the five in Table 2 (A) and Table 3 (B).
        The published SDs rank the gauges differently in A and B, and the paper's dead
        times follow them (L is a 3σ detection delay), so the factor follows Q.
    sensor_sd_mm : float
        White sensor noise, mm.
    level_resolution_mm : float
        Gauge resolution, 0.1 mm (paper).
    spike_probability : float
        Chance per sample and gauge of a spike.
    spike_mm : tuple[float, float]
        Range of spike magnitudes, mm (sign random).
    flow_sd_fraction, flow_resolution_m3h : float
        Flow-meter noise (repeatability 0.16 % of reading) and resolution.
    jitter_s : float
        SD of the timestamp jitter, s.
    """

    sigma0_mm: float = 0.33
    fr0: float = 0.078
    growth: float = 31.0
    sigma_max_mm: float = 2.5
    correlation_s: float = 1.5
    gauge_factor_flow_m3h: tuple[float, float] = (29.5, 72.5)
    gauge_factor: dict[str, tuple[float, float]] = field(
        default_factory=lambda: {
            "1D": (0.91, 1.19), "2E": (0.94, 1.15), "3F": (1.00, 0.63),
            "4G": (1.11, 1.36), "5H": (1.09, 0.67),
        }
    )  # fmt: skip
    sensor_sd_mm: float = 0.1
    level_resolution_mm: float = 0.1
    spike_probability: float = 0.0005
    spike_mm: tuple[float, float] = (5.0, 15.0)
    flow_sd_fraction: float = 0.0016
    flow_resolution_m3h: float = 0.1
    jitter_s: float = 0.004


@dataclass(frozen=True)
class LoggedRecord:
    """Columns of a record as the logger writes them (NaN = empty cell)."""

    time_s: np.ndarray
    opening_mm: np.ndarray
    hold: np.ndarray
    flow_m3h: np.ndarray
    levels_mm: dict[str, np.ndarray]
    sidecar: dict[str, Any]

    def to_csv(self) -> str:
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        gauges = list(self.levels_mm)
        writer.writerow(
            ["time_s", "opening_mm", "state", "flow_m3h", *[f"level_{g}_mm" for g in gauges]]
        )
        for k in range(self.time_s.size):
            writer.writerow(
                [
                    f"{self.time_s[k]:.3f}",
                    "" if np.isnan(self.opening_mm[k]) else f"{self.opening_mm[k]:.0f}",
                    "hold" if self.hold[k] else "open",
                    f"{self.flow_m3h[k]:.1f}",
                    *[f"{self.levels_mm[g][k]:.1f}" for g in gauges],
                ]
            )
        return buf.getvalue()

    def write(self, csv_path: str | Path) -> Path:
        """Write ``NAME.csv`` and its sidecar ``NAME.json``."""
        path = Path(csv_path)
        write_text_atomic(path, self.to_csv())
        write_json_atomic(path.with_suffix(".json"), self.sidecar)
        return path


def froude(depth_mm: np.ndarray, flow_m3h: np.ndarray, width_m: float) -> np.ndarray:
    h = depth_mm / 1000.0
    v = flow_m3h / 3600.0 / (width_m * h)
    return v / np.sqrt(G * h)


def _ar1(rng: np.random.Generator, n: int, phi: float) -> np.ndarray:
    e = rng.standard_normal(n) * np.sqrt(1.0 - phi * phi)
    out = np.empty(n)
    acc = rng.standard_normal()
    for k in range(n):
        acc = phi * acc + e[k]
        out[k] = acc
    return out


def _gauge_reading(
    rng: np.random.Generator, depth: np.ndarray, fr: np.ndarray, factor: np.ndarray,
    datum: float, lc: LoggerConfig, dt: float,
) -> np.ndarray:  # fmt: skip
    sigma = np.minimum(lc.sigma0_mm * np.exp(lc.growth * (fr - lc.fr0)), lc.sigma_max_mm)
    phi = float(np.exp(-dt / lc.correlation_s))
    level = depth + datum + factor * sigma * _ar1(rng, depth.size, phi)
    level = level + lc.sensor_sd_mm * rng.standard_normal(depth.size)
    spikes = rng.random(depth.size) < lc.spike_probability
    mags = rng.uniform(*lc.spike_mm, size=depth.size) * rng.choice([-1.0, 1.0], size=depth.size)
    level = np.where(spikes, level + mags, level)
    return np.round(level / lc.level_resolution_mm) * lc.level_resolution_mm


def _factor(lc: LoggerConfig, gauge: str, flow_m3h: np.ndarray) -> np.ndarray:
    f0, f1 = lc.gauge_factor.get(gauge, (1.0, 1.0))
    q0, q1 = lc.gauge_factor_flow_m3h
    w = np.clip((flow_m3h - q0) / (q1 - q0), 0.0, 1.0)
    return f0 + w * (f1 - f0)


def log_run(
    run: FlumeRun,
    cfg: FlumeConfig,
    seed: int,
    *,
    logger: LoggerConfig | None = None,
    sidecar: dict[str, Any] | None = None,
) -> LoggedRecord:
    """What the instruments write for ``run`` (deterministic for a given ``seed``)."""
    lc = logger or LoggerConfig()
    rng = np.random.default_rng(seed)
    hold = ~run.moving & (np.abs(run.position_mm - run.command_mm) < 1e-9)
    opening = np.where(hold, np.round(run.position_mm / cfg.actuator_resolution_mm), np.nan)
    opening = opening * cfg.actuator_resolution_mm
    levels = {}
    for g, depth in run.depth_mm.items():
        fr = froude(depth, run.flow_m3h, cfg.width_m)
        levels[g] = _gauge_reading(
            rng, depth, fr, _factor(lc, g, run.flow_m3h), cfg.gauge_datum_mm.get(g, 0.0), lc,
            cfg.sample_period_s,
        )  # fmt: skip
    flow = run.flow_m3h * (1.0 + lc.flow_sd_fraction * rng.standard_normal(run.flow_m3h.size))
    flow = np.round(flow / lc.flow_resolution_m3h) * lc.flow_resolution_m3h
    jitter = np.clip(lc.jitter_s * rng.standard_normal(run.time_s.size), -0.4, 0.4)
    jitter[0] = 0.0
    meta = {
        "synthetic": True,
        "generator": f"gatetwin virtual flume {FLUME_VERSION}",
        "flume_version": FLUME_VERSION,
        "seed": seed,
        "sample_period_s": cfg.sample_period_s,
        "gauges": dict(cfg.gauges_m),
        "gate_width_m": cfg.width_m,
        **(sidecar or {}),
    }
    return LoggedRecord(run.time_s + jitter, opening, hold, flow, levels, meta)
