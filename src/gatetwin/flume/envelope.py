"""Validation records across the flume's calibrated envelope (never fitted).

The fitted records (A–D, Q40–Q85) and the held-out Q55 lie on one operating line: the
opening an operator would hold for each discharge. A twin validated only there says nothing
about the rest of the gate. The records here span the envelope the flume is calibrated
over — Q 30–80 m³/h, openings 15–75 mm, levels 100–360 mm at every gauge — with wide
multi-step gate moves, discharge steps at a fixed gate, both at once, and a random
sequence. Their sidecars carry ``role: validation``: identification reads them but never
fits them; the run only validates models against them.

Every scenario is a :class:`~gatetwin.flume.experiments.Scenario` of piecewise-constant
breakpoints, like any scenario file. Every input pair held for longer than a time constant
has its steady level at every gauge inside the band with :data:`LEVEL_MARGIN_MM` to spare
(see :func:`steady_levels_mm`); pairs held briefly (a discharge change 20–30 s before the
gate follows it) move the level only part of the way, and the tests check the logged
levels over each whole record.
"""

from __future__ import annotations

import numpy as np

from gatetwin.errors import FlumeError
from gatetwin.flume.config import FlumeConfig
from gatetwin.flume.scenario import Breakpoints, Scenario
from gatetwin.flume.simulate import steady_gate_depth_m
from gatetwin.records.sidecar import VALIDATION_ROLE

__all__ = [
    "ENVELOPE_FLOW_M3H",
    "ENVELOPE_LEVEL_MM",
    "ENVELOPE_OPENING_MM",
    "LEVEL_MARGIN_MM",
    "START_S",
    "both_scenario",
    "envelope_openings_mm",
    "envelope_scenarios",
    "flow_steps_scenario",
    "in_band",
    "moves_scenario",
    "random_moves_scenario",
    "steady_levels_mm",
]

#: Discharge span of the calibrated envelope, m³/h.
ENVELOPE_FLOW_M3H = (30.0, 80.0)
#: Opening span of the calibrated envelope, mm.
ENVELOPE_OPENING_MM = (15.0, 75.0)
#: Level band every gauge must stay within, mm (the gauges' calibrated range in the flume).
ENVELOPE_LEVEL_MM = (100.0, 360.0)
#: Room kept between a steady level and the band's edges, mm: the largest logger spike
#: (15 mm) plus three times the largest surface-fluctuation SD (2.5 mm).
LEVEL_MARGIN_MM = 22.5
#: Steady start before the first change of every scenario, s (as in the step tests).
START_S = 180.0


def steady_levels_mm(cfg: FlumeConfig, flow_m3h: float, opening_mm: float) -> dict[str, float]:
    """Steady level each gauge would read at constant inputs, mm.

    The water surface upstream of the gate is nearly level at these Froude numbers
    (< 0.15), so the depth at a gauge ``x`` m upstream is the gate's steady depth less the
    bed's fall over ``x`` (``bed_slope · x``), plus the gauge's datum offset. Friction and
    velocity head add less than 1 mm over the 3 m to gauge 1D.

    Parameters
    ----------
    cfg : FlumeConfig
        The flume.
    flow_m3h : float
        Discharge, m³/h.
    opening_mm : float
        Gate opening, mm.

    Returns
    -------
    dict[str, float]
        Gauge name → level, mm.
    """
    gate_mm = 1000.0 * steady_gate_depth_m(cfg, flow_m3h, opening_mm)
    return {
        g: gate_mm - 1000.0 * cfg.bed_slope * x_m + cfg.gauge_datum_mm.get(g, 0.0)
        for g, x_m in cfg.gauges_m.items()
    }


def in_band(cfg: FlumeConfig, flow_m3h: float, opening_mm: float) -> bool:
    """Whether every gauge's steady level lies in the band with :data:`LEVEL_MARGIN_MM`."""
    lo, hi = ENVELOPE_LEVEL_MM
    levels = steady_levels_mm(cfg, flow_m3h, opening_mm).values()
    return all(lo + LEVEL_MARGIN_MM <= v <= hi - LEVEL_MARGIN_MM for v in levels)


def envelope_openings_mm(cfg: FlumeConfig, flow_m3h: float) -> tuple[float, float]:
    """Smallest and largest whole-millimetre opening in the envelope at ``flow_m3h``, mm.

    Raises
    ------
    FlumeError
        If no opening of the envelope keeps the levels in the band at this discharge.
    """
    lo, hi = (int(v) for v in ENVELOPE_OPENING_MM)
    ok = [float(e) for e in range(lo, hi + 1) if in_band(cfg, flow_m3h, e)]
    if not ok:
        raise FlumeError(f"no opening keeps the levels in the band at Q = {flow_m3h} m³/h")
    return ok[0], ok[-1]


def _timed(values: list[float], hold_s: float) -> Breakpoints:
    """``values`` in turn: the first from t = 0, each next after ``START_S`` + k·``hold_s``."""
    return tuple((0.0 if k == 0 else START_S + (k - 1) * hold_s, v) for k, v in enumerate(values))


def moves_scenario(
    name: str, flow_m3h: float, openings_mm: list[float], hold_s: float, seed: int
) -> Scenario:
    """Gate moves through ``openings_mm`` at one discharge, ``hold_s`` seconds each.

    Parameters
    ----------
    name : str
        Record name.
    flow_m3h : float
        Constant discharge, m³/h.
    openings_mm : list of float
        Openings in turn, mm; the first holds for ``START_S``, each later for ``hold_s``.
    hold_s : float
        Hold after each move, s (five time constants for the level to settle).
    seed : int
        Logger seed.
    """
    path = " -> ".join(f"{e:g}" for e in openings_mm)
    return Scenario(
        name, ((0.0, flow_m3h),), _timed(openings_mm, hold_s),
        START_S + (len(openings_mm) - 1) * hold_s, seed, "free",
        {"description": f"gate moves {path} mm at Q = {flow_m3h:g} m3/h, {hold_s:g} s holds",
         "role": VALIDATION_ROLE},
    )  # fmt: skip


def flow_steps_scenario(
    name: str, opening_mm: float, flows_m3h: list[float], hold_s: float, seed: int
) -> Scenario:
    """Discharge steps through ``flows_m3h`` with the gate fixed at ``opening_mm``.

    Parameters are as for :func:`moves_scenario`, with the roles of Q and opening swapped.
    """
    path = " -> ".join(f"{q:g}" for q in flows_m3h)
    return Scenario(
        name, _timed(flows_m3h, hold_s), ((0.0, opening_mm),),
        START_S + (len(flows_m3h) - 1) * hold_s, seed, "free",
        {"description": f"Q steps {path} m3/h at e = {opening_mm:g} mm (gate fixed), "
         f"{hold_s:g} s holds", "role": VALIDATION_ROLE},
    )  # fmt: skip


def random_moves_scenario(
    name: str, flow_m3h: float, seed: int, *, n_moves: int = 16,
    hold_range_s: tuple[float, float] = (60.0, 240.0), min_move_mm: float = 3.0,
    cfg: FlumeConfig | None = None,
) -> Scenario:  # fmt: skip
    """Random gate moves at one discharge: openings and hold times drawn from ``seed``.

    Openings are whole millimetres drawn uniformly over :func:`envelope_openings_mm` at
    ``flow_m3h``, each at least ``min_move_mm`` from the previous one; holds are uniform
    over ``hold_range_s`` (some shorter than the level's settling, some longer). The same
    seed drives the logger.
    """
    cfg = cfg or FlumeConfig()
    lo, hi = envelope_openings_mm(cfg, flow_m3h)
    if hi - lo < min_move_mm:
        raise FlumeError(f"scenario {name}: openings {lo:g}-{hi:g} mm leave no move of "
                         f"{min_move_mm:g} mm at Q = {flow_m3h:g} m³/h")  # fmt: skip
    rng = np.random.default_rng(seed)
    openings = [float(rng.integers(lo, hi + 1))]
    while len(openings) <= n_moves:
        e = float(rng.integers(lo, hi + 1))
        if abs(e - openings[-1]) >= min_move_mm:
            openings.append(e)
    holds = rng.uniform(*hold_range_s, size=n_moves)
    times = np.concatenate([[0.0], START_S + np.concatenate([[0.0], np.cumsum(holds[:-1])])])
    bps = tuple((round(float(t), 1), e) for t, e in zip(times, openings, strict=True))
    duration = round(START_S + float(np.sum(holds)), 1)
    return Scenario(
        name, ((0.0, flow_m3h),), bps, duration, seed, "free",
        {"description": f"{n_moves} random gate moves over {lo:g}-{hi:g} mm at "
         f"Q = {flow_m3h:g} m3/h, holds {hold_range_s[0]:g}-{hold_range_s[1]:g} s "
         f"(seed {seed})", "role": VALIDATION_ROLE},
    )  # fmt: skip


def both_scenario(name: str, seed: int) -> Scenario:
    """Gate moves and discharge changes overlapping in time.

    Each discharge change is followed 20–30 s later (inside the level's response to it) by
    a gate move, and the next change comes after 270 s; the final pair moves the gate
    before the discharge. Steady states: (Q, e) = (45, 25), (65, 35), (50, 45), (75, 50),
    (40, 30) in m³/h and mm.
    """
    flows = ((0.0, 45.0), (180.0, 65.0), (480.0, 50.0), (780.0, 75.0), (1100.0, 40.0))
    openings = ((0.0, 25.0), (200.0, 35.0), (510.0, 45.0), (800.0, 50.0), (1080.0, 30.0))
    return Scenario(
        name, flows, openings, 1400.0, seed, "free",
        {"description": "Q and gate change together: Q 45 -> 65 -> 50 -> 75 -> 40 m3/h, "
         "e 25 -> 35 -> 45 -> 50 -> 30 mm, each gate move inside the response to a Q change",
         "role": VALIDATION_ROLE},
    )  # fmt: skip


def envelope_scenarios() -> list[Scenario]:
    """The validation records across the envelope (seeds 111–116)."""
    return [
        moves_scenario("Emoves35", 35.0, [15.0, 20.0, 25.0, 30.0, 25.0, 20.0, 15.0], 360.0, 111),
        moves_scenario("Emoves75", 75.0, [40.0, 50.0, 60.0, 75.0, 60.0, 50.0, 40.0], 240.0, 112),
        flow_steps_scenario("EflowLow", 24.0, [30.0, 50.0, 35.0], 360.0, 113),
        flow_steps_scenario("EflowHigh", 45.0, [55.0, 80.0, 65.0], 300.0, 114),
        both_scenario("Eboth", 115),
        random_moves_scenario("Erandom60", 60.0, 116),
    ]
