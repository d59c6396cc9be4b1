"""The ARX family's part of the pythonfmu slave: its coefficients at the discharge, the
equilibrium, the envelope's scaling and the step sample by sample.

Spliced into the slave at export like ``slave_guard.py`` (between the BEGIN/END markers of
``slave_template.py``), without its imports of gatetwin: the slave defines those names
itself, so this file too uses the standard library only once embedded.
:class:`ArxFamily` is a mixin of ``GatetwinPlant``, which holds the instance's variables and
state; it mirrors fmu_templates/model_arx.c, and its arithmetic is gatetwin/plant/blocks.py's.
It is not the plant's pipeline (``slave_template.py``) nor the gate-law envelope
(``slave_physical.py``).
"""

from __future__ import annotations

# BEGIN gatetwin imports (removed at export: the slave defines these names)
from gatetwin.fmu.slave_config import CONFIG, PlantError, _g
from gatetwin.plant.blocks import (
    arx_envelope_coefficients,
    arx_equilibrium,
    arx_sample,
    first_order,
)

# END gatetwin imports

__all__ = ["ArxFamily"]


class ArxFamily:
    """The ARX family (model_arx.c): methods of ``GatetwinPlant``."""

    def _arx_check_parameters(self) -> None:
        period = self.real[self._vr("sample_period_s")]
        if not period > 0.0:
            raise PlantError(f"sample_period_s = {_g(period)} must be > 0")

    def _arx_coefficients(self, q: float) -> tuple[list[float], list[float]]:
        na, nb, _ = CONFIG["arx_orders"]
        a = [self._at(f"a{i}", q) for i in range(1, na + 1)]
        b = [self._at(f"b{j}", q) for j in range(1, nb + 1)]
        return a, b

    def _arx_equilibrium(self, u: float, q: float) -> float:
        if self._envelope():
            return self._envelope_point(u, q)[0]
        na, nb, _ = CONFIG["arx_orders"]
        a, b = self._arx_coefficients(q)
        sum_a, x0 = arx_equilibrium(a, b, u, na, nb)
        if sum_a == 1.0:
            raise PlantError(
                f"arx: no equilibrium at flow_m3h = {_g(self.real[self.vr_flow])} "
                "(sum of a coefficients is 1)"
            )
        return x0

    def _arx_initialize(self, u: float, x0: float) -> None:
        na, nb, nk = CONFIG["arx_orders"]
        u_in = x0 if self._envelope() else u  # an envelope ARX's input is a level
        self.dyn = {"x": x0, "x_hist": [x0] * na, "u_hist": [u_in] * (nk + nb - 1)}

    def _arx_envelope(self, u: float, q: float, a: list[float], b: list[float]
                      ) -> tuple[float, list[float], list[float]]:  # fmt: skip
        """The gate law's steady level and the coefficients scaled there (model_arx.c)."""
        level, tau = self._envelope_point(u, q)
        a_now, b_now = [0.0], [0.0] * len(b)
        arx_envelope_coefficients(a, b, a_now, b_now, len(b), self._at("time_constant_ref_s", q),
                                  tau)  # fmt: skip
        return level, a_now, b_now

    def _arx_samples(self, h: float) -> int:
        period = self.real[self._vr("sample_period_s")]
        n_float = h / period
        if not n_float <= CONFIG["arx_max_substeps"]:
            raise PlantError(
                f"communication step {_g(h)} s spans more than "
                f"{CONFIG['arx_max_substeps']:.0e} ARX samples"
            )
        n = round(n_float)
        if n < 1 or abs(n_float - n) > CONFIG["arx_step_rtol"] * max(1.0, n_float):
            raise PlantError(
                f"communication step {_g(h)} s is not a whole multiple of the ARX sample "
                f"period {_g(period)} s"
            )
        return n

    def _arx_step(self, n: int, command: float, q: float) -> None:
        na, nb, nk = CONFIG["arx_orders"]
        a, b = a0, b0 = self._arx_coefficients(q)
        d, fx = self.dyn, self.fx
        ts = self.real[self._vr("sample_period_s")]
        level_ref = self._at("level_ref_mm", q)
        rate_limited = self._has("actuator_rate_limit")
        duration = 0.0 if rate_limited else ts
        for _ in range(n):
            self._actuate(fx, command, duration)
            fx["held_gate_mm"] = fx["gate_mm"]
            u = self._effective_input(fx["gate_mm"])
            if self._envelope():
                u, a, b = self._arx_envelope(u, q, a0, b0)
            x_new = arx_sample(d["x_hist"], d["u_hist"], a, b, u, na, nb, nk)
            d["x"] = x_new
            if self._has("sensor_lag"):
                fx["sensed_mm"] = first_order(fx["sensed_mm"], level_ref + x_new, ts,
                                              self._p("sensor_lag", "time_constant_s"))  # fmt: skip
            self._seiche_piece(ts, fx["gate_mm"])
            duration = ts
        if rate_limited:
            self._actuate(fx, command, ts)
