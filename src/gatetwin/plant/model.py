"""Plant data objects: scheduled FOPDT and ARX models of one gauge.

Semantics shared by every rendering (Python simulator, C FMU, pythonfmu FMU, MPC):

* Inputs: gate opening ``e`` (mm) and discharge ``Q`` (m³/h), piecewise constant between
  communication points.
* Parameters follow ``Q`` by piecewise-linear interpolation over the schedule knots; outside
  ``[Q_min, Q_max]`` they are clamped to the end knot (and a warning is logged once).
* Output: absolute level ``y = level_ref_mm(Q) + x``, where ``level_ref_mm(Q)`` is the rating
  relation's level at the reference opening ``opening_ref_mm`` and ``x`` the dynamic
  deviation driven by ``u = e - opening_ref_mm``.
* FOPDT: ``T dx/dt = K u(t - L) - x``, integrated exactly for piecewise-constant input.
* ARX (paper's sign convention, nk >= 1):
  ``x(k) = sum_i a_i x(k-i) + sum_j b_j u(k-nk-j+1)``, stepped at ``sample_period_s``; ``u(k)``
  is the input in force at communication point ``k``.
* The initial state is the equilibrium for the first inputs.
* ``effects``: optional effect blocks (actuator, nonlinearity, seiche, inflow, sensor), as
  model-file dictionaries; their semantics are in :mod:`gatetwin.plant.effects`. They are
  checked and put in the blocks' evaluation order (defaults filled in) on construction.

This module holds data only; simulation is in :mod:`gatetwin.plant.simulate`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gatetwin.errors import ModelFileError
from gatetwin.plant import blocks
from gatetwin.plant import physical_kernel as kernel
from gatetwin.plant.effects import EffectSet, parse_effects

__all__ = [
    "ARX_ORDER_LIMIT",
    "ENVELOPE_EFFECTS",
    "FLOW_RANGE_M3H",
    "FORMAT_DEFAULTS",
    "LOWER_BOUNDS",
    "OPENING_RANGE_MM",
    "OPERATING_STORAGE_RULE",
    "STORAGE_RULE",
    "ArxPlant",
    "FopdtPlant",
    "PhysicalPlant",
    "Plant",
    "Schedule",
    "check_operating_storage",
    "check_physical_parameters",
    "envelope_point",
    "envelope_steady",
    "interp_clamped",
    "kernel_parameters",
    "local_fopdt",
    "lowest_operating_room",
    "plant_from_dict",
    "plant_to_dict",
    "steady_depth_m",
    "tangent_point",
]

#: Inputs outside these bounds are physically impossible for any gate we model: an opening
#: up to 50 m (the largest radial and lift gates of river barrages open some 20 m) and a
#: discharge up to 36,000,000 m³/h (10,000 m³/s, a large river's flood through one gate).
#: A model's own validity envelope (its provenance) is far narrower; these only refuse what
#: no gate can do, at every scale from a lab flume to a barrage.
OPENING_RANGE_MM = (0.0, 50_000.0)
FLOW_RANGE_M3H = (0.0, 36_000_000.0)
#: Largest ARX order a plant holds (the model-file schema's limit; the FMUs take up to 8).
ARX_ORDER_LIMIT = 50


@dataclass(frozen=True)
class Schedule:
    """Parameters tabulated over discharge knots.

    Attributes
    ----------
    flow_m3h : tuple[float, ...]
        Strictly increasing discharge knots, m³/h. One knot means constant parameters.
    values : dict[str, tuple[float, ...]]
        Each parameter's value at every knot (same length as ``flow_m3h``).
    """

    flow_m3h: tuple[float, ...]
    values: dict[str, tuple[float, ...]]

    def __post_init__(self) -> None:
        q = np.asarray(self.flow_m3h, dtype=float)
        if q.size == 0 or not np.all(np.isfinite(q)) or np.any(np.diff(q) <= 0):
            raise ModelFileError("schedule: flow_m3h knots must be finite and strictly increasing")
        for name, col in self.values.items():
            arr = np.asarray(col, dtype=float)
            if arr.shape != q.shape or not np.all(np.isfinite(arr)):
                raise ModelFileError(f"schedule: column {name!r} must hold one finite value a knot")

    @property
    def flow_range_m3h(self) -> tuple[float, float]:
        return (self.flow_m3h[0], self.flow_m3h[-1])

    def at(self, name: str, flow_m3h: float) -> float:
        """Piecewise-linear interpolation of ``name`` at ``flow_m3h``, clamped at the ends."""
        return interp_clamped(self.flow_m3h, self.values[name], flow_m3h)

    def to_dict(self) -> dict[str, Any]:
        return {"flow_m3h": list(self.flow_m3h), **{k: list(v) for k, v in self.values.items()}}


def interp_clamped(knots: tuple[float, ...], values: tuple[float, ...], x: float) -> float:
    """Linear interpolation with end clamping, written as the C FMU evaluates it."""
    n = len(knots)
    if n == 1 or x <= knots[0]:
        return float(values[0])
    if x >= knots[-1]:
        return float(values[-1])
    i = 0
    while x > knots[i + 1]:
        i += 1
    w = (x - knots[i]) / (knots[i + 1] - knots[i])
    return float(values[i] + w * (values[i + 1] - values[i]))


@dataclass(frozen=True)
class FopdtPlant:
    """Scheduled first-order-plus-dead-time plant of one gauge.

    Schedule columns: ``gain_mm_per_mm`` (K), ``time_constant_s`` (T > 0),
    ``dead_time_s`` (L >= 0), ``level_ref_mm`` (rating level at ``opening_ref_mm``).

    ``envelope`` (optional): the parameters of :mod:`gatetwin.plant.physical_kernel` (gate
    law, gauge offset, storage). With it the plant holds across the operating envelope: the
    level relaxes towards the steady level of the gate law at the delayed opening and the
    present discharge, ``T(Q, e) dy/dt = H_ss(Q, e(t - L)) - y``, with ``T`` the storage
    linearised at that steady point and ``L`` from the schedule; K is ``∂H_ss/∂e`` there
    (see :func:`local_fopdt`). A gate that discharges into a pool of its own adds the pool's
    depth as a second state (:func:`~gatetwin.plant.physical_kernel.tail_pool_piece`). The
    schedule's K, T and ``level_ref_mm`` then describe the
    operating line the step conditions were identified on (the small-signal meaning the
    paper's tables and the MPC use); the output no longer adds ``level_ref_mm``.
    """

    gauge: str
    opening_ref_mm: float
    schedule: Schedule
    effects: tuple[dict[str, Any], ...] = ()
    envelope: dict[str, float] | None = None

    kind = "fopdt"
    columns = ("gain_mm_per_mm", "time_constant_s", "dead_time_s", "level_ref_mm")

    def __post_init__(self) -> None:
        _check_columns(self, self.columns)
        _normalise_effects(self)
        if self.envelope is not None:
            _set_envelope(self)
        if min(self.schedule.values["time_constant_s"]) <= 0:
            raise ModelFileError("fopdt: time_constant_s must be > 0 at every knot")
        if min(self.schedule.values["dead_time_s"]) < 0:
            raise ModelFileError("fopdt: dead_time_s must be >= 0 at every knot")

    @property
    def max_dead_time_s(self) -> float:
        return float(max(self.schedule.values["dead_time_s"]))

    @property
    def effect_set(self) -> EffectSet:
        """The checked effect blocks."""
        return parse_effects(self.effects, self.kind)


@dataclass(frozen=True)
class ArxPlant:
    """Scheduled ARX(na, nb, nk) plant of one gauge, paper's sign convention.

    Schedule columns: ``a1..a<na>``, ``b1..b<nb>``, ``level_ref_mm``.

    ``envelope`` (optional): the parameters of :mod:`gatetwin.plant.physical_kernel`. With it
    the model holds across the operating envelope (a Hammerstein, linear-parameter-varying
    ARX): its input is the steady level of the gate law at the opening and the discharge,
    ``u(k) = H_ss(Q, e)`` (mm), its steady gain is 1, and its pole follows the pool's time
    constant, ``a1(Q, e) = a1^(T_ref / T(Q, e))`` with the ``b`` rescaled to keep the gain
    (:func:`~gatetwin.plant.blocks.arx_pole_scaled`), ``T`` the storage linearised at the
    steady point and ``T_ref`` (column ``time_constant_ref_s``) its value where ``a1`` was
    identified. It needs ``na = 1``; the output is the state itself (``level_ref_mm`` then
    describes the operating line only).
    """

    gauge: str
    opening_ref_mm: float
    sample_period_s: float
    na: int
    nb: int
    nk: int
    schedule: Schedule
    effects: tuple[dict[str, Any], ...] = ()
    envelope: dict[str, float] | None = None

    kind = "arx"

    def __post_init__(self) -> None:
        for name in ("na", "nb", "nk"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ModelFileError(f"arx: {name} must be an integer (got {value!r:.60})")
            if value > ARX_ORDER_LIMIT:
                raise ModelFileError(f"arx: {name} {value} is above the limit {ARX_ORDER_LIMIT}")
        if not (self.na >= 1 and self.nb >= 1 and self.nk >= 1):
            raise ModelFileError(
                "arx: an exported plant needs na >= 1, nb >= 1 and nk >= 1 "
                f"(got {self.na}, {self.nb}, {self.nk}); nk = 0 has no causal co-simulation"
            )
        if not self.sample_period_s > 0:
            raise ModelFileError("arx: sample_period_s must be > 0")
        _check_columns(self, self.columns)
        _normalise_effects(self)
        if self.envelope is not None:
            _set_envelope(self)
            if self.na != 1:
                raise ModelFileError(f"arx: an envelope ARX needs na = 1 (got {self.na})")
            a1 = self.schedule.values["a1"]
            if not all(0.0 < a < 1.0 for a in a1):
                raise ModelFileError("arx: an envelope ARX needs 0 < a1 < 1 at every knot")
            if not min(self.schedule.values["time_constant_ref_s"]) > 0:
                raise ModelFileError("arx: time_constant_ref_s must be > 0 at every knot")

    @property
    def effect_set(self) -> EffectSet:
        """The checked effect blocks."""
        return parse_effects(self.effects, self.kind)

    @property
    def columns(self) -> tuple[str, ...]:  # type: ignore[override]
        a = tuple(f"a{i}" for i in range(1, self.na + 1))
        b = tuple(f"b{j}" for j in range(1, self.nb + 1))
        envelope = ("time_constant_ref_s",) if self.envelope is not None else ()
        return (*a, *b, "level_ref_mm", *envelope)

    def coefficients(self, flow_m3h: float) -> tuple[np.ndarray, np.ndarray]:
        a = np.array([self.schedule.at(f"a{i}", flow_m3h) for i in range(1, self.na + 1)])
        b = np.array([self.schedule.at(f"b{j}", flow_m3h) for j in range(1, self.nb + 1)])
        return a, b


#: Effect blocks an envelope FOPDT carries: output blocks whose input is the gate position
#: alone (the others assume the local, linear-in-opening form).
ENVELOPE_EFFECTS = ("seiche",)

#: Each parameter's physical domain where it has one: it must exceed this bound (the rest
#: only be finite; the storage area has its own rule, ``physical_kernel.storage_room_m2``). A
#: discharge coefficient is positive; a gate narrower than a millimetre is no sluice gate.
LOWER_BOUNDS = {
    "cd_small": 0.0,
    "cd_large": 0.0,
    "width_m": 1e-3,
    "speed_mm_s": 0.0,
    "stall_depth_m": 0.0,
    "resolution_mm": 0.0,
    "max_substep_s": 0.0,
    "flow_scale_m3h": 0.0,
    "depth_max_m": 0.0,
}
#: What :func:`~gatetwin.plant.physical_kernel.storage_room_m2` asks, for the messages.
STORAGE_RULE = (
    f"area_m2 + area_per_depth_m (h - {kernel.AREA_DEPTH_REF_M:g} m) must exceed "
    f"{kernel.AREA_MIN_M2:g} m2 at some depth h up to depth_max_m"
)
#: What :func:`~gatetwin.plant.physical_kernel.operating_room_m2` asks, for the messages.
OPERATING_STORAGE_RULE = (
    f"area_m2 + area_per_depth_m (h - {kernel.AREA_DEPTH_REF_M:g} m) must exceed "
    f"{kernel.AREA_MIN_M2:g} m2 wherever the model runs (the validity's levels and discharges)"
)
#: Kernel parameters added after the first model files were written, with the values those
#: files' equations had built in (the discharge normalisation and the steady-depth bracket they
#: were identified with; no tail pool: a free gate; no floor at the gauge): a file without
#: them reads as it always did.
FORMAT_DEFAULTS = {
    "flow_centre_m3h": 55.0,
    "flow_scale_m3h": 100.0,
    "depth_max_m": 2.0,
    "tail_area_m2": 0.0,
    "tail_depth_m": 1.0,
    "tail_datum_m": 0.0,
    "tail_exponent": 0.5,
    "floor_mm": 0.0,
    "floor_per_q_mm": 0.0,
    "floor_smooth_mm": 0.0,
}


def check_physical_parameters(values: dict[str, float] | list[float]) -> list[float]:
    """The parameter vector in kernel order; raises :class:`ModelFileError` on a bad one."""
    if isinstance(values, dict):
        values = {**FORMAT_DEFAULTS, **values}
        missing = [n for n, _, _ in kernel.PARAMETERS if n not in values]
        if missing:
            raise ModelFileError(f"physical: parameters lack {', '.join(missing)}")
        vector = [values[n] for n, _, _ in kernel.PARAMETERS]
    else:
        vector = list(values)
    out = []
    for (name, _, _), value in zip(kernel.PARAMETERS, vector, strict=True):
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise ModelFileError(f"physical: parameter {name} must be a number") from None
        bound = LOWER_BOUNDS.get(name, -math.inf)
        if not (math.isfinite(v) and v > bound):
            rule = f"finite and > {bound:g}" if name in LOWER_BOUNDS else "finite"
            raise ModelFileError(f"physical: parameter {name} = {value!r} must be {rule}")
        out.append(v)
    if not kernel.storage_room_m2(out) > 0.0:
        raise ModelFileError(f"physical: the storage area {STORAGE_RULE}")
    tail = dict(zip((n for n, _, _ in kernel.PARAMETERS), out, strict=True))
    if tail["tail_area_m2"] < 0.0:
        raise ModelFileError(f"physical: parameter tail_area_m2 = {tail['tail_area_m2']!r} "
                             "must be >= 0 (0: no pool below the gate)")  # fmt: skip
    if tail["floor_smooth_mm"] < 0.0:
        raise ModelFileError(f"physical: parameter floor_smooth_mm = {tail['floor_smooth_mm']!r} "
                             "must be >= 0 (0: no floor)")  # fmt: skip
    if tail["tail_area_m2"] > 0.0 and not (tail["tail_depth_m"] > tail["tail_datum_m"]
                                           and tail["tail_exponent"] > 0.0):  # fmt: skip
        raise ModelFileError(
            f"physical: the pool below the gate needs tail_depth_m ({tail['tail_depth_m']!r}) "
            f"above tail_datum_m ({tail['tail_datum_m']!r}) and tail_exponent "
            f"({tail['tail_exponent']!r}) > 0"
        )
    return out


def lowest_operating_room(p: list[float], level_range_mm: list[float],
                          flow_range_m3h: list[float]) -> tuple[float, float, float]:  # fmt: skip
    """The storage area's smallest margin above its floor over the steady pools of a level
    range and a discharge range (:func:`~gatetwin.plant.physical_kernel.operating_room_m2`
    at their corners: the area is linear in depth, the depth linear in the level and, for
    discharges >= 0, monotonic in the discharge), m², with the level and discharge where it is
    smallest. The pool's depth is read from the level without a far gauge's floor (at a floored
    gauge the pool may be lower)."""
    return min((kernel.operating_room_m2(h, q, p), h, q)
               for h in level_range_mm for q in flow_range_m3h)  # fmt: skip


def check_operating_storage(plant: Any, level_range_mm: list[float],
                            flow_range_m3h: list[float]) -> None:  # fmt: skip
    """Refuse a plant carrying the physical kernel whose storage area is not above its floor
    at every depth it declares it runs at: the steady pools of its validity's level and
    discharge ranges (:func:`lowest_operating_room`; the C and python FMUs check the same)."""
    kernel_values = kernel_parameters(plant)
    if kernel_values is None:
        return
    p = list(kernel_values[1].values())
    room, level, flow = lowest_operating_room(p, level_range_mm, flow_range_m3h)
    if not room > 0.0:
        raise ModelFileError(
            f"{plant.kind}: the storage area is {room + kernel.AREA_MIN_M2:.4g} m2 at h = "
            f"{kernel.pool_depth_m(level, flow, p):.4g} m (the pool at level {level:g} mm and "
            f"{flow:g} m3/h, inside the validity); {OPERATING_STORAGE_RULE}"
        )


@dataclass(frozen=True)
class PhysicalPlant:
    """Storage-and-gate-law plant of one gauge.

    Attributes
    ----------
    gauge : str
        Gauge name; the output is ``level_<gauge>_mm``.
    parameters : dict[str, float]
        The kernel's parameters by name (:data:`~gatetwin.plant.physical_kernel.PARAMETERS`).
    schedule : Schedule
        Two discharge knots spanning the identified range, column ``level_ref_mm`` (a datum
        correction, mm).
    """

    gauge: str
    parameters: dict[str, float]
    schedule: Schedule
    effects: tuple[dict[str, Any], ...] = ()

    kind = "physical"
    columns = ("level_ref_mm",)
    opening_ref_mm = 0.0

    def __post_init__(self) -> None:
        vector = check_physical_parameters(self.parameters)
        names = [n for n, _, _ in kernel.PARAMETERS]
        object.__setattr__(self, "parameters", dict(zip(names, vector, strict=True)))
        if "level_ref_mm" not in self.schedule.values:
            raise ModelFileError("physical: schedule lacks column level_ref_mm")
        _normalise_effects(self)

    @property
    def effect_set(self) -> EffectSet:
        """The checked effect blocks (the seiche is the one this family can carry)."""
        return parse_effects(self.effects, self.kind)

    @property
    def vector(self) -> list[float]:
        """The parameters in kernel order."""
        return list(self.parameters.values())

    def steady_depth_m(self, opening_mm: float, flow_m3h: float) -> float:
        """Depth at the gate at which it passes ``flow_m3h`` (the initial state), m."""
        return steady_depth_m(opening_mm, flow_m3h, self.vector)

    def steady_level_mm(self, opening_mm: float, flow_m3h: float) -> float:
        """Steady level at the gauge, mm."""
        p = self.vector
        depth = steady_depth_m(opening_mm, flow_m3h, p)
        return kernel.level_mm(depth, opening_mm, flow_m3h, p) + self.schedule.at(
            "level_ref_mm", flow_m3h
        )


def envelope_steady(opening_mm: float, flow_m3h: float, p: list[float]
                    ) -> tuple[float, float, float]:  # fmt: skip
    """Steady level at the gauge (mm), small-signal time constant (s) and depth at the gate
    (m) at (Q, e) (``kernel_envelope_steady`` of the C FMU)."""
    depth = steady_depth_m(opening_mm, flow_m3h, p)
    return (
        kernel.level_mm(depth, opening_mm, flow_m3h, p),
        kernel.time_constant_s(depth, opening_mm, flow_m3h, p),
        depth,
    )


def envelope_point(opening_mm: float, flow_m3h: float, p: list[float]) -> tuple[float, float]:
    """Steady level at the gauge (mm) and small-signal time constant (s) at (Q, e)."""
    return envelope_steady(opening_mm, flow_m3h, p)[:2]


def local_fopdt(plant: FopdtPlant | ArxPlant | PhysicalPlant, flow_m3h: float,
                opening_mm: float) -> dict[str, float]:  # fmt: skip
    """K, T, L and the steady level of an envelope FOPDT or ARX or a physical plant at (Q, e).

    K is the central difference of the steady level over ±0.5 mm of opening (mm/mm). For an
    envelope ARX, T is its scaled pole's time constant ``-Ts / ln a1(Q, e)`` and L its input
    delay beyond one sample, ``(nk - 1) Ts``.
    """
    if isinstance(plant, PhysicalPlant):
        p, delay = plant.vector, 0.0
    elif isinstance(plant, FopdtPlant) and plant.envelope is not None:
        p, delay = list(plant.envelope.values()), plant.schedule.at("dead_time_s", flow_m3h)
    elif isinstance(plant, ArxPlant) and plant.envelope is not None:
        p, delay = list(plant.envelope.values()), (plant.nk - 1) * plant.sample_period_s
    else:
        raise ModelFileError("local_fopdt needs an envelope FOPDT or ARX or a physical plant")
    return tangent_point(envelope_point, plant, flow_m3h, opening_mm, p, delay)


def tangent_point(
    point: Any, plant: Any, flow_m3h: Any, opening_mm: Any, p: list[float], delay_s: Any
) -> dict[str, Any]:
    """:func:`local_fopdt` with the steady point ``point(opening_mm, flow_m3h, p) -> (level,
    time constant)`` given: :func:`envelope_point`, or a stand-in that returns symbols (the
    observer FMU's generated code takes the points its C computes at the openings asked)."""
    level, tau = point(opening_mm, flow_m3h, p)
    if isinstance(plant, ArxPlant):
        a1 = blocks.arx_pole_scaled(
            plant.schedule.at("a1", flow_m3h),
            plant.schedule.at("time_constant_ref_s", flow_m3h),
            tau,
        )
        tau = -plant.sample_period_s / math.log(a1)
    gain = (point(opening_mm + 0.5, flow_m3h, p)[0]
            - point(opening_mm - 0.5, flow_m3h, p)[0])  # fmt: skip
    return {"gain_mm_per_mm": gain, "time_constant_s": tau, "dead_time_s": delay_s,
            "level_mm": level}  # fmt: skip


def steady_depth_m(opening_mm: float, flow_m3h: float, p: list[float],
                   tail_m: float | None = None) -> float:  # fmt: skip
    """The kernel's steady-depth solve (as the C FMU runs it); the tail pool at its steady
    depth for the discharge, or held at ``tail_m``."""
    k = kernel
    if tail_m is None:
        return k.steady_depth_m(opening_mm, flow_m3h, p)
    return k.held_steady_depth_m(tail_m, opening_mm, flow_m3h, p)


Plant = FopdtPlant | ArxPlant | PhysicalPlant


def kernel_parameters(plant: Plant) -> tuple[str, dict[str, float]] | None:
    """``(variable prefix, values)`` of the physical kernel's parameters a plant carries, in
    kernel order: ``physical.*`` for the physical family, ``envelope.*`` for an envelope FOPDT
    or ARX; None for a plant without the kernel."""
    if isinstance(plant, PhysicalPlant):
        return "physical", plant.parameters
    if isinstance(plant, FopdtPlant | ArxPlant) and plant.envelope is not None:
        return "envelope", plant.envelope
    return None


def _set_envelope(plant: Any) -> None:
    """Check an envelope plant's kernel parameters (stored in kernel order) and its blocks."""
    vector = check_physical_parameters(plant.envelope)
    names = [n for n, _, _ in kernel.PARAMETERS]
    object.__setattr__(plant, "envelope", dict(zip(names, vector, strict=True)))
    other = sorted({e["kind"] for e in plant.effects} - set(ENVELOPE_EFFECTS))
    if other:
        raise ModelFileError(
            f"{plant.kind}: effect block {other[0]} is not supported on an envelope "
            f"{plant.kind.upper()} (only {', '.join(ENVELOPE_EFFECTS)}; use its local form, "
            "without 'envelope')"
        )


def _normalise_effects(plant: Any) -> None:
    """Check the effect dictionaries; store them in evaluation order with defaults filled."""
    if isinstance(plant.effects, (str, bytes, dict)) or not hasattr(plant.effects, "__iter__"):
        raise ModelFileError(f"{plant.kind}: effects must be a list of effect objects")
    blocks = parse_effects(tuple(plant.effects), plant.kind).blocks
    object.__setattr__(plant, "effects", tuple(b.to_dict() for b in blocks))


def _check_columns(plant: Any, columns: tuple[str, ...]) -> None:
    missing = [c for c in columns if c not in plant.schedule.values]
    if missing:
        raise ModelFileError(f"{plant.kind}: schedule lacks column(s) {', '.join(missing)}")
    if not np.isfinite(plant.opening_ref_mm):
        raise ModelFileError(f"{plant.kind}: opening_ref_mm must be finite")


def plant_to_dict(plant: Plant) -> dict[str, Any]:
    """The ``plant`` section of a model file."""
    out: dict[str, Any] = {
        "kind": plant.kind,
        "gauge": plant.gauge,
        "opening_ref_mm": plant.opening_ref_mm,
        "schedule": plant.schedule.to_dict(),
        "effects": [dict(e) for e in plant.effects],
    }
    if isinstance(plant, FopdtPlant | ArxPlant) and plant.envelope is not None:
        out["envelope"] = {
            "parameters": dict(plant.envelope),
            "equations": "gatetwin.plant.physical_kernel",
        }
    if isinstance(plant, PhysicalPlant):
        out.update(parameters=dict(plant.parameters), equations="gatetwin.plant.physical_kernel")
    if isinstance(plant, ArxPlant):
        out.update(sample_period_s=plant.sample_period_s, na=plant.na, nb=plant.nb, nk=plant.nk)
    return out


def plant_from_dict(data: dict[str, Any]) -> Plant:
    """Inverse of :func:`plant_to_dict`; raises :class:`ModelFileError` on bad content.

    The section is checked against the model-file schema first
    (:func:`gatetwin.modelschema.check_plant_section`: types, integer orders, physical
    bounds, gauge name), so nothing is built from a malformed one.
    """
    from gatetwin.modelschema import check_plant_section

    check_plant_section(data)
    try:
        sched = dict(data["schedule"])
        knots = tuple(float(v) for v in sched.pop("flow_m3h"))
        schedule = Schedule(knots, {k: tuple(float(x) for x in v) for k, v in sched.items()})
        common = dict(
            gauge=str(data["gauge"]),
            opening_ref_mm=float(data["opening_ref_mm"]),
            schedule=schedule,
            effects=tuple(dict(e) for e in data.get("effects", ())),
        )
        envelope = data.get("envelope")
        if envelope is not None and not (
            isinstance(envelope, dict) and isinstance(envelope.get("parameters"), dict)
        ):
            raise ModelFileError(f"{data['kind']}: envelope.parameters must be an object")
        if data["kind"] == "fopdt":
            return FopdtPlant(**common, envelope=envelope and envelope["parameters"])
        if data["kind"] == "physical":
            if not isinstance(data.get("parameters"), dict):
                raise ModelFileError("physical: parameters must be an object of name: number")
            return PhysicalPlant(
                gauge=common["gauge"],
                parameters=data["parameters"],
                schedule=schedule,
                effects=common["effects"],
            )
        if data["kind"] == "arx":
            return ArxPlant(
                sample_period_s=float(data["sample_period_s"]),
                na=data["na"],
                nb=data["nb"],
                nk=data["nk"],
                **common,
                envelope=envelope and envelope["parameters"],
            )
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, ModelFileError):
            raise
        raise ModelFileError(f"plant: malformed section ({exc})") from None
    raise ModelFileError(
        f"plant: unknown kind {data.get('kind')!r} (expected fopdt, arx or physical)"
    )
