"""Hidden effects that appear at a known time in a measured record: the test bed of online
detection (:class:`gatetwin.mpc.online.OnlineObserver`, the observer FMU).

:func:`with_onset` returns a record's level as the gauge would have logged it had one effect
appeared at sample ``onset``; before it nothing changes. The effects are what a gate keeper
fears on a running canal, each stated physically:

* ``sensor_drift`` — the gauge's zero drifts at ``rate_mm_per_s``;
* ``sensor_lag`` — the gauge starts reporting a first-order filtered level (a fouled stilling
  well), time constant ``time_constant_s``;
* ``seiche`` — a standing wave is set off (wind, a passing boat): ``amplitude_mm``,
  ``period_s``, ``decay_time_s``;
* ``unmeasured_inflow`` — an inflow the flow meter does not see, ``flow_m3h``;
* ``stuck_gate`` — the gate stays where it is; the log goes on showing the commands;
* ``slowed_gate`` — the gate follows its commands at ``rate_mm_per_s`` only.

The last three change what the pool receives; their effect on the level is the difference of
two simulations of the truth ``plant`` (:func:`gatetwin.plant.simulate.simulate`), with and
without the change, added to the measured level: the record keeps its own noise and its own
model mismatch. :func:`detection` reads an anomaly flag against the onset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gatetwin.errors import OnsetError
from gatetwin.plant.model import FopdtPlant
from gatetwin.plant.simulate import simulate

#: The effects, with the parameters each is injected with by default: material for the
#: flume's pools (3F: K ≈ −12 mm/mm, T ≈ 60 s, gauge noise ≈ 1 mm) and ordinary in a canal.
#: A drift of 0.6 mm/min; a lag of 10 s (a sixth of the pool's time constant); a seiche of
#: 3 mm at the flume's own period (11.5 s) dying out over a minute; an unseen inflow of 5 m³/h
#: (≈ 10 % of the discharge); a gate at a tenth of a mm per second (a move of 5 mm takes 50 s
#: instead of one sample).
ONSET_EFFECTS: dict[str, dict[str, float]] = {
    "sensor_drift": {"rate_mm_per_s": 0.01},
    "sensor_lag": {"time_constant_s": 10.0},
    "seiche": {"amplitude_mm": 3.0, "period_s": 11.5, "decay_time_s": 60.0},
    "unmeasured_inflow": {"flow_m3h": 5.0},
    "stuck_gate": {},
    "slowed_gate": {"rate_mm_per_s": 0.1},
}


def with_onset(
    plant: FopdtPlant,
    time_s: np.ndarray,
    level_mm: np.ndarray,
    opening_mm: np.ndarray,
    flow_m3h: np.ndarray,
    effect: str,
    onset: int,
    **parameters: float,
) -> np.ndarray:
    """The level the gauge logs when ``effect`` appears at sample ``onset`` (see the module).

    ``opening_mm`` is the logged command (finite at every sample), ``plant`` the truth for
    the effects that change what the pool receives. Missing parameters take
    :data:`ONSET_EFFECTS`' values.
    """
    if effect not in ONSET_EFFECTS:
        raise OnsetError(f"unknown effect {effect!r}; expected one of {', '.join(ONSET_EFFECTS)}")
    t, y, e, q = (np.asarray(v, dtype=float) for v in (time_s, level_mm, opening_mm, flow_m3h))
    if not (isinstance(onset, int) and 1 <= onset < t.size):
        raise OnsetError(f"onset {onset!r} must be a sample index in [1, {t.size - 1}]")
    unknown = set(parameters) - set(ONSET_EFFECTS[effect])
    if unknown:
        raise OnsetError(f"{effect} has no parameter {', '.join(sorted(unknown))}")
    p = {**ONSET_EFFECTS[effect], **parameters}
    if not all(math.isfinite(v) for v in p.values()):
        raise OnsetError(f"{effect}: parameters must be finite ({p})")
    after = np.arange(t.size) >= onset
    tau = np.where(after, t - t[onset], 0.0)
    out = y.copy()
    if effect == "sensor_drift":
        out += p["rate_mm_per_s"] * tau
    elif effect == "sensor_lag":
        out[onset:] = _lagged(t[onset:], y[onset:], p["time_constant_s"])
    elif effect == "seiche":
        wave = np.exp(-tau / p["decay_time_s"]) * np.sin(2.0 * math.pi * tau / p["period_s"])
        out += np.where(after, p["amplitude_mm"] * wave, 0.0)
    else:
        e_true, q_true = _received(effect, p, e, q, after, onset, t)
        out += simulate(plant, t, e_true, q_true) - simulate(plant, t, e, q)
    return out


def _lagged(t: np.ndarray, y: np.ndarray, time_constant_s: float) -> np.ndarray:
    out = np.empty_like(y)
    out[0] = y[0]
    for k in range(1, y.size):
        a = math.exp(-(t[k] - t[k - 1]) / time_constant_s)
        out[k] = a * out[k - 1] + (1.0 - a) * y[k]
    return out


def _received(
    effect: str, p: dict[str, float], e: np.ndarray, q: np.ndarray, after: np.ndarray,
    onset: int, t: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """The opening and discharge the pool really gets."""
    if effect == "unmeasured_inflow":
        return e, q + np.where(after, p["flow_m3h"], 0.0)
    gate = e.copy()
    if effect == "stuck_gate":
        gate[onset:] = e[onset - 1]
        return gate, q
    for k in range(onset, e.size):
        step = p["rate_mm_per_s"] * (t[k] - t[k - 1])
        gate[k] = gate[k - 1] + float(np.clip(e[k] - gate[k - 1], -step, step))
    return gate, q


def first_move_after(time_s: np.ndarray, opening_mm: np.ndarray, fraction: float = 0.4) -> int:
    """Index of the first opening change at or after ``fraction`` of the record's span: an
    onset at a gate move, so that a gate fault appears at once."""
    t, e = np.asarray(time_s, dtype=float), np.asarray(opening_mm, dtype=float)
    start = t[0] + fraction * (t[-1] - t[0])
    moves = np.flatnonzero((t[1:] >= start) & (np.diff(e) != 0.0)) + 1
    if moves.size == 0:
        raise OnsetError(f"no gate move after {start:g} s")
    return int(moves[0])


@dataclass(frozen=True)
class Detection:
    """An anomaly flag read against a known onset.

    Attributes
    ----------
    delay_s : float
        From the onset to the first flagged sample at or after it, s (NaN: never flagged).
    false_alarms : int
        Times the flag rose before the onset.
    """

    delay_s: float
    false_alarms: int

    def to_dict(self) -> dict[str, Any]:
        return {"delay_s": None if math.isnan(self.delay_s) else self.delay_s,
                "false_alarms": self.false_alarms}  # fmt: skip


def detection(time_s: np.ndarray, anomaly: np.ndarray, onset: int | None) -> Detection:
    """Read ``anomaly`` (0/1 per sample) against ``onset`` (``None``: a clean record)."""
    flag = np.asarray(anomaly) > 0.5
    end = flag.size if onset is None else onset
    rises = np.flatnonzero(flag[:end] & ~np.r_[False, flag[: end - 1]]) if end else []
    if onset is None:
        return Detection(math.nan, len(rises))
    hit = np.flatnonzero(flag[onset:])
    delay = float(time_s[onset + hit[0]] - time_s[onset]) if hit.size else math.nan
    return Detection(delay, len(rises))


__all__ = ["ONSET_EFFECTS", "Detection", "OnsetError", "detection", "first_move_after",
           "with_onset"]  # fmt: skip
