"""Plants for the closed loop, all behind one step interface: ``y = plant.step(u, Q)``.

A :class:`LoopPlant` is what a controller talks to: it rounds the commanded opening to
the actuator's resolution (1 mm: the controllers never round), advances a *core* by one
control period, and returns the level a gauge would read (true level plus noise at the
gauge's 0.1 mm resolution). Cores give the true level:

* :class:`ModelCore` — the Python reference simulation of a plant
  (:class:`gatetwin.plant.PlantSimulator`);
* :class:`FmuCore` — an exported FMU driven through fmpy (co-simulation);
* :class:`FlumeCore` — the virtual flume, one :func:`gatetwin.flume.run_flume` call per
  sample with the hydraulic state and the leaf position carried over. The actuator moves
  the leaf at its own load-dependent speed; the level answers inflow changes physically.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from gatetwin.errors import ControlError, GatetwinError
from gatetwin.flume import FlumeConfig, run_flume, spin_up
from gatetwin.flume.solver import HydraulicState
from gatetwin.mpc.discrete import SAMPLE_PERIOD_S
from gatetwin.plant.model import Plant
from gatetwin.plant.simulate import PlantSimulator


class PlantCore(Protocol):
    """A simulated process: true level after each control period.

    A core whose gauge reads something other than the true level (a plant with sensor
    blocks) also has ``reading_mm``, the reading after the last call; the loop measures it.
    """

    description: str

    def start(self, opening_mm: float, flow_m3h: float) -> float:
        """Steady state for the inputs; returns the true level, mm."""
        ...

    def advance(self, opening_mm: float, flow_m3h: float) -> float:
        """Hold the inputs for one control period; returns the true level, mm."""
        ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class MeasurementNoise:
    """Gauge noise: AR(1) fluctuations plus the gauge's resolution.

    Modelled on :mod:`gatetwin.flume.logger` (surface fluctuations correlated over a few
    seconds, 0.1 mm resolution) with one fixed standard deviation instead of the logger's
    Froude-dependent one, so that both plants see the same noise.

    Attributes
    ----------
    sd_mm : float
        Standard deviation of the reading about the true level, mm.
    correlation_s : float
        Correlation time of the fluctuations, s.
    resolution_mm : float
        Reading resolution, mm.
    seed : int
        Seed of the noise sequence.
    """

    sd_mm: float = 0.7
    correlation_s: float = 1.5
    resolution_mm: float = 0.1
    seed: int = 0

    def __post_init__(self) -> None:
        if not (self.sd_mm >= 0 and self.correlation_s > 0 and self.resolution_mm >= 0):
            raise ControlError("measurement noise: need sd >= 0, correlation > 0, resolution >= 0")


class LoopPlant:
    """One step interface for every plant: ``start`` once, then ``step`` per sample.

    Parameters
    ----------
    core : PlantCore
        The simulated process.
    noise : MeasurementNoise or None
        Gauge noise; ``None`` for exact readings.
    actuator_resolution_mm : float
        The opening is rounded to a multiple of this before it reaches the core; 0 = none.
    sample_period_s : float
        Control period, s.
    """

    def __init__(
        self,
        core: PlantCore,
        *,
        noise: MeasurementNoise | None = None,
        actuator_resolution_mm: float = 1.0,
        sample_period_s: float = SAMPLE_PERIOD_S,
    ) -> None:
        if not actuator_resolution_mm >= 0:
            raise ControlError("actuator resolution must be >= 0 mm")
        self.core = core
        self.noise = noise
        self.actuator_resolution_mm = actuator_resolution_mm
        self.sample_period_s = sample_period_s
        self.true_level_mm = math.nan
        self.applied_opening_mm = math.nan
        self._rng = np.random.default_rng(noise.seed if noise else 0)
        self._ar = 0.0

    def quantise(self, opening_mm: float) -> float:
        r = self.actuator_resolution_mm
        return float(opening_mm) if r == 0 else float(np.round(opening_mm / r) * r)

    def start(self, opening_mm: float, flow_m3h: float) -> float:
        """Steady start; returns the measured level, mm."""
        self.applied_opening_mm = self.quantise(opening_mm)
        self.true_level_mm = self.core.start(self.applied_opening_mm, flow_m3h)
        self._ar = float(self._rng.standard_normal())
        return self._measure()

    def step(self, opening_mm: float, flow_m3h: float) -> float:
        """Apply the opening for one sample at ``flow_m3h``; returns the measured level, mm."""
        if not math.isfinite(opening_mm):
            raise ControlError(f"plant: opening {opening_mm} mm is not finite")
        self.applied_opening_mm = self.quantise(opening_mm)
        self.true_level_mm = self.core.advance(self.applied_opening_mm, flow_m3h)
        return self._measure()

    def _measure(self) -> float:
        # a core with sensor blocks reads something other than the true level
        reading = getattr(self.core, "reading_mm", self.true_level_mm)
        if self.noise is None:
            return reading
        phi = math.exp(-self.sample_period_s / self.noise.correlation_s)
        self._ar = phi * self._ar + math.sqrt(1.0 - phi * phi) * float(self._rng.standard_normal())
        reading = reading + self.noise.sd_mm * self._ar
        res = self.noise.resolution_mm
        return reading if res == 0 else float(np.round(reading / res) * res)

    def close(self) -> None:
        self.core.close()


class ModelCore:
    """The Python reference simulation of a plant (exact, fast).

    The true level is the water level (:attr:`PlantSimulator.process_level_mm`);
    ``reading_mm`` is what the plant's gauge reads, which differs from it by the sensor
    blocks (lag, drift) the plant may carry.
    """

    def __init__(self, plant: Plant, sample_period_s: float = SAMPLE_PERIOD_S) -> None:
        self.plant = plant
        self.sample_period_s = sample_period_s
        self.description = f"python reference simulation of the {plant.kind} plant"
        self._sim = PlantSimulator(plant)
        self.reading_mm = math.nan

    def start(self, opening_mm: float, flow_m3h: float) -> float:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # Q beyond the knots: clamped
            self._sim.initialize(opening_mm, flow_m3h)
        self.reading_mm = self._sim.level_mm
        return self._sim.process_level_mm

    def advance(self, opening_mm: float, flow_m3h: float) -> float:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            self.reading_mm = self._sim.do_step(self.sample_period_s, opening_mm, flow_m3h)
        return self._sim.process_level_mm

    def close(self) -> None:
        return None


class FmuCore:
    """An FMI 2.0 co-simulation FMU (inputs ``opening_mm``, ``flow_m3h``) through fmpy."""

    def __init__(self, fmu_path: str | Path, sample_period_s: float = SAMPLE_PERIOD_S) -> None:
        from gatetwin.fmi_host import UnpackedFmu

        self.path = Path(fmu_path)
        self.sample_period_s = sample_period_s
        self.description = f"FMU {self.path.name} (fmpy co-simulation)"
        self._fmu = UnpackedFmu(self.path, error=ControlError)
        self._vr = self._fmu.vr
        outputs = [n for n, v in self._fmu.variables.items() if v.causality == "output"]
        if not {"opening_mm", "flow_m3h"} <= set(self._vr) or len(outputs) != 1:
            self._fmu.cleanup()
            raise ControlError(
                f"{self.path.name}: expected inputs opening_mm, flow_m3h and one output"
            )
        self._out = self._vr[outputs[0]]
        self.time_s = 0.0

    @property
    def _slave(self) -> Any:
        """The open instance (``None`` before the first start or after a refused one)."""
        return self._fmu.instance

    def start(self, opening_mm: float, flow_m3h: float) -> float:
        slave = self._fmu.open("gatetwin_mpc")
        self.time_s = 0.0
        slave.initialise(0.0, ([self._vr["opening_mm"], self._vr["flow_m3h"]],
                               [opening_mm, flow_m3h]))  # fmt: skip
        return float(slave.getReal([self._out])[0])

    def _set(self, opening_mm: float, flow_m3h: float) -> None:
        self._slave.setReal(
            [self._vr["opening_mm"], self._vr["flow_m3h"]], [float(opening_mm), float(flow_m3h)]
        )

    def advance(self, opening_mm: float, flow_m3h: float) -> float:
        if self._slave is None:
            raise ControlError("fmu: start() before advance()")
        from fmpy.fmi1 import FMICallException

        try:
            self._set(opening_mm, flow_m3h)
            self._slave.doStep(
                currentCommunicationPoint=self.time_s, communicationStepSize=self.sample_period_s
            )
        except FMICallException as exc:
            raise ControlError(
                f"fmu {self.path.name}: step at t = {self.time_s} s refused ({exc})"
            ) from None
        self.time_s += self.sample_period_s
        return float(self._slave.getReal([self._out])[0])

    def close(self) -> None:
        self._fmu.close()

    def cleanup(self) -> None:
        """Close and delete the extracted FMU."""
        self._fmu.cleanup()


class FlumeCore:
    """The virtual flume at one gauge; level = true depth + the gauge's datum offset.

    Parameters
    ----------
    config : FlumeConfig
        The flume.
    gauge : str
        Gauge whose level is returned (``"3F"``).
    spin_up_s : float
        Duration of the steady spin-up at the start inputs, s.
    """

    def __init__(
        self, config: FlumeConfig | None = None, gauge: str = "3F", spin_up_s: float = 900.0
    ) -> None:
        self.config = config or FlumeConfig()
        if gauge not in self.config.gauges_m:
            raise ControlError(
                f"flume: no gauge {gauge!r} (have {', '.join(self.config.gauges_m)})"
            )
        self.gauge = gauge
        self.spin_up_s = spin_up_s
        self.description = f"virtual flume (Saint-Venant), gauge {gauge}"
        self.position_mm = math.nan
        self._state: HydraulicState | None = None
        self._last = (math.nan, math.nan)

    def _level(self, depth_mm: float) -> float:
        return float(depth_mm + self.config.gauge_datum_mm.get(self.gauge, 0.0))

    def start(self, opening_mm: float, flow_m3h: float) -> float:
        try:
            self._state = spin_up(self.config, flow_m3h, opening_mm, self.spin_up_s)
            run = run_flume(
                self.config, np.full(2, opening_mm), np.full(2, flow_m3h), state=self._state
            )
        except GatetwinError as exc:
            raise ControlError(f"flume start: {exc}") from None
        self._state = run.final_state
        self.position_mm = float(run.position_mm[-1])
        self._last = (float(opening_mm), float(flow_m3h))
        return self._level(run.depth_mm[self.gauge][-1])

    def advance(self, opening_mm: float, flow_m3h: float) -> float:
        if self._state is None:
            raise ControlError("flume: start() before advance()")
        try:
            run = run_flume(
                self.config,
                np.array([self._last[0], opening_mm]),
                np.array([self._last[1], flow_m3h]),
                state=self._state,
                start_position_mm=self.position_mm,
            )
        except GatetwinError as exc:
            raise ControlError(f"flume: {exc}") from None
        self._state = run.final_state
        self.position_mm = float(run.position_mm[-1])
        self._last = (float(opening_mm), float(flow_m3h))
        return self._level(run.depth_mm[self.gauge][-1])

    def close(self) -> None:
        return None


__all__ = ["FlumeCore", "FmuCore", "LoopPlant", "MeasurementNoise", "ModelCore", "PlantCore"]
