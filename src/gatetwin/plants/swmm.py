"""An EPA SWMM model as a plant: one gate, its gauges, its inflow, stepped like the flume.

:class:`SwmmCore` satisfies :class:`gatetwin.mpc.plants.PlantCore` (``start``, ``advance``,
``close``, ``description``), so :class:`gatetwin.mpc.plants.LoopPlant` wraps it like the
virtual flume. SWMM 5.2's dynamic-wave solver runs through ``pyswmm`` (the ``swmm`` extra);
the plant:

* drives the gate, a ``SIDE`` orifice of shape ``RECT_CLOSED``: opening = target setting ×
  orifice height. An actuator moves the opening towards the command at a finite speed
  (``gate_speed_mm_s``), in sub-steps of the model's routing step;
* drives the inflow at the inflow node(s) through SWMM's generated inflow; the ``.inp``'s
  own constant FLOW inflows at those nodes are dropped (the plant's flow replaces them) and
  the plant's flow is shared among several nodes in proportion to those baselines (equally
  without any);
* reads levels: a gauge at node N reads N's depth + N's invert elevation − the gate's sill
  elevation (the bottom of the orifice opening), in mm: **the datum is the gate's sill**;
* runs on a temporary copy of the ``.inp`` (the end date moved to cover the run, rules
  acting on the gate dropped); the user's file is never modified.

Units: gatetwin's mm and m³/h outside; the model's metric units inside (CMS, LPS or MLD,
lengths in m). Models in US units are refused.
"""

from __future__ import annotations

import math
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gatetwin.errors import NotSteadyError, PlantError
from gatetwin.plants.swmm_inp import InpFile, Orifice

__all__ = [
    "EXTRA_MESSAGE",
    "RESOLUTION_MM",
    "SwmmCore",
    "SwmmPlantSpec",
    "gauge_name",
    "load_pyswmm",
    "swmm_versions",
]

#: What a missing ``pyswmm`` says.
EXTRA_MESSAGE = "the SWMM plant needs the swmm extra: pip install 'gatetwin[swmm]'"
#: Gauge reading resolution, mm (the loop's gauges read to 0.1 mm).
RESOLUTION_MM = 0.1


def load_pyswmm() -> Any:
    """The ``pyswmm`` module, or a one-line :class:`PlantError` naming the extra."""
    try:
        import pyswmm
    except ImportError:
        raise PlantError(EXTRA_MESSAGE) from None
    return pyswmm


def swmm_versions() -> str:
    """``"EPA SWMM 5.2.4 (pyswmm 2.2.0, swmm-toolkit 0.17.0)"``."""
    pyswmm = load_pyswmm()
    from swmm.toolkit import __version__ as toolkit_version
    from swmm.toolkit import solver

    code = int(solver.swmm_get_version())
    return (f"EPA SWMM {code // 10000}.{code // 1000 % 10}.{code % 1000} "
            f"(pyswmm {pyswmm.__version__}, swmm-toolkit {toolkit_version})")  # fmt: skip


def gauge_name(node: str) -> str:
    """A gauge name for node ``node`` that fits the record's ``level_<G>_mm`` columns:
    letters, digits and inner underscores (``"P1_2"`` stays, ``"U-1.a"`` → ``"U1a"``); a
    name ending in ``_sd`` (which would read as a level's SD column) loses its underscores."""
    name = re.sub(r"[^0-9A-Za-z_]+", "", node).strip("_")
    if name.lower().endswith("_sd"):
        name = name.replace("_", "")
    if not name:
        raise PlantError(f"gauge node {node!r}: no letter or digit to name its level column")
    return name


@dataclass(frozen=True)
class SwmmPlantSpec:
    """What makes a SWMM model a plant.

    Attributes
    ----------
    inp_path : Path
        The SWMM input file.
    gate : str
        The gate's ``[ORIFICES]`` link (``SIDE``, ``RECT_CLOSED``).
    gauges : dict[str, float]
        Gauge node -> distance upstream of the gate, m.
    inflow_nodes : tuple[str, ...]
        Node(s) receiving the inflow.
    gate_speed_mm_s : float
        Actuator speed, mm/s.
    sample_period_s : float
        Control period: one ``advance`` holds the inputs this long, s.
    level_node : str or None
        Gauge node whose level ``start``/``advance`` return; default the one nearest
        the gate.
    steady_tolerance_mm : float
        Spin-up ends when the level moves less than this over a pool time constant (and the
        last quarter of the spin-up), and what is left of its approach is less too, mm.
    max_spin_up_s : float
        Longest spin-up before the model is called unsteady, s.
    horizon_s : float
        Longest run after the spin-up, s (sets the copy's end date).
    """

    inp_path: Path
    gate: str
    gauges: dict[str, float]
    inflow_nodes: tuple[str, ...]
    gate_speed_mm_s: float = 5.0
    sample_period_s: float = 10.0
    level_node: str | None = None
    steady_tolerance_mm: float = RESOLUTION_MM
    max_spin_up_s: float = 2 * 86400.0
    horizon_s: float = 30 * 86400.0
    gauge_names: dict[str, str] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "inp_path", Path(self.inp_path))
        checks = {
            "gate speed (mm/s)": self.gate_speed_mm_s,
            "sample period (s)": self.sample_period_s,
            "steady tolerance (mm)": self.steady_tolerance_mm,
            "spin-up bound (s)": self.max_spin_up_s,
            "horizon (s)": self.horizon_s,
        }
        for what, value in checks.items():
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise PlantError(f"SWMM plant: {what} must be a positive number, got {value!r}")
        if not self.gauges or not self.inflow_nodes:
            raise PlantError("SWMM plant: need at least one gauge node and one inflow node")
        for node, distance in self.gauges.items():
            if not (math.isfinite(distance) and distance >= 0):
                raise PlantError(f"gauge {node}: distance {distance} m; expected >= 0 m upstream")
        names = {node: gauge_name(node) for node in self.gauges}
        if len(set(names.values())) < len(names):
            raise PlantError(f"gauge nodes {', '.join(self.gauges)}: two give the same name")
        object.__setattr__(self, "gauge_names", names)
        if self.level_node is not None and self.level_node not in self.gauges:
            raise PlantError(f"level node {self.level_node!r} is not one of the gauges")

    @property
    def output_node(self) -> str:
        return self.level_node or min(self.gauges, key=self.gauges.__getitem__)


class SwmmCore:
    """A SWMM model driven step by step (see the module docstring).

    Parameters
    ----------
    spec : SwmmPlantSpec
        The model and the names in it.

    Raises
    ------
    PlantError
        pyswmm missing, the ``.inp`` unreadable, in US units, or the names not in it.
    """

    def __init__(self, spec: SwmmPlantSpec) -> None:
        self._pyswmm = load_pyswmm()
        self.spec = spec
        if not spec.inp_path.exists():
            raise PlantError(f"{spec.inp_path}: no such SWMM input file")
        self.inp = InpFile(spec.inp_path)
        self.to_m3s = self.inp.flow_to_m3s()
        self.orifice: Orifice = self.inp.orifice(spec.gate)
        self.inp.check_nodes(list(spec.gauges), "gauge node")
        self.inp.check_nodes(list(spec.inflow_nodes), "inflow node")
        self.datum_m = {n: self.inp.invert_m(n) - self.orifice.sill_elevation_m
                        for n in spec.gauges}  # fmt: skip
        base = [max(self.inp.baseline_inflow(n), 0.0) for n in spec.inflow_nodes]
        total = sum(base)
        self.shares = [b / total if total > 0 else 1.0 / len(base) for b in base]
        self.base_flow_m3s = total * self.to_m3s
        self.routing_step_s = _routing_step_s(self.inp)
        #: Gate sub-step: the routing step, at least the 1 s SWMM strides by, s.
        self.substep_s = max(1.0, self.routing_step_s)
        self.dropped_rules = self.inp.gate_rules(spec.gate)
        self.description = (
            f"EPA SWMM model {spec.inp_path.name}, gate {spec.gate}, level at {spec.output_node}"
        )
        self.position_mm = math.nan
        self.time_s = 0.0
        self.spin_up_s = math.nan
        self._sim: Any = None
        self._tmp: tempfile.TemporaryDirectory[str] | None = None

    @property
    def height_mm(self) -> float:
        return 1000.0 * self.orifice.height_m

    def rule_opening_mm(self) -> float | None:
        """The opening the model's own rules hold the gate at, mm, when they set it to one
        value (a model's operating point); ``None`` otherwise."""
        pattern = rf"\bORIFICE\s+{re.escape(self.spec.gate)}\s+SETTING\s*=\s*([0-9.eE+-]+)"
        values = {float(v) for v in re.findall(pattern, self.inp.text, flags=re.IGNORECASE)}
        return self.height_mm * values.pop() if len(values) == 1 else None

    def base_opening_mm(self, opening_mm: float | None = None) -> float:
        """The experiments' base opening, whole mm: ``opening_mm``, else the one the model's
        rules hold the gate at (:meth:`rule_opening_mm`) where it is inside the gate (a rule
        that closes the gate or opens it fully holds no operating point), else half the
        orifice height.

        Raises
        ------
        PlantError
            ``opening_mm`` is not inside the gate's 0..height.
        """
        if opening_mm is None:
            rule = self.rule_opening_mm()
            inside = rule is not None and 0 < rule < self.height_mm
            return float(round(rule if inside else self.height_mm / 2))
        if not 0 < opening_mm < self.height_mm:
            raise PlantError(f"--opening {opening_mm} mm: outside the gate's "
                             f"0..{self.height_mm:g} mm")  # fmt: skip
        return float(round(opening_mm))

    # ----------------------------------------------------------------- PlantCore

    def start(self, opening_mm: float, flow_m3h: float) -> float:
        """Spin up to steady state with the gate at ``opening_mm`` and the inflow at
        ``flow_m3h``; returns the level at the output gauge, mm."""
        self._check(opening_mm, flow_m3h)
        self.close()
        self._open()
        self.position_mm = float(opening_mm)
        self._set_gate(self.position_mm)
        self._set_flow(flow_m3h)
        self._spin_up()
        return self.level_mm()

    def advance(self, opening_mm: float, flow_m3h: float) -> float:
        """Hold the command and the inflow for one sample period; the gate travels towards
        the command at the actuator's speed. Returns the level at the output gauge, mm."""
        if self._sim is None:
            raise PlantError("SWMM plant: start() before advance()")
        self._check(opening_mm, flow_m3h)
        self._set_flow(flow_m3h)
        period, done = self.spec.sample_period_s, 0.0
        while done < period - 1e-9:
            gap = float(opening_mm) - self.position_mm
            if gap == 0.0:
                self._stride(period - done)
                break
            dt = min(self.substep_s, period - done)
            move = math.copysign(min(abs(gap), self.spec.gate_speed_mm_s * dt), gap)
            self.position_mm += move
            self._set_gate(self.position_mm)
            self._stride(dt)
            done += dt
        return self.level_mm()

    def close(self) -> None:
        if self._sim is not None:
            self._sim.close()
            self._sim = None
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    # ----------------------------------------------------------------- readings

    def level_mm(self, node: str | None = None) -> float:
        """Level at a gauge node above the gate's sill, mm (default: the output gauge)."""
        node = node or self.spec.output_node
        depth = float(self._nodes[node].depth)
        return 1000.0 * (depth + self.datum_m[node])

    def levels_mm(self) -> dict[str, float]:
        """Every gauge's level, keyed by gauge name (not node), mm."""
        return {self.spec.gauge_names[n]: self.level_mm(n) for n in self.spec.gauges}

    def top_mm(self, node: str | None = None) -> float:
        """Top of a gauge node (SWMM's full depth, the bank) above the gate's sill, mm."""
        node = node or self.spec.output_node
        return 1000.0 * (float(self._nodes[node].full_depth) + self.datum_m[node])

    def flooding(self) -> bool:
        """Whether any gauge node overflows (SWMM's node flooding is positive)."""
        return any(float(self._nodes[n].flooding) > 0 for n in self.spec.gauges)

    def gate_flow_m3h(self) -> float:
        """Discharge through the gate, m³/h."""
        return 3600.0 * float(self._links[self.spec.gate].flow) * self.to_m3s

    # ----------------------------------------------------------------- internals

    def _check(self, opening_mm: float, flow_m3h: float) -> None:
        if not 0.0 <= opening_mm <= self.height_mm:
            raise PlantError(f"SWMM plant: opening {opening_mm} mm outside the gate's "
                             f"0..{self.height_mm:g} mm")  # fmt: skip
        if not (math.isfinite(flow_m3h) and flow_m3h >= 0):
            raise PlantError(f"SWMM plant: inflow {flow_m3h} m³/h; expected a finite flow >= 0")

    def _open(self) -> None:
        spec = self.spec
        self._tmp = tempfile.TemporaryDirectory(prefix="gatetwin-swmm-")
        copy = Path(self._tmp.name) / spec.inp_path.name
        duration = spec.max_spin_up_s + spec.horizon_s
        copy.write_text(self.inp.driven_copy(spec.gate, list(spec.inflow_nodes), duration),
                        encoding="utf-8")  # fmt: skip
        try:
            self._sim = self._pyswmm.Simulation(str(copy))
            self._sim.__enter__()
            self._sim.start()
        except Exception as exc:  # pyswmm raises bare Exception with SWMM's error text
            detail = _report_errors(copy.with_suffix(".rpt")) or str(exc)
            self.close()
            raise PlantError(f"{spec.inp_path}: SWMM refused the model: "
                             f"{' '.join(detail.split())}") from None  # fmt: skip
        self._nodes = self._pyswmm.Nodes(self._sim)
        self._links = self._pyswmm.Links(self._sim)
        self._t0 = self._sim.current_time
        self.time_s = self._nominal_s = 0.0

    def _set_gate(self, opening_mm: float) -> None:
        self._links[self.spec.gate].target_setting = opening_mm / self.height_mm

    def _set_flow(self, flow_m3h: float) -> None:
        flow_units = flow_m3h / 3600.0 / self.to_m3s
        for node, share in zip(self.spec.inflow_nodes, self.shares, strict=True):
            self._nodes[node].generated_inflow(flow_units * share)

    def _stride(self, seconds: float) -> float:
        """Advance SWMM by ``seconds``; returns the time actually advanced, s.

        SWMM strides in whole seconds: the plant keeps a nominal clock and advances to the
        whole second nearest it, so the model's time stays within 0.5 s of the nominal
        time and the rounding never accumulates.
        """
        before = self.time_s
        self._nominal_s += seconds
        whole = int(round(self._nominal_s - self.time_s))
        if whole < 1:
            return 0.0
        self._sim.step_advance(whole)
        try:
            next(self._sim)
        except StopIteration:
            msg = f"SWMM plant: the run passed its horizon of {self.spec.horizon_s:g} s"
            raise PlantError(msg) from None
        self.time_s = (self._sim.current_time - self._t0).total_seconds()
        return self.time_s - before

    def _spin_up(self) -> None:
        """Run with the inputs held until the level is steady: it moved less than the
        tolerance over the last pool time constant (at least ten samples, and at least the
        last quarter of the spin-up), and what is left of its approach is less than the
        tolerance too. The time constant is estimated as the level's total change over its
        fastest rate of change (for h∞ − Δ·exp(−t/T) both are Δ and Δ/T), so no length of
        time is assumed. SWMM's first filling can make that rate fast and the estimate
        short, and a pool that overshoots is still for a while at its turn: the quarter of
        the spin-up so far keeps the window growing with the approach, and over three equal
        windows an exponential approach moves by d, d·r, d·r² and has d·r³/(1 − r) left to
        go (:func:`_left_to_go_mm`)."""
        spec, step = self.spec, self.spec.sample_period_s
        first = self.level_mm()
        history, fastest = [first], 0.0
        while self.time_s < spec.max_spin_up_s:
            self._stride(step)
            history.append(self.level_mm())
            fastest = max(fastest, abs(history[-1] - history[-2]) / step)
            change = abs(history[-1] - first)
            tau = change / fastest if fastest > 0 else 0.0
            n = max(10, math.ceil(tau / step), len(history) // 4)
            if len(history) <= 3 * n or len(history) % max(1, n // 10):
                continue  # judged every tenth of a window: its length grows with the spin-up
            window = history[-n - 1 :]
            moved = max(window) - min(window)
            tolerance = spec.steady_tolerance_mm
            # a level creeping at a steady pace has no exponential end, but below a
            # thousandth of the tolerance over the window it is still
            if moved < tolerance and (moved < 1e-3 * tolerance
                                      or _left_to_go_mm(history, n) < tolerance):  # fmt: skip
                self.spin_up_s = self.time_s
                return
        window = history[-n - 1 :]
        left = _left_to_go_mm(history, n) if len(history) > 3 * n else math.inf
        raise NotSteadyError(
            f"{spec.inp_path.name}: not steady after {spec.max_spin_up_s / 3600:g} h of spin-up "
            f"(level at {spec.output_node} still moves {max(window) - min(window):.2f} mm over "
            f"{n * step:g} s, {left:.2f} mm left of its approach; tolerance "
            f"{spec.steady_tolerance_mm:g} mm)",
            min(window),
        )


def _left_to_go_mm(history: list[float], n: int) -> float:
    """How far the level has still to go, mm, if it approaches its end exponentially: from
    its moves over the last three windows of ``n`` samples, ``d₁, d₂, d₃``, the ratio
    ``r = d₃/d₂`` and ``d₃·r/(1 − r)``; infinite when the moves do not shrink (a level
    still speeding up, or holding its pace)."""
    y0, y1, y2, y3 = history[-3 * n - 1], history[-2 * n - 1], history[-n - 1], history[-1]
    d2, d3 = y2 - y1, y3 - y2
    if d3 == 0.0:
        return 0.0
    ratio = d3 / d2 if d2 != 0.0 else math.inf
    if ratio <= 0.0:  # turning round (a wave in the pool): what is left is of its size
        return max(abs(d3), abs(y1 - y0))
    return abs(d3) * ratio / (1.0 - ratio) if ratio < 1.0 else math.inf


def _routing_step_s(inp: InpFile) -> float:
    text = inp.option("ROUTING_STEP", "20")
    try:
        if ":" in text:
            parts = [float(p) for p in text.split(":")]
            value = sum(p * 60.0**i for i, p in enumerate(reversed(parts)))
        else:
            value = float(text)
    except ValueError:
        raise PlantError(f"{inp.path.name}: ROUTING_STEP {text!r} unreadable") from None
    if not value > 0:
        raise PlantError(f"{inp.path.name}: ROUTING_STEP must be positive")
    return value


def _report_errors(report: Path) -> str:
    """SWMM's ERROR lines (with the offending input line) from its report file."""
    try:
        lines = report.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return ""
    out = []
    for i, line in enumerate(lines):
        if "ERROR" in line:
            nxt = lines[i + 1].strip() if i + 1 < len(lines) else ""
            out.append(f"{line.strip()} {nxt}".strip())
    return "; ".join(out[:3])
