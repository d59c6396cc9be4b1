"""The physical family's part of the pythonfmu slave, and the gate-law envelope an FOPDT or
ARX plant may carry: the kernel's parameters and their checks, steady points and sub-steps.

Spliced into the slave at export like ``slave_guard.py`` (between the BEGIN/END markers of
``slave_template.py``), without its imports of gatetwin: the slave defines those names
itself, so this file too uses the standard library only once embedded.
:class:`PhysicalFamily` is a mixin of ``GatetwinPlant``, which holds the instance's variables
and state; it mirrors fmu_templates/model_physical.c and kernel_point.c around
gatetwin/plant/physical_kernel.py. It is not the plant's pipeline (``slave_template.py``) nor
the FMI layer (``slave_guard.py``).
"""

from __future__ import annotations

# BEGIN gatetwin imports (removed at export: the slave defines these names)
from gatetwin.fmu.slave_config import CONFIG, PlantError, _g
from gatetwin.plant import physical_kernel

# END gatetwin imports

__all__ = ["PhysicalFamily"]


class PhysicalFamily:
    """The physical family (model_physical.c around physical_kernel) and the envelope
    (kernel_point.c): methods of ``GatetwinPlant``."""

    def _physical(self) -> list[float]:
        first = CONFIG["kernel_first"]
        return self.real[first : first + len(physical_kernel.PARAMETERS)]

    def _physical_check_parameters(self) -> None:
        first = CONFIG["kernel_first"]
        for name, bound in CONFIG["physical_lower_bounds"].items():
            vr = first + physical_kernel.INDEX[name]
            if not self.real[vr] > bound:
                raise PlantError(f"parameter {self.variables[vr]['name']} = {_g(self.real[vr])} "
                                 f"must be > {_g(bound)}")  # fmt: skip
        if not physical_kernel.storage_room_m2(self._physical()) > 0.0:
            raise PlantError(f"the storage area {CONFIG['physical_storage_rule']}")
        if "level_mm" in CONFIG["validity"] and "flow_m3h" in CONFIG["validity"]:
            for level in CONFIG["validity"]["level_mm"][:2]:
                for flow in CONFIG["validity"]["flow_m3h"][:2]:
                    if not physical_kernel.operating_room_m2(level, flow, self._physical()) > 0.0:
                        raise PlantError(
                            f"the storage area at level {_g(level)} mm and {_g(flow)} m3/h: "
                            f"{CONFIG['physical_operating_storage_rule']}"
                        )

    def _envelope(self) -> bool:
        return CONFIG["family"] in ("fopdt", "arx") and CONFIG["kernel_first"] is not None

    def _envelope_point(self, u: float, q: float) -> tuple[float, float]:
        """Steady level and time constant at the opening u + opening_ref (kernel_point.c)."""
        return self._envelope_steady(u, q)[:2]

    def _envelope_steady(self, u: float, q: float) -> tuple[float, float, float]:
        """The same and the steady depth at the gate, m (kernel_envelope_steady); the
        steady-depth solve only when the opening, the discharge or a parameter changed (as
        ``piece_point`` of model_fopdt.c keeps its point while they are held)."""
        p = self._physical()
        e = u + self.real[self.vr_opening_ref]
        key = (e, q, *p)
        if self.steady_point[0] != key:
            depth = self._physical_depth(e, q)
            self.steady_point = (key, (
                physical_kernel.level_mm(depth, e, q, p),
                physical_kernel.time_constant_s(depth, e, q, p),
                depth,
            ))  # fmt: skip
        return self.steady_point[1]

    def _piece_point(self, u: float, x: float, q: float) -> tuple[float, float]:
        """A piece from the level x with u held: the target and the storage's secant time
        constant to it (piece_point of model_fopdt.c)."""
        target, tangent, depth = self._envelope_steady(u, q)
        e = u + self.real[self.vr_opening_ref]
        return target, physical_kernel.secant_time_constant_s(
            x, target, depth, tangent, e, q, self._physical()
        )

    def _tail_pool(self) -> bool:
        """An envelope FOPDT whose gate discharges into a pool (model_fopdt.c)."""
        return self._envelope() and bool(physical_kernel.has_tail(self._physical()))

    def _tail_pool_piece(self, u: float, q: float, duration_s: float) -> None:
        """Sub-steps of the kernel's tail_pool_piece (tail_piece of model_fopdt.c)."""
        p, d = self._physical(), self.dyn
        e = u + self.real[self.vr_opening_ref]
        n = int(physical_kernel.substep_count(duration_s, p))
        for _ in range(n):
            steady = self._physical_depth(e, q, d["tail_m"])
            d["x"], d["tail_m"] = physical_kernel.tail_pool_piece(
                d["x"], d["tail_m"], steady, e, q, duration_s / n, p
            )

    def _level_offset(self, q: float) -> float:
        return 0.0 if self._envelope() else self._at("level_ref_mm", q)

    def _physical_depth(self, gate_mm: float, q: float, tail_m: float | None = None) -> float:
        """The steady depth (kernel_point.c): the tail pool steady, or held at ``tail_m``."""
        k, p = physical_kernel, self._physical()
        if tail_m is None:
            return k.steady_depth_m(gate_mm, q, p)
        return k.held_steady_depth_m(tail_m, gate_mm, q, p)

    def _physical_level(self, depth_m: float, gate_mm: float, q: float) -> float:
        return physical_kernel.level_mm(depth_m, gate_mm, q, self._physical())

    def _physical_initialize(self, u: float, x0: float, q: float) -> None:
        gate = physical_kernel.actuator_target_mm(u, self._physical())
        self.dyn = {
            "x": x0,
            "depth_m": self._physical_depth(gate, q),
            "tail_m": physical_kernel.tail_steady_m(q, self._physical()),
            "gate_mm": gate,
        }

    def _physical_step(self, h: float, command: float, q: float) -> None:
        p = self._physical()
        n = physical_kernel.substep_count(h, p)
        if not n <= CONFIG["physical_max_substeps"]:
            raise PlantError(
                f"communication step {_g(h)} s needs {n:.0f} sub-steps of at most "
                f"{_g(p[physical_kernel.INDEX['max_substep_s']])} s; the limit is "
                f"{CONFIG['physical_max_substeps']}"
            )
        target = physical_kernel.actuator_target_mm(command, p)
        depth, tail, gate, dt = self.dyn["depth_m"], self.dyn["tail_m"], self.dyn["gate_mm"], h / n
        for _ in range(int(n)):
            start = gate  # drives the seiche over the sub-step (model_physical.c)
            depth, tail, gate = physical_kernel.substep(depth, tail, gate, target, q, dt, p)
            self._seiche_piece(dt, start)
        self.dyn = {
            "x": physical_kernel.level_mm(depth, gate, q, p),
            "depth_m": depth,
            "tail_m": tail,
            "gate_mm": gate,
        }
