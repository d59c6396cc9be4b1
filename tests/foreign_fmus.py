"""A gate FMU gatetwin did not write: built with pythonfmu, its variables named and dimensioned
its own way (SI units), and a measured record of it, for the tests of validating other
people's FMUs."""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np

#: The foreign gate: level h (m) relaxing with time constant T towards
#: h_ss = H0 + A * Q - B * u (Q in m³/s, u in m), as a stranger might write it.
H0_M, A_S_PER_M2, B, T_S = 0.2, 5.0, 4.0, 30.0
SLAVE = textwrap.dedent(f"""
    import math

    from pythonfmu import Fmi2Causality, Fmi2Initial, Fmi2Slave, Real


    class ForeignGate(Fmi2Slave):
        description = "A first-order gate pool, SI units"

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.u_gate = 0.02
            self.Q_in = 0.01
            self.h_up = 0.0
            self.register_variable(Real("u_gate", causality=Fmi2Causality.input))
            self.register_variable(Real("Q_in", causality=Fmi2Causality.input))
            self.register_variable(Real("h_up", causality=Fmi2Causality.output,
                                        initial=Fmi2Initial.exact))

        def _steady(self):
            return {H0_M} + {A_S_PER_M2} * self.Q_in - {B} * self.u_gate

        def exit_initialization_mode(self):
            self.h_up = self._steady()

        def do_step(self, current_time, step_size):
            keep = math.exp(-step_size / {T_S})
            self.h_up = keep * self.h_up + (1.0 - keep) * self._steady()
            return True
""")
#: Gauge noise of the record, mm; the free-run fit then sits near 100 % less the noise's
#: share of the 20 mm step's variance (~97 %): 90 % passes with room, a wrong map cannot.
NOISE_MM = 0.5


def foreign_gate_fmu(folder: Path) -> Path:
    """The foreign gate's FMU, built with pythonfmu into ``folder``."""
    from pythonfmu.builder import FmuBuilder

    folder.mkdir(parents=True, exist_ok=True)
    script = folder / "foreign_gate.py"
    script.write_text(SLAVE, encoding="utf-8")
    return Path(FmuBuilder.build_FMU(script, dest=folder))


def foreign_gate_record(folder: Path) -> Path:
    """The foreign gate's response to a 20 -> 25 mm opening step at 40 m³/h, logged in mm
    and m³/h every second, with gauge noise."""
    rng = np.random.default_rng(5)
    n, q = 400, 40.0
    opening = np.where(np.arange(n) < 100, 20.0, 25.0)
    keep = math.exp(-1.0 / T_S)
    level = np.empty(n)
    steady = lambda e: 1000.0 * (H0_M + A_S_PER_M2 * q / 3600.0 - B * e / 1000.0)  # noqa: E731
    level[0] = steady(opening[0])
    for k in range(1, n):
        level[k] = keep * level[k - 1] + (1.0 - keep) * steady(opening[k - 1])
    lines = ["time_s,opening_mm,state,flow_m3h,level_3F_mm"]
    for k in range(n):
        lines.append(f"{k:.1f},{opening[k]:.1f},hold,{q:.1f},"
                     f"{level[k] + NOISE_MM * rng.standard_normal():.2f}")  # fmt: skip
    path = folder / "step.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
