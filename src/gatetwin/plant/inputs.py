"""Input checks every plant rendering shares, and the error a refused input raises."""

from __future__ import annotations

from gatetwin.errors import SimulationError
from gatetwin.plant.model import FLOW_RANGE_M3H, OPENING_RANGE_MM

__all__ = ["check_inputs"]


def check_inputs(opening_mm: float, flow_m3h: float) -> None:
    """Refuse NaN or physically impossible inputs (as the FMUs do with fmi2Error)."""
    if not OPENING_RANGE_MM[0] <= opening_mm <= OPENING_RANGE_MM[1]:
        raise SimulationError(
            f"opening_mm = {opening_mm} is outside [{OPENING_RANGE_MM[0]}, {OPENING_RANGE_MM[1]}]"
        )
    if not FLOW_RANGE_M3H[0] <= flow_m3h <= FLOW_RANGE_M3H[1]:
        raise SimulationError(
            f"flow_m3h = {flow_m3h} is outside [{FLOW_RANGE_M3H[0]}, {FLOW_RANGE_M3H[1]}]"
        )
