"""A flume scenario: piecewise-constant schedules of the commanded opening and the discharge.

Shared by the reference suite (:mod:`gatetwin.flume.experiments`) and the envelope records
(:mod:`gatetwin.flume.envelope`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gatetwin.errors import FlumeError

Breakpoints = tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Scenario:
    """Piecewise-constant input schedules for one logged run.

    Attributes
    ----------
    name : str
        Record name (file stem).
    flow_m3h, opening_mm : tuple of (time_s, value)
        Breakpoints, the first at t = 0; each value holds until the next breakpoint.
    duration_s : float
        Length of the logged run, s.
    seed : int
        Logger seed (noise, spikes, jitter).
    test : str
        ``step``, ``prbs`` or ``free`` (written to the sidecar).
    meta : dict
        Extra sidecar fields (condition, role, description).
    """

    name: str
    flow_m3h: Breakpoints
    opening_mm: Breakpoints
    duration_s: float
    seed: int
    test: str = "free"
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.duration_s > 0:
            raise FlumeError(f"scenario {self.name}: duration_s must be > 0")
        for label, bps in (("flow_m3h", self.flow_m3h), ("opening_mm", self.opening_mm)):
            times = [t for t, _ in bps]
            if not bps or times[0] != 0 or np.any(np.diff(times) <= 0):
                raise FlumeError(
                    f"scenario {self.name}: {label} breakpoints must start at t = 0 and increase"
                )
            if not all(math.isfinite(v) and v > 0 for _, v in bps):
                raise FlumeError(f"scenario {self.name}: {label} values must be finite and > 0")
        if self.test not in ("step", "prbs", "free"):
            raise FlumeError(f"scenario {self.name}: test must be step, prbs or free")

    def sampled(self, sample_period_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Command and flow in force during the interval ending at each sample."""
        n = int(math.floor(self.duration_s / sample_period_s)) + 1
        t = np.arange(n) * sample_period_s
        t_in_force = np.maximum(t - 0.5 * sample_period_s, 0.0)
        return _hold(self.opening_mm, t_in_force), _hold(self.flow_m3h, t_in_force)


def _hold(bps: Breakpoints, t: np.ndarray) -> np.ndarray:
    times = np.array([b[0] for b in bps])
    values = np.array([b[1] for b in bps])
    return values[np.searchsorted(times, t, side="right") - 1]
