"""Effect blocks: physical effects a plain FOPDT/ARX plant misses, as parts of the plant.

A plant's ``effects`` field holds plain dictionaries ``{"kind": ..., <parameters>}`` (the
model-file form); :func:`parse_effects` checks them and returns an :class:`EffectSet` of the
frozen block objects below. Every rendering evaluates the blocks in one fixed order, whatever
the order of the dictionaries::

    command c --[actuator_rate_limit]--> actuator a --[actuator_backlash]--> gate g
      g --[opening_nonlinearity]--> u = map(g - opening_ref)  --> dynamics (K, T [, L] or ARX)
                                     [flow_dependent_gain scales K and T with Q]
    level = level_ref(Q) + x --[sensor_lag]--> + seiche(g) + inflow(Q) + drift --> output

At most one block of each kind. Semantics shared by the Python reference
(:mod:`gatetwin.plant.simulate`), the C FMU (``fmu_templates/effects.c``) and the pythonfmu
FMU, exact for inputs held over each communication step:

* ``actuator_rate_limit`` (input; state: actuator position ``a``): the actuator moves toward
  the commanded opening at ``rate_mm_per_s`` (exactly piecewise linear). The dynamics see the
  gate position *sampled and held on a fixed grid*: for FOPDT plants the grid
  ``t_init + k * substep_s`` (a fixed parameter, default 0.1 s), for ARX plants the ARX
  sample instants. Without this block the gate reaches each command at once.
* ``actuator_backlash`` (input; state: gate position ``g``): play operator of width
  ``deadband_mm`` between actuator and gate; at initialisation the gate sits in the middle
  of the band (``g = a``), so the first move of either direction loses half the band.
* ``opening_nonlinearity`` (input, static): the dynamics see
  ``u = expm1(s v) / s`` of the gate deviation ``v = g - opening_ref_mm``, i.e. the local
  gain is ``K exp(s v)``: ``gain_slope_per_mm`` is the relative change of the gain per mm.
* ``flow_dependent_gain`` (dynamics, FOPDT only): ``K_eff = K(Q) exp(aK (Q - Q_ref))``,
  ``T_eff = T(Q) exp(aT (Q - Q_ref))``.
* ``seiche`` (output; state ``x1, x2``): a lightly damped oscillation driven by the gate
  deviation ``v`` (undelayed): step response ``amplitude e^(-t/decay) sin(2 pi t/period)``
  per mm of gate move; zero at rest.
* ``inflow_disturbance`` (output; state ``x_q``): ``tau_q x_q' = k_q (Q - Q_ref) - x_q``
  with ``Q`` the measured discharge; adds ``x_q`` to the level.
* ``sensor_drift`` (output; state: accumulated offset): adds ``rate (t - t_init)``.
* ``sensor_lag`` (output; state: sensed level ``z``): first-order filter of the level the
  dynamics produce, ``lag z' = level_ref(Q) + x - z``, integrated exactly with the FOPDT
  (one ARX sample at a time for ARX plants). The seiche, inflow and drift terms are added
  after it (a lag much shorter than their time scales, the usual case, makes the order
  immaterial).

For the MPC each block gives either a linear discrete-time state-space at a sample period
(:meth:`EffectBlock.state_space`; inputs and outputs named in :attr:`EffectBlock.mpc`) or a
documented constraint/inverse (nonlinear blocks). This module holds data and renderings; the
arithmetic of the simulation is in :mod:`gatetwin.plant.blocks`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np
from scipy import linalg

from gatetwin.errors import ModelFileError
from gatetwin.plant import blocks

__all__ = [
    "BLOCKS",
    "BLOCK_FIELDS",
    "DEFAULT_SUBSTEP_S",
    "KINDS",
    "ActuatorBacklash",
    "ActuatorRateLimit",
    "EffectBlock",
    "EffectSet",
    "FlowDependentGain",
    "InflowDisturbance",
    "OpeningNonlinearity",
    "ParameterSpec",
    "Seiche",
    "SensorDrift",
    "SensorLag",
    "effect_dict",
    "parameter_specs",
    "parse_effects",
]

#: Evaluation order of the blocks (also the order of their FMU parameters).
KINDS = (
    "actuator_rate_limit",
    "actuator_backlash",
    "opening_nonlinearity",
    "flow_dependent_gain",
    "seiche",
    "inflow_disturbance",
    "sensor_drift",
    "sensor_lag",
)
#: Default sub-step grid of the rate-limited actuator for FOPDT plants, s.
DEFAULT_SUBSTEP_S = 0.1


@dataclass(frozen=True)
class ParameterSpec:
    """One block parameter: name (with unit), unit, meaning and allowed range.

    ``minimum < value`` when ``minimum_exclusive`` else ``minimum <= value``; and
    ``value <= maximum``. ``fixed`` parameters are FMI ``fixed`` (settable only before
    initialisation); ``equilibrium`` ones change the initial (equilibrium) output.
    """

    name: str
    unit: str
    description: str
    minimum: float = -math.inf
    maximum: float = math.inf
    minimum_exclusive: bool = False
    fixed: bool = False
    equilibrium: bool = False
    default: float | None = None

    def problem(self, value: float) -> str:
        """Why ``value`` is not allowed ("" when it is)."""
        if not math.isfinite(value):
            return "must be finite"
        if self.minimum_exclusive and not value > self.minimum:
            return f"must be > {self.minimum:g}"
        if not self.minimum_exclusive and not value >= self.minimum:
            return f"must be >= {self.minimum:g}"
        if not value <= self.maximum:
            return f"must be <= {self.maximum:g}"
        return ""


@dataclass(frozen=True)
class EffectBlock:
    """Base of the blocks: the dictionary form and checks shared by all."""

    kind: ClassVar[str] = ""
    placement: ClassVar[str] = ""
    families: ClassVar[tuple[str, ...]] = ("fopdt", "arx")
    parameters: ClassVar[tuple[ParameterSpec, ...]] = ()
    #: What the MPC gets: "state_space: ..." or "constraint: ..." / "inverse: ...".
    mpc: ClassVar[str] = ""

    def to_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, **{f.name: getattr(self, f.name) for f in fields(self)}}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EffectBlock:
        """Checked block from its dictionary; :class:`ModelFileError` names the fault."""
        known = {p.name for p in cls.parameters}
        extra = sorted(set(data) - known - {"kind"})
        if extra:
            raise ModelFileError(f"effect {cls.kind}: unknown parameter(s) {', '.join(extra)}")
        values: dict[str, float] = {}
        for spec in cls.parameters:
            raw = data.get(spec.name, spec.default)
            if raw is None:
                raise ModelFileError(f"effect {cls.kind}: parameter {spec.name} missing")
            try:
                value = float(raw)
            except (TypeError, ValueError):
                raise ModelFileError(
                    f"effect {cls.kind}: {spec.name} must be a number (got {raw!r})"
                ) from None
            why = spec.problem(value)
            if why:
                raise ModelFileError(f"effect {cls.kind}: {spec.name} = {value!r} {why}")
            values[spec.name] = value
        return cls(**values)

    def state_space(self, sample_period_s: float) -> tuple[np.ndarray, ...]:
        raise NotImplementedError(f"{self.kind} is nonlinear: {self.mpc}")


def _zoh(a: np.ndarray, b: np.ndarray, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact zero-order-hold discretisation of ``x' = a x + b u``."""
    n, m = a.shape[0], b.shape[1]
    block = np.zeros((n + m, n + m))
    block[:n, :n], block[:n, n:] = a, b
    phi = linalg.expm(block * ts)
    return phi[:n, :n], phi[:n, n:]


def _check_period(sample_period_s: float) -> None:
    if not (sample_period_s > 0 and math.isfinite(sample_period_s)):
        raise ValueError(f"sample period {sample_period_s} s must be finite and > 0")


@dataclass(frozen=True)
class ActuatorRateLimit(EffectBlock):
    """The gate moves at a finite speed toward the commanded opening."""

    rate_mm_per_s: float
    substep_s: float = DEFAULT_SUBSTEP_S

    kind: ClassVar[str] = "actuator_rate_limit"
    placement: ClassVar[str] = "input"
    parameters: ClassVar[tuple[ParameterSpec, ...]] = (
        ParameterSpec("rate_mm_per_s", "mm/s", "Actuator speed: the gate moves toward the "
                      "commanded opening at this rate", 0.0, 1e6, minimum_exclusive=True),
        ParameterSpec("substep_s", "s", "Grid on which FOPDT dynamics sample the moving gate "
                      "(from the initialisation time)", 1e-3, 60.0, fixed=True,
                      default=DEFAULT_SUBSTEP_S),
    )  # fmt: skip
    mpc: ClassVar[str] = (
        "constraint: |c(k) - c(k-1)| <= rate_mm_per_s * Ts on the commanded opening "
        "(rate_constraint_mm); a plan that obeys it is followed with the gate reaching each "
        "command within the sample"
    )

    def rate_constraint_mm(self, sample_period_s: float) -> float:
        """Largest opening change per sample the gate can follow, mm."""
        _check_period(sample_period_s)
        return self.rate_mm_per_s * sample_period_s


@dataclass(frozen=True)
class ActuatorBacklash(EffectBlock):
    """A dead band between actuator and gate that is crossed on every reversal."""

    deadband_mm: float

    kind: ClassVar[str] = "actuator_backlash"
    placement: ClassVar[str] = "input"
    parameters: ClassVar[tuple[ParameterSpec, ...]] = (
        ParameterSpec("deadband_mm", "mm", "Play between actuator and gate: on a reversal the "
                      "actuator travels this far before the gate moves", 0.0, 1000.0),
    )  # fmt: skip
    mpc: ClassVar[str] = (
        "inverse: command = wanted gate opening + sign(move) * deadband_mm / 2 "
        "(compensate_mm), the direction of the last move kept as controller state"
    )

    def compensate_mm(self, wanted_gate_mm: float, direction: float) -> float:
        """Commanded opening that puts the gate at ``wanted_gate_mm`` after a move in
        ``direction`` (> 0 opening, < 0 closing; 0: centred, no compensation)."""
        return wanted_gate_mm + math.copysign(0.5 * self.deadband_mm, direction) * (direction != 0)


@dataclass(frozen=True)
class OpeningNonlinearity(EffectBlock):
    """The gain depends on the opening: local gain ``K exp(s (e - opening_ref))``."""

    gain_slope_per_mm: float

    kind: ClassVar[str] = "opening_nonlinearity"
    placement: ClassVar[str] = "input"
    parameters: ClassVar[tuple[ParameterSpec, ...]] = (
        ParameterSpec("gain_slope_per_mm", "1/mm", "Relative change of the level-opening gain "
                      "per mm of opening (rating-shaped: negative)", -0.25, 0.25,
                      equilibrium=True),
    )  # fmt: skip
    mpc: ClassVar[str] = (
        "inverse: plan in the effective input u = map(e - opening_ref) with the linear model "
        "and command e = opening_ref + inverse(u) (forward_mm / inverse_mm); opening bounds "
        "map through forward_mm (monotonic)"
    )

    def forward_mm(self, deviation_mm: float) -> float:
        return blocks.gain_map(deviation_mm, self.gain_slope_per_mm)

    def inverse_mm(self, effective_mm: float) -> float:
        return blocks.gain_map_inverse(effective_mm, self.gain_slope_per_mm)


@dataclass(frozen=True)
class FlowDependentGain(EffectBlock):
    """K and T follow the discharge: ``K exp(aK (Q - Q_ref))``, ``T exp(aT (Q - Q_ref))``."""

    gain_slope_per_m3h: float
    time_constant_slope_per_m3h: float
    flow_ref_m3h: float

    kind: ClassVar[str] = "flow_dependent_gain"
    placement: ClassVar[str] = "dynamics"
    families: ClassVar[tuple[str, ...]] = ("fopdt",)
    parameters: ClassVar[tuple[ParameterSpec, ...]] = (
        ParameterSpec("gain_slope_per_m3h", "h/m3", "Relative change of K per m3/h of "
                      "discharge", -0.1, 0.1, equilibrium=True),
        ParameterSpec("time_constant_slope_per_m3h", "h/m3", "Relative change of T per m3/h "
                      "of discharge", -0.1, 0.1),
        ParameterSpec("flow_ref_m3h", "m3/h", "Discharge at which K and T are the schedule's",
                      0.0, 5000.0, equilibrium=True),
    )  # fmt: skip
    mpc: ClassVar[str] = (
        "linear at each discharge: evaluate K and T at the measured Q with factors(Q), as "
        "the schedule is re-evaluated"
    )

    def factors(self, flow_m3h: float) -> tuple[float, float]:
        """``(K factor, T factor)`` at ``flow_m3h``."""
        dq = flow_m3h - self.flow_ref_m3h
        return (math.exp(self.gain_slope_per_m3h * dq),
                math.exp(self.time_constant_slope_per_m3h * dq))  # fmt: skip


@dataclass(frozen=True)
class Seiche(EffectBlock):
    """A lightly damped oscillation of the pool excited by gate moves."""

    period_s: float
    decay_time_s: float
    amplitude_mm_per_mm: float

    kind: ClassVar[str] = "seiche"
    placement: ClassVar[str] = "output"
    families: ClassVar[tuple[str, ...]] = ("fopdt", "arx", "physical")
    parameters: ClassVar[tuple[ParameterSpec, ...]] = (
        ParameterSpec("period_s", "s", "Period of the oscillation", 0.0, 1e5,
                      minimum_exclusive=True),
        ParameterSpec("decay_time_s", "s", "Time for the envelope to fall by 1/e", 0.0, 1e6,
                      minimum_exclusive=True),
        ParameterSpec("amplitude_mm_per_mm", "mm/mm", "Initial envelope of the oscillation per "
                      "mm of gate move", -1e3, 1e3),
    )  # fmt: skip
    mpc: ClassVar[str] = (
        "state_space: input v = gate opening - opening_ref (mm), output level term (mm); "
        "states x1, x2"
    )

    def continuous(self) -> tuple[np.ndarray, ...]:
        w, sigma = 2.0 * math.pi / self.period_s, 1.0 / self.decay_time_s
        a = np.array([[0.0, 1.0], [-(sigma * sigma + w * w), -2.0 * sigma]])
        b = np.array([[0.0], [1.0]])
        c = np.array([[0.0, self.amplitude_mm_per_mm * w]])
        return a, b, c, np.zeros((1, 1))

    def state_space(self, sample_period_s: float) -> tuple[np.ndarray, ...]:
        """``(A, B, C, D)`` at ``Ts``, exact for ``v`` held over each sample."""
        _check_period(sample_period_s)
        a, b, c, d = self.continuous()
        ad, bd = _zoh(a, b, sample_period_s)
        return ad, bd, c, d


@dataclass(frozen=True)
class InflowDisturbance(EffectBlock):
    """The level answers changes of the measured discharge with a first-order lag."""

    gain_mm_per_m3h: float
    time_constant_s: float
    flow_ref_m3h: float

    kind: ClassVar[str] = "inflow_disturbance"
    placement: ClassVar[str] = "output"
    parameters: ClassVar[tuple[ParameterSpec, ...]] = (
        ParameterSpec("gain_mm_per_m3h", "mm/(m3/h)", "Steady level change per m3/h of "
                      "discharge", -1e4, 1e4, equilibrium=True),
        ParameterSpec("time_constant_s", "s", "Time constant of the level's answer to Q",
                      0.0, 1e6, minimum_exclusive=True),
        ParameterSpec("flow_ref_m3h", "m3/h", "Discharge at which the term is zero", 0.0,
                      5000.0, equilibrium=True),
    )  # fmt: skip
    mpc: ClassVar[str] = (
        "state_space: input Q - flow_ref_m3h (m3/h, a measured disturbance), output level "
        "term (mm); state x_q"
    )

    def state_space(self, sample_period_s: float) -> tuple[np.ndarray, ...]:
        """``(A, B, C, D)`` at ``Ts``, exact for ``Q`` held over each sample."""
        _check_period(sample_period_s)
        a = math.exp(-sample_period_s / self.time_constant_s)
        return (np.array([[a]]), np.array([[self.gain_mm_per_m3h * (1.0 - a)]]),
                np.array([[1.0]]), np.zeros((1, 1)))  # fmt: skip


@dataclass(frozen=True)
class SensorDrift(EffectBlock):
    """The gauge's zero drifts linearly in time."""

    rate_mm_per_s: float

    kind: ClassVar[str] = "sensor_drift"
    placement: ClassVar[str] = "output"
    parameters: ClassVar[tuple[ParameterSpec, ...]] = (
        ParameterSpec("rate_mm_per_s", "mm/s", "Drift of the reading", -1e3, 1e3),
    )  # fmt: skip
    mpc: ClassVar[str] = (
        "state_space: no input; states (offset mm, rate mm/s), x0 = (0, rate_mm_per_s); "
        "output the offset (an integrating output disturbance for the observer)"
    )

    def state_space(self, sample_period_s: float) -> tuple[np.ndarray, ...]:
        _check_period(sample_period_s)
        return (np.array([[1.0, sample_period_s], [0.0, 1.0]]), np.zeros((2, 0)),
                np.array([[1.0, 0.0]]), np.zeros((1, 0)))  # fmt: skip


@dataclass(frozen=True)
class SensorLag(EffectBlock):
    """The gauge reports a first-order filtered level."""

    time_constant_s: float

    kind: ClassVar[str] = "sensor_lag"
    placement: ClassVar[str] = "output"
    parameters: ClassVar[tuple[ParameterSpec, ...]] = (
        ParameterSpec("time_constant_s", "s", "Time constant of the gauge's filter", 0.0, 1e5,
                      minimum_exclusive=True),
    )  # fmt: skip
    mpc: ClassVar[str] = (
        "state_space: input the level of the dynamics (mm), output the sensed level (mm); "
        "for exactness with an FOPDT discretise the cascade from continuous()"
    )

    def continuous(self) -> tuple[np.ndarray, ...]:
        tau = self.time_constant_s
        return (np.array([[-1.0 / tau]]), np.array([[1.0 / tau]]), np.array([[1.0]]),
                np.zeros((1, 1)))  # fmt: skip

    def state_space(self, sample_period_s: float) -> tuple[np.ndarray, ...]:
        """``(A, B, C, D)`` at ``Ts`` for a level held over each sample (ARX plants)."""
        _check_period(sample_period_s)
        a = math.exp(-sample_period_s / self.time_constant_s)
        return np.array([[a]]), np.array([[1.0 - a]]), np.array([[1.0]]), np.zeros((1, 1))


BLOCKS: dict[str, type[EffectBlock]] = {
    cls.kind: cls
    for cls in (
        ActuatorRateLimit,
        ActuatorBacklash,
        OpeningNonlinearity,
        FlowDependentGain,
        Seiche,
        InflowDisturbance,
        SensorDrift,
        SensorLag,
    )  # fmt: skip
}


@dataclass(frozen=True)
class EffectSet:
    """The checked blocks of one plant, at most one of each kind (None when absent)."""

    rate_limit: ActuatorRateLimit | None = None
    backlash: ActuatorBacklash | None = None
    nonlinearity: OpeningNonlinearity | None = None
    flow_gain: FlowDependentGain | None = None
    seiche: Seiche | None = None
    inflow: InflowDisturbance | None = None
    drift: SensorDrift | None = None
    lag: SensorLag | None = None

    @property
    def blocks(self) -> tuple[EffectBlock, ...]:
        """Present blocks in evaluation order."""
        present = (getattr(self, f.name) for f in fields(self))
        return tuple(b for b in present if b is not None)

    def __bool__(self) -> bool:
        return bool(self.blocks)


#: Field of :class:`EffectSet` (and C macro stem, upper-cased) of each kind.
BLOCK_FIELDS = {
    "actuator_rate_limit": "rate_limit", "actuator_backlash": "backlash",
    "opening_nonlinearity": "nonlinearity", "flow_dependent_gain": "flow_gain",
    "seiche": "seiche", "inflow_disturbance": "inflow", "sensor_drift": "drift",
    "sensor_lag": "lag",
}  # fmt: skip


def parse_effects(effects: tuple[dict[str, Any], ...] | list[Any], family: str) -> EffectSet:
    """Check a plant's effect dictionaries and return its :class:`EffectSet`.

    Raises
    ------
    ModelFileError
        Unknown kind, a kind twice, a parameter missing, unknown or out of range, or a block
        the plant's family cannot carry.
    """
    found: dict[str, EffectBlock] = {}
    for item in effects:
        if not isinstance(item, dict) or "kind" not in item:
            raise ModelFileError("effects: every entry must be an object with a 'kind'")
        kind = item["kind"]
        if kind not in BLOCKS:
            raise ModelFileError(f"effects: unknown kind {kind!r}; known: {', '.join(KINDS)}")
        if kind in found:
            raise ModelFileError(f"effects: {kind} given twice (at most one block of a kind)")
        block = BLOCKS[kind].from_dict(item)
        if family not in block.families:
            raise ModelFileError(f"effects: {kind} applies to {', '.join(block.families)} "
                                 f"plants, not {family}")  # fmt: skip
        found[kind] = block
    return EffectSet(**{BLOCK_FIELDS[k]: b for k, b in found.items()})


def effect_dict(kind: str, **parameters: float) -> dict[str, Any]:
    """A checked effect dictionary (defaults filled in) for a plant's ``effects``."""
    if kind not in BLOCKS:
        raise ModelFileError(f"effects: unknown kind {kind!r}; known: {', '.join(KINDS)}")
    return BLOCKS[kind].from_dict({"kind": kind, **parameters}).to_dict()


def parameter_specs(kind: str) -> tuple[ParameterSpec, ...]:
    """The parameters of one block kind, in FMU order."""
    return BLOCKS[kind].parameters
