"""A flume scenario: piecewise-constant schedules of the commanded opening and the discharge.

Shared by the reference suite (:mod:`gatetwin.flume.experiments`) and the envelope records
(:mod:`gatetwin.flume.envelope`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from gatetwin.errors import FlumeError

__all__ = ["Breakpoints", "Scenario", "with_inflow"]

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


def with_inflow(scn: Scenario, start_s: float, extra_m3h: float) -> Scenario:
    """``scn`` with ``extra_m3h`` more discharge from ``start_s`` on (an inflow that a meter
    logging ``scn``'s discharge would not see); the same seed, so the same logger noise.

    Raises
    ------
    FlumeError
        ``start_s`` outside ``(0, duration_s)`` or a discharge that is not > 0.
    """
    if not (math.isfinite(start_s) and 0.0 < start_s < scn.duration_s):
        raise FlumeError(f"scenario {scn.name}: inflow start {start_s!r} s must lie in "
                         f"(0, {scn.duration_s:g}) s")  # fmt: skip
    before = tuple((t, q) for t, q in scn.flow_m3h if t < start_s)
    at = before[-1][1] if not any(t == start_s for t, _ in scn.flow_m3h) else None
    after = tuple((t, q + extra_m3h) for t, q in scn.flow_m3h if t >= start_s)
    head = ((start_s, at + extra_m3h),) if at is not None else ()
    return replace(scn, flow_m3h=before + head + after)


def _hold(bps: Breakpoints, t: np.ndarray) -> np.ndarray:
    times = np.array([b[0] for b in bps])
    values = np.array([b[1] for b in bps])
    return values[np.searchsorted(times, t, side="right") - 1]
