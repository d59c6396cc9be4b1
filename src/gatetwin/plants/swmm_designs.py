"""The designs of :mod:`gatetwin.plants.swmm_experiments` (rules in its docstring), and
:func:`run_design`, which measures the plant's step response and runs a design."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import max_len_seq

from gatetwin.errors import NotSteadyError, PlantError
from gatetwin.plants.swmm import SwmmCore
from gatetwin.plants.swmm_experiments import (
    DESIGNS,
    FIT_FLOW_FACTORS,
    HELD_OUT_FLOW_FACTOR,
    STATIC_FLOW_FACTORS,
    STATIC_OPENING_FACTORS,
    Schedule,
    StepResponse,
    check_in_bank,
    check_regime,
    gate_step_mm,
    measure_step,
    record_csv,
    run_schedule,
    sidecar,
)
from gatetwin.records.segments import STEP_WINDOW_SAMPLES

__all__ = [
    "Base",
    "InBank",
    "Output",
    "free_schedules",
    "prbs_schedule",
    "run_design",
    "static_table",
    "step_schedules",
]

Output = tuple[str, str, dict[str, Any]]


@dataclass(frozen=True)
class Base:
    """The operating point and the measured response every design is sized from."""

    opening_mm: float
    flow_m3h: float
    response: StepResponse
    sample_period_s: float
    gate_speed_mm_s: float

    def whole(self, seconds: float) -> float:
        """``seconds`` rounded up to whole samples, s."""
        return self.sample_period_s * max(1, math.ceil(seconds / self.sample_period_s))

    @property
    def settle_s(self) -> float:
        r = self.response
        return r.time_constant_s + r.dead_time_s


def step_schedules(b: Base) -> list[Schedule]:
    """Step tests on the operating line (opening ∝ flow), four fit and one held out; each
    hold at least the step method's window of samples long (a slow logger on a quick pool:
    at 60 s, a 1400 s time constant is 23 samples, and the reader refuses a step record
    with fewer than 40 before its step)."""
    window = (STEP_WINDOW_SAMPLES + 2) * b.sample_period_s
    pre = b.whole(max(b.response.time_constant_s, 5 * b.sample_period_s, window))
    post = b.whole(max(5 * b.settle_s, window))
    out = []
    factors = [(f, "fit") for f in FIT_FLOW_FACTORS] + [(HELD_OUT_FLOW_FACTOR, "held_out")]
    for f, role in factors:
        q, e = round(b.flow_m3h * f, 1), float(round(b.opening_mm * f))
        de = gate_step_mm(e)
        out.append(Schedule(
            f"step_Q{round(100 * f):03d}", "step", role, [(0.0, e), (pre, e + de)],
            [(0.0, q)], pre + post, f"step {e:g} -> {e + de:g} mm at Q = {q:g} m3/h",
        ))  # fmt: skip
    return out


def prbs_schedule(b: Base) -> Schedule:
    """A 63-bit maximum-length sequence of ± the gate step, clock T / 2."""
    bits = max_len_seq(6, state=np.ones(6, dtype=np.int8))[0]
    runs = np.diff(np.flatnonzero(np.diff(np.r_[-1, bits, -1]) != 0))
    de = b.response.step_mm
    clock = b.whole(b.response.time_constant_s / 2)
    travel = b.whole(2 * de / b.gate_speed_mm_s)
    t, level, bps = 0.0, bool(bits[0]), []
    for run_length in runs:
        bps.append((t, b.opening_mm + (de if level else -de)))
        t += travel + int(run_length) * clock
        level = not level
    return Schedule("prbs", "prbs", "fit", bps, [(0.0, b.flow_m3h)], t,
                    f"PRBS {b.opening_mm - de:g}/{b.opening_mm + de:g} mm at Q = "
                    f"{b.flow_m3h:g} m3/h, clock {clock:g} s")  # fmt: skip


def free_schedules(b: Base, seed: int) -> list[Schedule]:
    """Validation records: wide gate moves, inflow steps of ∓40 %, both, random."""
    hold, e, q, de = b.whole(3 * b.settle_s), b.opening_mm, b.flow_m3h, b.response.step_mm
    moves = [0, 1, 2, 3, 2, 1, 0, -1, -2, -1, 0]
    gate = [(i * hold, e + k * de) for i, k in enumerate(moves)]
    flows = [(0.0, q), (hold, round(0.6 * q, 1)), (3 * hold, q), (4 * hold, round(1.4 * q, 1)),
             (6 * hold, q)]  # fmt: skip
    both_gate = [(0.0, e), (hold, e + 2 * de), (3 * hold, e - de), (5 * hold, e)]
    rng = np.random.default_rng(seed)
    n = 12
    starts = np.cumsum(np.r_[0.0, [b.whole(x) for x in rng.uniform(1, 3, n - 1) * b.settle_s]])
    rand_e = [(float(s), e + de * float(rng.integers(-3, 4))) for s in starts]
    rand_q = [(float(s), round(q * float(rng.uniform(0.7, 1.3)), 1)) for s in starts]
    end = float(starts[-1]) + hold
    return [
        Schedule("free_moves", "free", "validation", gate, [(0.0, q)], len(moves) * hold,
                 f"gate moves {' -> '.join(f'{v:g}' for _, v in gate)} mm at Q = {q:g} m3/h"),
        Schedule("free_flow", "free", "validation", [(0.0, e)], flows, 7 * hold,
                 f"inflow {q:g} -> -40 % -> {q:g} -> +40 % -> {q:g} m3/h at e = {e:g} mm"),
        Schedule("free_both", "free", "validation", both_gate, flows, 7 * hold,
                 "gate moves and inflow steps of -40 % and +40 % together"),
        Schedule("free_random", "free", "validation", rand_e, rand_q, end,
                 f"random openings within ±{3 * de:g} mm and flows within ±30 %"),
    ]  # fmt: skip


class InBank:
    """Where a free record's holds may sit (rule in :mod:`gatetwin.plants.swmm_experiments`):
    each hold's steady level is measured on the plant, once per (opening, flow)."""

    def __init__(self, core: SwmmCore, b: Base) -> None:
        self.core = core
        self.step_mm = b.response.step_mm
        #: Room below the node's top: one gate step's level change, mm.
        self.margin_mm = abs(b.response.gain_mm_per_mm) * b.response.step_mm
        self._seen: dict[tuple[float, float], int] = {}

    def side(self, opening_mm: float, flow_m3h: float) -> int:
        """+1 when the steady level is too high (or there is none away from the gate's lip),
        -1 too low (at or under the lip: out of orifice regime), 0 in bank."""
        key = (opening_mm, flow_m3h)
        if key not in self._seen:
            core = self.core
            try:
                level = core.start(opening_mm, flow_m3h)
            except NotSteadyError as exc:
                # no steady state: a pool still rising to its top, or a level dithering at
                # the gate's lip (reaching it within the steady tolerance over the last
                # window), where SWMM switches the orifice between its weir and orifice laws
                lip = exc.low_mm <= opening_mm + core.spec.steady_tolerance_mm
                side = -1 if lip and not core.flooding() else 1
            except PlantError:
                side = 1  # no steady state: the pool overtops
            else:
                too_high = core.flooding() or level > core.top_mm() - self.margin_mm
                side = 1 if too_high else (-1 if level <= opening_mm else 0)
            self._seen[key] = side
        return self._seen[key]

    def opening(self, opening_mm: float, flow_m3h: float) -> float:
        """The opening nearest ``opening_mm``, in whole gate steps, whose hold is in bank; where
        the band of such openings is narrower than a gate step (the level jumps from below
        the gate's lip to the bank's margin within one step), the whole millimetre in it
        that bisection finds."""
        direction = self.side(opening_mm, flow_m3h)
        e = opening_mm
        while direction and self.side(e, flow_m3h) == direction:
            e += direction * self.step_mm
            if not self.step_mm <= e <= self.core.height_mm:
                raise PlantError(f"free records: no opening keeps Q = {flow_m3h:g} m³/h in bank "
                                 f"and in orifice regime near e = {opening_mm:g} mm")  # fmt: skip
        if not self.side(e, flow_m3h):
            return e
        near, far = e - direction * self.step_mm, e  # sides: ``direction``, then past the band
        while abs(far - near) > 1.0:
            middle = float(round(0.5 * (near + far)))
            side = self.side(middle, flow_m3h)
            if side == 0:
                return middle
            near, far = (middle, far) if side == direction else (near, middle)
        raise PlantError(
            f"free records: Q = {flow_m3h:g} m³/h is out of bank or out of "
            f"orifice regime at every opening near e = {opening_mm:g} mm"
        )

    def fit(self, sch: Schedule) -> Schedule:
        """``sch`` with every hold's opening moved in bank (its description says which)."""
        times = sorted({t for t, _ in sch.opening_mm} | {t for t, _ in sch.flow_m3h})
        gate: list[tuple[float, float]] = []
        moved = []
        for t in times:
            e, q = sch.at(t)
            new = self.opening(e, q)
            if new != e:
                moved.append(f"{e:g} -> {new:g} mm at Q = {q:g} m3/h")
            if not gate or gate[-1][1] != new:
                gate.append((t, new))
        if not moved:
            return sch
        note = f" (holds moved in bank: {'; '.join(moved)})"
        return Schedule(sch.name, sch.test, sch.role, gate, sch.flow_m3h, sch.duration_s,
                        sch.description + note, sch.meta)  # fmt: skip


def static_table(core: SwmmCore, b: Base, noise_mm: float, seed: int) -> str:
    """The rating grid's CSV text: steady means and SDs per feasible (Q, e) point."""
    rng = np.random.default_rng(seed)
    names = list(core.spec.gauge_names.values())
    header = ["flow_m3h", "opening_mm"] + [f"level_{g}_mm" for g in names]
    lines = [",".join(header + [f"level_{g}_sd_mm" for g in names])]
    gate_node = core.spec.output_node
    for fq in STATIC_FLOW_FACTORS:
        for fe in STATIC_OPENING_FACTORS:
            q, e = round(b.flow_m3h * fq, 1), float(round(b.opening_mm * fe))
            try:
                core.start(e, q)
            except PlantError:
                continue  # no steady state there (overtopping, emptying): not a rating point
            if not e < core.level_mm(gate_node) or core.flooding():
                continue  # out of orifice regime, or the canal overtops
            samples = {g: [] for g in names}
            for _ in range(30):
                core.advance(e, q)
                for g, v in core.levels_mm().items():
                    samples[g].append(v + noise_mm * float(rng.standard_normal()))
            means = [float(np.mean(samples[g])) for g in names]
            sds = [float(np.std(samples[g], ddof=1)) for g in names]
            lines.append(",".join([f"{q:.2f}", f"{e:.0f}"] + [f"{m:.2f}" for m in means]
                                  + [f"{s:.2f}" for s in sds]))  # fmt: skip
    if len(lines) < 4:
        raise PlantError("static table: fewer than three feasible (Q, e) points")
    return "\n".join(lines) + "\n"


def run_design(
    core: SwmmCore, design: str, opening_mm: float, flow_m3h: float, *, noise_mm: float,
    seed: int, progress: Callable[[str], None] | None = None,
) -> tuple[list[Output], Base]:  # fmt: skip
    """Measure the step response at the base point, then run ``design``'s records."""
    if design not in DESIGNS:
        raise PlantError(f"design {design!r}: expected one of {', '.join(DESIGNS)}")
    say = progress or (lambda _: None)
    check_regime(core, opening_mm, flow_m3h)
    say(f"swmm: step response at e = {opening_mm:g} mm, Q = {flow_m3h:g} m3/h")
    response = measure_step(core, opening_mm, flow_m3h)
    s = core.spec
    base = Base(opening_mm, flow_m3h, response, s.sample_period_s, s.gate_speed_mm_s)
    say(f"swmm: K = {response.gain_mm_per_mm:.3g} mm/mm, T = {response.time_constant_s:.0f} s, "
        f"L = {response.dead_time_s:.0f} s")  # fmt: skip
    schedules: list[Schedule] = []
    if design in ("step", "all"):
        schedules += step_schedules(base)
    if design in ("prbs", "all"):
        schedules.append(prbs_schedule(base))
    if design in ("free", "all"):
        bank = InBank(core, base)
        say(f"swmm: placing the free records' holds in bank ({bank.margin_mm:.0f} mm below "
            f"the top of {core.spec.output_node})")  # fmt: skip
        schedules += [bank.fit(sch) for sch in free_schedules(base, seed)]
    outputs: list[Output] = []
    for i, sch in enumerate(schedules):
        say(f"swmm: running {sch.name} ({sch.description})")
        run = run_schedule(core, sch, noise_mm, seed + i + 1)
        check_in_bank(run, sch.name)
        side = sidecar(core, seed=seed + i + 1, noise_mm=noise_mm, condition=sch.name,
                       test=sch.test, role=sch.role, description=sch.description,
                       design_from=response.to_dict())  # fmt: skip
        outputs.append((sch.name, record_csv(run), side))
    if design in ("static", "all"):
        say("swmm: running the static rating grid")
        text = static_table(core, base, noise_mm, seed)
        side = sidecar(core, seed=seed, noise_mm=noise_mm, kind="static rating table",
                       design_from=response.to_dict())  # fmt: skip
        outputs.append(("static", text, side))
    core.close()
    return outputs, base
