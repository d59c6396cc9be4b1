"""A field-scale two-pool canal as an EPA SWMM model, written by the tests (not the shipped
ASCE canal): a 3 m wide, 2 m high check gate passing about 10 m³/s with some 2–2.5 m of
water above its sill, a 120 m upstream pool (bed 6 m, side slopes 1.5:1) and a downstream
pool drained by a second gate, so the check runs submerged as in a real canal. The initial
depths are near the steady state at the base point (1 m opening), which shortens spin-up."""

from __future__ import annotations

from pathlib import Path

#: The check gate: width and height, m; its discharge coefficient.
GATE_WIDTH_M, GATE_HEIGHT_M, GATE_CD = 3.0, 2.0, 0.62
#: Base inflow, m³/s, and the base opening, mm.
FLOW_M3S = 10.0
OPENING_MM = 1000.0
#: Gauge nodes and their distances upstream of the gate, m.
GAUGES = {"U2": 0.0, "U1": 60.0, "U0": 120.0}
INFLOW_NODE = "U0"
GATE = "CHECK"

FIELD_CANAL = f"""[TITLE]
a field-scale two-pool test canal

[OPTIONS]
FLOW_UNITS           CMS
FLOW_ROUTING         DYNWAVE
LINK_OFFSETS         DEPTH
START_DATE           03/01/2021
START_TIME           06:00:00
END_DATE             03/01/2021
END_TIME             07:00:00
REPORT_STEP          00:30:00
ROUTING_STEP         1
VARIABLE_STEP        0
INERTIAL_DAMPING     PARTIAL
NORMAL_FLOW_LIMITED  BOTH
MIN_SURFAREA         1.0

[JUNCTIONS]
U0 100.06 4.0 2.7 0 0
U1 100.03 4.0 2.73 0 0
U2 100.00 4.0 2.76 0 0
D0 99.90 4.0 1.39 0 0
D1 99.80 4.0 1.49 0 0

[OUTFALLS]
OUT 97.0 FREE NO

[CONDUITS]
CU1 U0 U1 60 0.016 0 0 0 0
CU2 U1 U2 60 0.016 0 0 0 0
CD1 D0 D1 150 0.016 0 0 0 0

[ORIFICES]
{GATE} U2 D0 SIDE 0 {GATE_CD} NO 0
TAIL D1 OUT SIDE 0 0.62 NO 0

[XSECTIONS]
CU1 TRAPEZOIDAL 4.0 6.0 1.5 1.5 1
CU2 TRAPEZOIDAL 4.0 6.0 1.5 1.5 1
CD1 TRAPEZOIDAL 4.0 6.0 1.5 1.5 1
{GATE} RECT_CLOSED {GATE_HEIGHT_M} {GATE_WIDTH_M} 0 0
TAIL RECT_CLOSED 2.0 4.0 0 0

[INFLOWS]
{INFLOW_NODE} FLOW "" FLOW 1.0 1.0 {FLOW_M3S}

[CONTROLS]
RULE TAIL_OPEN
IF SIMULATION TIME >= 0
THEN ORIFICE TAIL SETTING = 0.45
"""


def write_field_canal(folder: Path) -> Path:
    """Write the canal's ``.inp`` into ``folder``; returns its path."""
    path = Path(folder) / "field_canal.inp"
    path.write_text(FIELD_CANAL, encoding="utf-8")
    return path
