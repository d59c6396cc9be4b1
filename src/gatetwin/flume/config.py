"""Configuration of the virtual flume: geometry, gate law, actuator and logger settings.

Every number the reference study does not give is a calibration choice; each is documented
here with why it has its value. ``gatetwin.flume.calibration`` recomputes the calibrated
ones from the published tables and a test holds these defaults to that computation.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from gatetwin.errors import FlumeError

__all__ = ["PAPER_GAUGES_M", "FlumeConfig", "GateLaw"]

#: Gauge name → distance upstream of the gate, m (the paper's Figure 1).
PAPER_GAUGES_M: dict[str, float] = {"1D": 3.0, "2E": 2.1, "3F": 1.1, "4G": 0.7, "5H": 0.2}


@dataclass(frozen=True)
class GateLaw:
    """Effective discharge coefficient of the free underflow, ``Cd(r, Q)`` with ``r = e/h``.

    ``q = Cd · e · sqrt(2 g h)`` per unit width, with ``h`` the depth just upstream of the
    gate. The paper's levels imply Cd ≈ 0.77–0.86, well above the textbook 0.6, falling
    with ``r`` and with a slope that steepens with discharge. The law is linear in ``r``
    inside the calibrated band ``[r_low, r_high]`` with intercept and slope interpolated
    linearly in Q between the two calibration flows (clamped outside them); below
    ``r_low`` it is constant; above ``r_high`` it continues with the same slope but
    saturates exponentially towards ``cd_large_r`` (the classical value for a gate barely
    touching the water), so it stays physical over the whole static grid.

    Attributes
    ----------
    flow_m3h : tuple[float, float]
        Calibration flows (conditions A and B), m³/h.
    intercept, slope : tuple[float, float]
        Cd = intercept + slope · r at each calibration flow.
    r_low, r_high : float
        Calibrated band of e/h.
    cd_large_r : float
        Asymptote of Cd for large e/h.
    """

    flow_m3h: tuple[float, float] = (29.5, 72.5)
    intercept: tuple[float, float] = (0.9195, 1.0133)
    slope: tuple[float, float] = (-1.2275, -1.8317)
    r_low: float = 0.05
    r_high: float = 0.14
    cd_large_r: float = 0.55


@dataclass(frozen=True)
class FlumeConfig:
    """The virtual flume of the reference study, with its calibration choices.

    Attributes
    ----------
    width_m : float
        Channel width, 0.30 m (paper).
    pool_length_m : float
        Length of the simulated reach from the inlet (stilling section) to the gate. The
        paper's time constants suggest ~1.4–1.5 m² of storage from a linearised orifice;
        with the calibrated Cd law (which makes the outflow more sensitive to the level)
        and the actuator below, 8.3 m reproduces T of Tables 2–3 (A: 71 s, B: 42 s) with
        the paper's method (medians over seeds within 2 %).
    bed_slope : float
        Bed slope (positive: the bed falls towards the gate). The gauges read ~11 mm more
        depth at 5H than at 1D in every condition; 1/250 reproduces that gradient.
    manning_n : float
        Manning roughness, s/m^(1/3): 0.010, a clean acrylic flume.
    dx_m : float
        Cell size, m (5 cm default: 1.1 m between gauges 3F and 4G spans 8 cells).
    cfl : float
        Courant number of the explicit scheme.
    gate : GateLaw
        Discharge-coefficient law.
    tailwater_depth_m : float | None
        Depth downstream of the gate; ``None`` is a free outfall (the paper's tailwater tank).
    actuator_speed_mm_s, actuator_stall_depth_m : float
        No-load speed of the gate (1.66 mm/s) and the depth at the gate at which the drive
        would stall (0.452 m): the speed falls as ``1 − (h/h_stall)²`` with the water load
        (see :func:`gatetwin.flume.solver.leaf_speed`). The paper's L is at least the
        motion time (motion samples are dropped before detection): ~4.5 s in A (h ≈ 0.24 m,
        5 mm at 1.2 mm/s) but 8–10 s in B (h ≈ 0.35 m, 0.67 mm/s). Both values follow from
        those two dead times.
    actuator_delay_s : float
        Time from the motor starting (the logger writes ``open``) to the leaf moving:
        slack in the drive taken up before the gate lifts.
    actuator_resolution_mm : float
        Position resolution, 1 mm (paper).
    gauges_m : dict[str, float]
        Gauge name → distance upstream of the gate, m.
    gauge_datum_mm : dict[str, float]
        Each gauge's datum offset, mm (installation offset of an ultrasonic gauge); fitted
        to the residual of the 20 published means after the bed slope.
    sample_period_s : float
        Logger period, 1.2 s (paper).
    """

    width_m: float = 0.30
    pool_length_m: float = 8.3
    bed_slope: float = 1.0 / 250.0
    manning_n: float = 0.010
    dx_m: float = 0.05
    cfl: float = 0.8
    gate: GateLaw = field(default_factory=GateLaw)
    tailwater_depth_m: float | None = None
    actuator_speed_mm_s: float = 1.66
    actuator_stall_depth_m: float = 0.452
    actuator_delay_s: float = 0.0
    actuator_resolution_mm: float = 1.0
    gauges_m: dict[str, float] = field(default_factory=lambda: dict(PAPER_GAUGES_M))
    gauge_datum_mm: dict[str, float] = field(
        default_factory=lambda: {"1D": 0.47, "2E": 1.66, "3F": -2.72, "4G": 0.09, "5H": 0.5}
    )
    sample_period_s: float = 1.2
    depth_limit_m: float = 0.40

    def __post_init__(self) -> None:
        checks = {
            "width_m": self.width_m > 0,
            "pool_length_m": self.pool_length_m > 0,
            "dx_m": 0 < self.dx_m <= self.pool_length_m / 10,
            "cfl": 0 < self.cfl <= 1,
            "manning_n": self.manning_n >= 0,
            "actuator_speed_mm_s": self.actuator_speed_mm_s > 0,
            "actuator_stall_depth_m": self.actuator_stall_depth_m > 0,
            "actuator_delay_s": self.actuator_delay_s >= 0,
            "sample_period_s": self.sample_period_s > 0,
        }
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise FlumeError(f"flume config: invalid {', '.join(bad)}")
        for name, dist in self.gauges_m.items():
            if not 0 <= dist <= self.pool_length_m - self.dx_m:
                raise FlumeError(
                    f"flume config: gauge {name} at {dist} m lies outside the simulated pool"
                )

    @property
    def n_cells(self) -> int:
        return max(10, round(self.pool_length_m / self.dx_m))

    def with_(self, **changes: object) -> FlumeConfig:
        """A copy with some fields changed."""
        return replace(self, **changes)  # type: ignore[arg-type]
