"""What the FMUs of the components whose arithmetic casadi generates (the MPC controller,
:mod:`gatetwin.fmu.mpc_controller`; the observer, :mod:`gatetwin.fmu.observer_fmu`) share:
the schedule's parameters as variables, the GUID, the code digest and ``model_config.h``'s
common part (the glue's head, the ``GT_GEN_*`` macros ``generated_support.c`` reads, the
variable table).

This module describes; it neither generates arithmetic (:mod:`gatetwin.mpc.codegen`,
:mod:`gatetwin.mpc.observer_codegen`) nor builds (:mod:`gatetwin.fmu.c_build`).
"""

from __future__ import annotations

import hashlib
import json
import uuid
from pathlib import Path
from typing import Any

from gatetwin.fmu.c_build import (
    FMI_APIS,
    GENERATED_SUPPORT_FILES,
    GLUE_CORE_HEADERS,
    GLUE_CORE_SOURCES,
    c_double,
    fmu_target,
    templates_dir,
    write_atomically,
)
from gatetwin.fmu.description import (
    FmuDescription,
    VariableSpec,
    component_config_lines,
    variable_table_lines,
)
from gatetwin.mpc.codegen import COLUMNS, Layout, theta_names
from gatetwin.plant.model import FLOW_RANGE_M3H, FopdtPlant

#: The steady observer covariance at the start: the Riccati iteration stops when a step
#: moves no entry by more than this times the largest (round-off: the fixed point is reached
#: to a few ulps in ~200 iterations on the demo plant), and fails after this many iterations.
RICCATI_RTOL = 1e-14
RICCATI_MAX_ITER = 100_000

#: One variable: name, causality, variability, initial, unit, description, start.
Row = tuple[str, str, str, str | None, str, str, float | None]

_SCHEDULE_META = {
    "flow_m3h": ("m3/h", "Discharge knot of the schedule (strictly increasing)"),
    "gain_mm_per_mm": ("mm/mm", "Static gain K of level on opening"),
    "time_constant_s": ("s", "Time constant T (> 0)"),
    "dead_time_s": ("s", "Dead time L (>= 0, at most the export's largest)"),
    "level_ref_mm": ("mm", "Rating level at opening_ref_mm"),
    "opening_ref_mm": ("mm", "Reference opening of the schedule's model"),
}


def schedule_rows(plant: FopdtPlant) -> list[Row]:
    """The fixed parameters the generated functions take as ``theta``: the schedule's knots,
    its columns at each knot and ``opening_ref_mm``."""
    knots = plant.schedule.flow_m3h
    values = [*knots, *(v for c in COLUMNS for v in plant.schedule.values[c]),
              plant.opening_ref_mm]  # fmt: skip
    rows: list[Row] = []
    for name, value in zip(theta_names(len(knots)), values, strict=True):
        unit, text = _SCHEDULE_META[name.split(".")[-1].split("[")[0]]
        rows.append((name, "parameter", "fixed", "exact", unit, text, float(value)))
    return rows


def variables_of(rows: list[Row]) -> tuple[VariableSpec, ...]:
    """The rows as variables, value references in row order; every output depends initially
    on every other variable."""
    return tuple(
        VariableSpec(n, vr, c, var, init, u, d, s, initial_dependency=c != "output")
        for vr, (n, c, var, init, u, d, s) in enumerate(rows)
    )


def generated_guid(facts: Any) -> str:
    """A GUID from what the FMU is built from (JSON of ``facts``, sorted keys)."""
    text = json.dumps(facts, sort_keys=True, default=str)
    digest = hashlib.sha256(text.encode()).digest()
    return "{" + str(uuid.UUID(bytes=digest[:16], version=5)) + "}"


def code_digest(component_files: tuple[str, ...], mpc_modules: tuple[str, ...]) -> str:
    """sha256 (16 hex digits) of the fixed C the FMU is built from (either FMI glue and the
    core both stand on: one GUID for both) and of the :mod:`gatetwin.mpc` modules its
    arithmetic is generated from."""
    digest = hashlib.sha256()
    glues = (*(api.glue for api in FMI_APIS.values()), *GLUE_CORE_SOURCES, *GLUE_CORE_HEADERS)
    for n in (*glues, *component_files, *GENERATED_SUPPORT_FILES, "component.h"):
        digest.update((templates_dir() / n).read_bytes())
    mpc = Path(__file__).resolve().parents[1] / "mpc"
    for n in mpc_modules:
        digest.update((mpc / n).read_bytes())
    return digest.hexdigest()[:16]


def config_header(
    desc: FmuDescription,
    component_header: str,
    layout: Layout,
    sizes: dict[str, dict[str, int]],
    sample_period_s: float,
    component_lines: list[str],
    value_references: dict[str, str],
    schedule: bool = True,
) -> str:
    """``model_config.h``: the glue's head, the ``GT_GEN_*`` macros (sizes of the generated
    code's arrays, the observer's states, the sample period, the limits), the component's own
    ``component_lines``, ``VR_<MACRO>`` for each ``value_references`` (macro -> variable
    name) and, with ``schedule``, the schedule's, and the variable table."""
    vr = {v.name: v.vr for v in desc.variables}
    big = {k: max(s[k] for s in sizes.values()) for k in ("arg", "res", "iw", "w")}
    max_dead_time_s = layout.register * sample_period_s * (1.0 - 1e-9)  # L = n Ts + θ, n < m
    lines = [
        *component_config_lines(desc, component_header),
        f"#define GT_N_KNOTS {desc.n_knots}",
        "",
        "/* the generated code (generated_support.c) */",
        f"#define GT_GEN_NZ {layout.n_states}",
        f"#define GT_GEN_NP {(layout.n_states + 1) ** 2}",
        f"#define GT_GEN_SZ_ARG {big['arg']}",
        f"#define GT_GEN_SZ_RES {big['res']}",
        f"#define GT_GEN_SZ_IW {max(1, big['iw'])}",
        f"#define GT_GEN_SZ_W {max(1, big['w'])}",
        f"#define GT_GEN_SAMPLE_PERIOD_S {c_double(sample_period_s)}",
        f"#define GT_GEN_FLOW_MIN_M3H {c_double(FLOW_RANGE_M3H[0])}",
        f"#define GT_GEN_FLOW_MAX_M3H {c_double(FLOW_RANGE_M3H[1])}",
        f"#define GT_GEN_MAX_DEAD_TIME_S {c_double(max_dead_time_s)}",
        f"#define GT_GEN_RICCATI_RTOL {c_double(RICCATI_RTOL)}",
        f"#define GT_GEN_RICCATI_MAX_ITER {RICCATI_MAX_ITER}",
        "",
        *component_lines,
        "",
        "/* value references (indices into ModelData.real) */",
        *(f"#define VR_{macro} {vr[name]}" for macro, name in value_references.items()),
    ]
    if schedule:
        lines += [
            f"#define VR_THETA {vr['schedule.flow_m3h[1]']}",
            f"#define VR_COL_FLOW_M3H {vr['schedule.flow_m3h[1]']}",
            *(f"#define VR_COL_{c.upper()} {vr[f'schedule.{c}[1]']}" for c in COLUMNS),
        ]
    return "\n".join(lines + variable_table_lines(desc.variables))


__all__ = ["RICCATI_MAX_ITER", "RICCATI_RTOL", "code_digest", "config_header", "fmu_target",
           "generated_guid", "schedule_rows", "variables_of", "write_atomically"]  # fmt: skip
