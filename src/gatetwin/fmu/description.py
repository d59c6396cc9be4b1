"""The one description of a plant FMU's interface, and its two renderings.

:func:`describe` turns a plant into an :class:`FmuDescription`: every variable with its value
reference, causality, variability, unit, description and start value, decided here once.
:func:`model_config_header` renders it as the C FMU's ``model_config.h`` and
:func:`model_description_xml` as ``modelDescription.xml`` for both backends; the pythonfmu
slave reads the same description as JSON (:func:`slave_config`). Value references are never
written down anywhere else.

Variable names (FMI structured naming, 1-based knot index ``k``):

* ``opening_mm``, ``flow_m3h`` — inputs; ``level_<gauge>_mm`` — the output (absolute level);
* ``opening_ref_mm`` — tunable; ``sample_period_s`` (ARX only) — fixed;
* ``schedule.flow_m3h[k]`` — the discharge knots; ``schedule.<column>[k]`` — each schedule
  column at knot ``k`` (``gain_mm_per_mm``, ``time_constant_s``, ``dead_time_s``,
  ``level_ref_mm`` for FOPDT; ``a1``.., ``b1``.., ``level_ref_mm`` for ARX), all tunable;
* ``effect.<kind>.<parameter>`` — each effect block's parameters
  (:mod:`gatetwin.plant.effects`), tunable (the rate limit's ``substep_s`` fixed), with the
  block's limits checked by both backends.

This module builds nothing; see :mod:`gatetwin.fmu.c_build` and :mod:`gatetwin.fmu.python_build`.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import uuid
from dataclasses import dataclass, field, replace
from typing import Any, Protocol
from xml.etree import ElementTree as ET

from gatetwin.errors import ExportError, ModelFileError
from gatetwin.fmu.checks import (
    MAX_GAUGE_CHARS,
    c_string_literal,
    check_well_formed,
    gauge_name_ok,
    xml_text,
)
from gatetwin.fmu.limits import (
    MAX_COMMUNICATION_STEP_S,
    MAX_TIME_S,
    PARAMETER_MAX_ABS,
    VALIDITY_QUANTITIES,
    check_parameter_values,
    validity_ranges,
)
from gatetwin.plant import physical_kernel
from gatetwin.plant.effects import BLOCK_FIELDS, KINDS, parameter_specs
from gatetwin.plant.model import (
    FLOW_RANGE_M3H,
    LOWER_BOUNDS,
    OPENING_RANGE_MM,
    OPERATING_STORAGE_RULE,
    STORAGE_RULE,
    ArxPlant,
    FopdtPlant,
    PhysicalPlant,
    Plant,
    check_operating_storage,
    kernel_parameters,
    plant_to_dict,
)
from gatetwin.plant.physical import MAX_SUBSTEPS
from gatetwin.plant.simulate import (
    ARX_MAX_SUBSTEPS,
    ARX_STEP_RTOL,
    DELAY_HISTORY_CAPACITY,
    FOPDT_MAX_STEP_S,
)

__all__ = [
    "COMMUNICATION_POINT_RTOL",
    "LOG_CATEGORIES",
    "MAX_ARX_ORDER",
    "UNITS",
    "CoSimulationFlags",
    "ComponentInterface",
    "FmuDescription",
    "VariableSpec",
    "component_config_lines",
    "describe",
    "finished_xml",
    "guid_of",
    "initial_dependencies",
    "model_config_header",
    "model_description_xml",
    "output_name",
    "shared_elements",
    "slave_config",
    "variable_table_lines",
    "xml_bool",
]

#: Largest ARX orders the FMUs accept (fixed-size C state).
MAX_ARX_ORDER = 8
#: doStep refuses a currentCommunicationPoint further than this (relative) from the FMU's time.
COMMUNICATION_POINT_RTOL = 1e-9
#: Log categories both backends declare.
LOG_CATEGORIES = {
    "logStatusWarning": "Warnings (an input or the level outside the model's validity, or the "
    "discharge outside the schedule's knots)",
    "logStatusError": "Errors: refused inputs, parameters and communication steps",
    "logAll": "Everything, including informational messages",
}
#: name -> (description, SI base-unit exponents, factor to SI)
UNITS: dict[str, tuple[str, dict[str, int], float]] = {
    "mm": ("millimetre", {"m": 1}, 0.001),
    "m3/h": ("cubic metre per hour", {"m": 3, "s": -1}, 1.0 / 3600.0),
    "s": ("second", {"s": 1}, 1.0),
    "mm/mm": ("millimetre per millimetre (dimensionless)", {}, 1.0),
    "mm/s": ("millimetre per second", {"m": 1, "s": -1}, 0.001),
    "1/mm": ("per millimetre", {"m": -1}, 1000.0),
    "h/m3": ("per cubic metre per hour", {"m": -3, "s": 1}, 3600.0),
    "mm/(m3/h)": ("millimetre per cubic metre per hour", {"m": -2, "s": 1}, 3.6),
    "1": ("dimensionless", {}, 1.0),
    "m": ("metre", {"m": 1}, 1.0),
    "m2": ("square metre", {"m": 2}, 1.0),
}
_FOPDT_COLUMNS = {
    "gain_mm_per_mm": ("mm/mm", "Static gain K of level on opening"),
    "time_constant_s": ("s", "Time constant T (> 0)"),
    "dead_time_s": ("s", "Dead time L (>= 0; not above the largest at initialisation)"),
    "level_ref_mm": ("mm", "Rating level at opening_ref_mm"),
}
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")
#: What a variable name may hold to be written into model_config.h as a C string literal.
_C_NAME = re.compile(r"[A-Za-z0-9_.\[\]]{1,200}")


@dataclass(frozen=True)
class VariableSpec:
    """One FMI Real variable. ``kind`` is ``input``, ``output``, ``tunable`` or ``fixed``."""

    name: str
    vr: int
    causality: str
    variability: str
    initial: str | None
    unit: str
    description: str
    start: float | None
    initial_dependency: bool = True

    @property
    def kind(self) -> str:
        if self.causality == "parameter":
            return self.variability
        return self.causality


class ComponentInterface(Protocol):
    """What the renderings of an FMU's interface (``modelDescription.xml``, the head and the
    variable table of ``model_config.h``) need of a component: a plant
    (:class:`FmuDescription`) or a controller (:mod:`gatetwin.fmu.controller`)."""

    @property
    def model_identifier(self) -> str: ...

    @property
    def guid(self) -> str: ...

    @property
    def summary(self) -> str: ...

    @property
    def step_size_s(self) -> float: ...

    @property
    def variables(self) -> tuple[VariableSpec, ...]: ...

    @property
    def output(self) -> VariableSpec: ...


@dataclass(frozen=True)
class FmuDescription:
    """Everything both backends need to know about one exported plant.

    ``columns`` maps each schedule column (``flow_m3h`` for the knots first) to the value
    reference of its entry at the first knot; the entries at later knots follow it.
    ``effects`` maps each effect block's kind to ``{parameter: value reference}``.
    """

    model_identifier: str
    guid: str
    family: str
    gauge: str
    n_knots: int
    variables: tuple[VariableSpec, ...]
    columns: dict[str, int]
    arx_orders: tuple[int, int, int] | None
    step_size_s: float
    summary: str
    provenance: dict[str, Any] = field(default_factory=dict)
    effects: dict[str, dict[str, int]] = field(default_factory=dict)
    kernel_first: int | None = None

    @property
    def output(self) -> VariableSpec:
        return next(v for v in self.variables if v.causality == "output")

    def vr(self, name: str) -> int:
        return next(v.vr for v in self.variables if v.name == name)


def describe(
    plant: Plant, model_name: str, provenance: dict[str, Any], build_id: str,
    start_inputs: tuple[float, float] | None = None,
) -> FmuDescription:  # fmt: skip
    """The FMU description of ``plant``; raises :class:`ExportError` on what cannot be exported.

    ``build_id`` names the backend and a digest of its code; with the plant, the name and the
    provenance it determines the GUID, so a serialised FMU state only fits the build it came
    from. ``start_inputs`` (opening mm, discharge m3/h) replaces the inputs' start values (the
    point the FMU rests at when a master sets no input before initialising it).
    """
    _check_exportable(plant, model_name)
    specs = _variables(plant)
    if start_inputs is not None:
        starts = dict(zip(("opening_mm", "flow_m3h"), map(float, start_inputs), strict=True))
        if not all(math.isfinite(v) for v in starts.values()):
            raise ExportError(f"start inputs {tuple(start_inputs)} must be finite")
        specs = [replace(v, start=starts.get(v.name, v.start)) for v in specs]
    check_parameter_values(specs)
    ranges = validity_ranges(provenance)
    if "level_mm" in ranges and "flow_m3h" in ranges:
        # the FMU's initialisation refuses what this refuses: no FMU that cannot start
        try:
            check_operating_storage(plant, list(ranges["level_mm"]), list(ranges["flow_m3h"]))
        except ModelFileError as exc:
            raise ExportError(str(exc)) from None
    columns = {"flow_m3h": _first(specs, "schedule.flow_m3h[1]").vr}
    for name in plant.columns:
        columns[name] = _first(specs, f"schedule.{name}[1]").vr
    orders = (plant.na, plant.nb, plant.nk) if isinstance(plant, ArxPlant) else None
    summary = xml_text(_summary(plant, provenance))
    effects = {
        e["kind"]: {p.name: _first(specs, f"effect.{e['kind']}.{p.name}").vr
                    for p in parameter_specs(e["kind"])}
        for e in plant.effects
    }  # fmt: skip
    return FmuDescription(
        model_identifier=model_name,
        guid=_guid(plant, model_name, provenance, build_id, start_inputs),
        family=plant.kind,
        gauge=plant.gauge,
        n_knots=len(plant.schedule.flow_m3h),
        variables=tuple(specs),
        columns=columns,
        arx_orders=orders,
        step_size_s=plant.sample_period_s if isinstance(plant, ArxPlant) else 1.0,
        summary=summary,
        provenance=dict(provenance),
        effects=effects,
        kernel_first=_kernel_first(plant, specs),
    )


def _check_exportable(plant: Plant, model_name: str) -> None:
    if not isinstance(plant, (FopdtPlant, ArxPlant, PhysicalPlant)):
        raise ExportError(
            f"cannot export {type(plant).__name__}: expected FopdtPlant, ArxPlant or PhysicalPlant"
        )
    if not _IDENTIFIER.fullmatch(model_name):
        raise ExportError(
            f"model_name {model_name!r} must be a C identifier (letters, digits, _; <= 64 chars)"
        )
    if not gauge_name_ok(plant.gauge):
        shown = str(plant.gauge)[:60].encode("unicode_escape").decode("ascii")
        raise ExportError(f"gauge '{shown}' must be 1 to {MAX_GAUGE_CHARS} characters without "
                          "control characters (the output is level_<gauge>_mm)")  # fmt: skip
    if isinstance(plant, ArxPlant) and max(plant.na, plant.nb, plant.nk) > MAX_ARX_ORDER:
        raise ExportError(
            f"arx orders (na, nb, nk) = ({plant.na}, {plant.nb}, {plant.nk}) exceed "
            f"{MAX_ARX_ORDER}, the largest the FMU supports"
        )


def _first(specs: list[VariableSpec], name: str) -> VariableSpec:
    return next(v for v in specs if v.name == name)


def output_name(gauge: str) -> str:
    """``level_<gauge>_mm`` with characters outside [A-Za-z0-9_] replaced by ``_``."""
    return f"level_{re.sub(r'[^A-Za-z0-9_]', '_', gauge)}_mm"


def _variables(plant: Plant) -> list[VariableSpec]:
    knots = plant.schedule.flow_m3h
    rows: list[tuple[str, str, str, str | None, str, str, float | None]] = [
        (
            "opening_mm",
            "input",
            "continuous",
            None,
            "mm",
            "Gate opening, held over each communication step",
            plant.opening_ref_mm,
        ),
        (
            "flow_m3h",
            "input",
            "continuous",
            None,
            "m3/h",
            "Discharge Q, held over each communication step; schedules the parameters",
            0.5 * (knots[0] + knots[-1]),
        ),
        (
            output_name(plant.gauge),
            "output",
            "continuous",
            "calculated",
            "mm",
            f"Level at gauge {plant.gauge}: level_ref_mm(Q) + dynamic deviation",
            None,
        ),
        (
            "opening_ref_mm",
            "parameter",
            "tunable",
            "exact",
            "mm",
            "Reference opening of the operating point; the dynamics see opening - opening_ref",
            plant.opening_ref_mm,
        ),
    ]
    if isinstance(plant, PhysicalPlant):
        rows[2] = (
            output_name(plant.gauge),
            "output",
            "continuous",
            "calculated",
            "mm",
            f"Level at gauge {plant.gauge}: storage and gate law, plus level_ref_mm(Q)",
            None,
        )
        rows[3] = (
            "opening_ref_mm",
            "parameter",
            "fixed",
            "exact",
            "mm",
            "Always 0: the physical family takes the opening as it is",
            0.0,
        )
    if isinstance(plant, ArxPlant):
        rows.append(
            (
                "sample_period_s",
                "parameter",
                "fixed",
                "exact",
                "s",
                "ARX sample period; communication steps must be whole multiples",
                plant.sample_period_s,
            )
        )
    columns = [("flow_m3h", ("m3/h", "Discharge knot of the schedule (strictly increasing)"))]
    columns += [(name, _column_meta(name, plant.kind)) for name in plant.columns]
    for name, (unit, text) in columns:
        values = knots if name == "flow_m3h" else plant.schedule.values[name]
        for k, value in enumerate(values, start=1):
            rows.append(
                (
                    f"schedule.{name}[{k}]",
                    "parameter",
                    "tunable",
                    "exact",
                    unit,
                    f"{text}, knot {k}",
                    float(value),
                )
            )
    kernel = kernel_parameters(plant)
    if kernel is not None:
        prefix, values = kernel
        rows += [
            (f"{prefix}.{name}", "parameter", "tunable", "exact", unit, text, values[name])
            for name, unit, text in physical_kernel.PARAMETERS
        ]
    specs = [VariableSpec(r[0], vr, *r[1:]) for vr, r in enumerate(rows)]
    for effect in plant.effects:
        for p in parameter_specs(effect["kind"]):
            specs.append(VariableSpec(
                f"effect.{effect['kind']}.{p.name}", len(specs), "parameter",
                "fixed" if p.fixed else "tunable", "exact", p.unit,
                f"{effect['kind']}: {p.description}", float(effect[p.name]),
                initial_dependency=p.equilibrium,
            ))  # fmt: skip
    return specs


def _kernel_first(plant: Plant, specs: list[VariableSpec]) -> int | None:
    kernel = kernel_parameters(plant)
    if kernel is None:
        return None
    return _first(specs, f"{kernel[0]}.{physical_kernel.PARAMETERS[0][0]}").vr


def _column_meta(name: str, kind: str) -> tuple[str, str]:
    if kind == "physical":
        return ("mm", "Datum correction added to the level (0 as identified)")
    if name in _FOPDT_COLUMNS:
        return _FOPDT_COLUMNS[name]
    if name == "time_constant_ref_s":
        return ("s", "Envelope ARX: the pool's time constant where a1 was identified")
    if name.startswith("a"):
        return ("mm/mm", f"ARX coefficient {name} of x(k-{name[1:]})")
    return ("mm/mm", f"ARX coefficient {name} of the input, lag nk+{int(name[1:]) - 1}")


def _guid(plant: Plant, model_name: str, provenance: dict[str, Any], build_id: str,
          start_inputs: tuple[float, float] | None = None) -> str:  # fmt: skip
    starts = [] if start_inputs is None else [[float(v) for v in start_inputs]]
    return guid_of([plant_to_dict(plant), model_name, provenance, build_id, *starts])


def guid_of(content: list[Any]) -> str:
    """The GUID of an FMU built from ``content`` (JSON data): a digest, so the same inputs give
    the same GUID and any change gives another."""
    try:
        text = json.dumps(content, sort_keys=True, allow_nan=False, default=str)
    except ValueError as exc:
        raise ExportError(f"provenance must be JSON without NaN ({exc})") from None
    digest = hashlib.sha256(text.encode()).digest()
    return "{" + str(uuid.UUID(bytes=digest[:16], version=5)) + "}"


def _summary(plant: Plant, provenance: dict[str, Any]) -> str:
    lo, hi = plant.schedule.flow_range_m3h
    head = (
        f"gatetwin {plant.kind.upper()} plant of gauge {plant.gauge}, scheduled on Q over "
        f"{len(plant.schedule.flow_m3h)} knot(s), valid for Q in [{lo:g}, {hi:g}] m3/h"
    )
    if isinstance(plant, PhysicalPlant):
        head = (
            f"gatetwin PHYSICAL plant of gauge {plant.gauge} (pool storage drained by the "
            f"gate law, loaded actuator), valid for Q in [{lo:g}, {hi:g}] m3/h"
        )
    facts = [f"{k}={_short(v)}" for k, v in _flatten(provenance) if v is not None]
    return head + ("; " + "; ".join(facts) if facts else "")


def _flatten(data: dict[str, Any], prefix: str = "") -> list[tuple[str, Any]]:
    out: list[tuple[str, Any]] = []
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out += _flatten(value, name + ".")
        elif isinstance(value, (str, int, float, bool)) or value is None:
            out.append((name, value))
        else:
            out.append((name, json.dumps(value, default=str)))
    return out


def _short(value: Any, limit: int = 80) -> str:
    text = f"{value:.6g}" if isinstance(value, float) else str(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


# -- renderings -------------------------------------------------------------------------------


def _c_double(value: float) -> str:
    text = repr(float(value))
    return text if any(c in text for c in ".en") else text + ".0"


def _macro(name: str) -> str:
    return "VR_COL_" + re.sub(r"[^A-Za-z0-9]", "_", name).upper()


def component_config_lines(desc: ComponentInterface, component_header: str) -> list[str]:
    """The head of any component's ``model_config.h`` (component.h): identity, the header
    that defines its ModelData, the glue's limits."""
    return [
        f"/* Generated by gatetwin.fmu.description for {desc.model_identifier}; do not edit. */",
        "#ifndef GATETWIN_MODEL_CONFIG_H",
        "#define GATETWIN_MODEL_CONFIG_H",
        "",
        f"#define GT_MODEL_IDENTIFIER {c_string_literal(desc.model_identifier)}",
        f"#define GT_GUID {c_string_literal(desc.guid)}",
        f"#define GT_COMPONENT_HEADER {c_string_literal(component_header)}",
        f"#define GT_N_REAL {len(desc.variables)}",
        f"#define GT_COMMUNICATION_POINT_RTOL {_c_double(COMMUNICATION_POINT_RTOL)}",
        f"#define GT_MAX_COMMUNICATION_STEP_S {_c_double(MAX_COMMUNICATION_STEP_S)}",
        f"#define GT_MAX_TIME_S {_c_double(MAX_TIME_S)}",
        f"#define GT_PARAMETER_MAX_ABS {_c_double(PARAMETER_MAX_ABS)}",
        "#define GT_LOG_CATEGORIES {" + ", ".join(f'"{c}"' for c in LOG_CATEGORIES) + "}",
    ]


def variable_table_lines(variables: tuple[VariableSpec, ...]) -> list[str]:
    """The tail of any component's ``model_config.h``: every Real variable as
    ``GT_VARIABLES(X)`` (component.c builds the table from it), and the closing guard."""
    kinds = {
        "input": "GT_KIND_INPUT",
        "output": "GT_KIND_OUTPUT",
        "tunable": "GT_KIND_TUNABLE",
        "fixed": "GT_KIND_FIXED",
    }
    for v in variables:  # names become C string literals: nothing that could end one
        if not _C_NAME.fullmatch(v.name):
            raise ExportError(f"variable name {v.name!r} has characters a C FMU cannot carry")
    lines = [
        "",
        "/* every Real variable in value-reference order: name, kind, start */",
        "#define GT_VARIABLES(X) \\",
    ]
    lines += [
        f"    X({c_string_literal(v.name)}, {kinds[v.kind]}, {_c_double(v.start or 0.0)}) \\"
        for v in variables
    ]
    return [*lines, "", "#endif", ""]


def model_config_header(desc: FmuDescription) -> str:
    """``model_config.h`` of the C FMU: identity, sizes, value references, variable table."""
    lines = [
        *component_config_lines(desc, "plant_data.h"),
        f'#define GT_DYNAMICS_HEADER "model_{desc.family}.h"',
        f"#define GT_N_KNOTS {desc.n_knots}",
        f"#define GT_OPENING_MIN_MM {_c_double(OPENING_RANGE_MM[0])}",
        f"#define GT_OPENING_MAX_MM {_c_double(OPENING_RANGE_MM[1])}",
        f"#define GT_FLOW_MIN_M3H {_c_double(FLOW_RANGE_M3H[0])}",
        f"#define GT_FLOW_MAX_M3H {_c_double(FLOW_RANGE_M3H[1])}",
    ]
    if desc.arx_orders is None:
        lines.append(f"#define GT_HISTORY_CAPACITY {DELAY_HISTORY_CAPACITY}")
    else:
        na, nb, nk = desc.arx_orders
        lines += [
            f"#define GT_NA {na}",
            f"#define GT_NB {nb}",
            f"#define GT_NK {nk}",
            f"#define GT_ARX_STEP_RTOL {_c_double(ARX_STEP_RTOL)}",
            f"#define GT_ARX_MAX_SUBSTEPS {_c_double(ARX_MAX_SUBSTEPS)}",
        ]
    lines += [
        "",
        "/* value references (indices into ModelData.real) */",
        f"#define VR_OPENING_MM {desc.vr('opening_mm')}",
        f"#define VR_FLOW_M3H {desc.vr('flow_m3h')}",
        f"#define VR_OPENING_REF_MM {desc.vr('opening_ref_mm')}",
        f"#define VR_OUTPUT {desc.output.vr}",
    ]
    if desc.arx_orders is not None:
        lines.append(f"#define VR_SAMPLE_PERIOD_S {desc.vr('sample_period_s')}")
    lines += _kernel_config_lines(desc)
    lines += _validity_config_lines(desc)
    lines.append("/* schedule column c at knot k (from 0): VR_COL_c + k */")
    lines += [f"#define {_macro(name)} {vr}" for name, vr in desc.columns.items()]
    lines += _effect_config_lines(desc)
    return "\n".join(lines + variable_table_lines(desc.variables))


def _validity_config_lines(desc: FmuDescription) -> list[str]:
    """The validity envelope: GT_VALIDITY_<Q> is 1 when the model states the range of Q."""
    ranges = validity_ranges(desc.provenance)
    lines = ["/* validity envelope of the model file: 1 when a range is stated, then its ends */"]
    for name, unit, stem in VALIDITY_QUANTITIES:
        lines.append(f"#define GT_VALIDITY_{stem} {int(name in ranges)}")
        lo, hi = ranges.get(name, (0.0, 0.0))
        lines += [
            f"#define GT_VALIDITY_{stem}_MIN {_c_double(lo)}",
            f"#define GT_VALIDITY_{stem}_MAX {_c_double(hi)}",
            f'#define GT_VALIDITY_{stem}_UNIT "{unit}"',
        ]
    return lines


def _kernel_config_lines(desc: FmuDescription) -> list[str]:
    """The physical kernel's parameter block (physical family, envelope FOPDT and ARX)."""
    envelope = int(desc.family in ("fopdt", "arx") and desc.kernel_first is not None)
    lines = [f"#define GT_ENVELOPE {envelope}"]
    if desc.kernel_first is None:
        return lines
    first = desc.kernel_first
    bounded = [first + physical_kernel.INDEX[n] for n in LOWER_BOUNDS]
    bounds = LOWER_BOUNDS.values()
    return lines + [
        "/* the physical kernel's parameters from VR_KERNEL_FIRST on, in kernel order */",
        f"#define VR_KERNEL_FIRST {first}",
        "#define GT_KERNEL_BOUNDED " + ", ".join(str(vr) for vr in bounded),
        "#define GT_KERNEL_LOWER_BOUNDS " + ", ".join(repr(float(b)) for b in bounds),
        f'#define GT_KERNEL_STORAGE_RULE "{STORAGE_RULE}"',
        f'#define GT_KERNEL_OPERATING_STORAGE_RULE "{OPERATING_STORAGE_RULE}"',
        f"#define GT_PHYSICAL_MAX_SUBSTEPS {MAX_SUBSTEPS}",
        f"#define GT_PHYSICAL_MAX_SUBSTEP_INDEX {physical_kernel.INDEX['max_substep_s']}",
    ]


def _effect_limits(desc: FmuDescription) -> list[tuple[int, float, float, bool]]:
    """``(vr, minimum, maximum, minimum_exclusive)`` of every effect parameter."""
    out = []
    for kind, vrs in desc.effects.items():
        for p in parameter_specs(kind):
            if not (math.isfinite(p.minimum) and math.isfinite(p.maximum)):
                raise ExportError(f"effect {kind}: {p.name} needs finite limits for the FMU")
            out.append((vrs[p.name], p.minimum, p.maximum, p.minimum_exclusive))
    return out


def _effect_config_lines(desc: FmuDescription) -> list[str]:
    lines = ["", "/* effect blocks (gatetwin.plant.effects): 1 when the model carries one */"]
    for kind in KINDS:
        stem = BLOCK_FIELDS[kind].upper()
        lines.append(f"#define GT_HAS_{stem} {int(kind in desc.effects)}")
        for name, vr in desc.effects.get(kind, {}).items():
            lines.append(f"#define VR_FX_{stem}_{name.upper()} {vr}")
    lines.append("/* effect parameter limits: vr, minimum, maximum, minimum exclusive */")
    lines.append("#define GT_EFFECT_LIMITS(X) \\")
    lines += [f"    X({vr}, {_c_double(lo)}, {_c_double(hi)}, {int(excl)}) \\"
              for vr, lo, hi, excl in _effect_limits(desc)]  # fmt: skip
    lines.append("")
    return lines


def slave_config(desc: FmuDescription) -> dict[str, Any]:
    """The description as plain JSON data for the self-contained pythonfmu slave."""
    return {
        "model_identifier": desc.model_identifier,
        "guid": desc.guid,
        "summary": desc.summary,
        "family": desc.family,
        "n_knots": desc.n_knots,
        "arx_orders": list(desc.arx_orders) if desc.arx_orders else None,
        "columns": desc.columns,
        "opening_range_mm": list(OPENING_RANGE_MM),
        "flow_range_m3h": list(FLOW_RANGE_M3H),
        "history_capacity": DELAY_HISTORY_CAPACITY,
        "arx_step_rtol": ARX_STEP_RTOL,
        "arx_max_substeps": ARX_MAX_SUBSTEPS,
        "fopdt_max_step_s": FOPDT_MAX_STEP_S,
        "validity": _slave_validity(desc),
        "communication_point_rtol": COMMUNICATION_POINT_RTOL,
        "effects": desc.effects,
        "kernel_first": desc.kernel_first,
        "physical_lower_bounds": LOWER_BOUNDS,
        "physical_storage_rule": STORAGE_RULE,
        "physical_operating_storage_rule": OPERATING_STORAGE_RULE,
        "physical_max_substeps": MAX_SUBSTEPS,
        "effect_limits": [list(row) for row in _effect_limits(desc)],
        "variables": [
            {
                "name": v.name,
                "vr": v.vr,
                "causality": v.causality,
                "variability": v.variability,
                "initial": v.initial,
                "kind": v.kind,
                "description": v.description,
                "start": v.start,
            }
            for v in desc.variables
        ],
    }


def _slave_validity(desc: FmuDescription) -> dict[str, list[Any]]:
    """The validity envelope for the python FMU, ``{quantity: [low, high, name, unit]}``: the
    same ranges, names and units the C FMU's warning uses (``model_config.h``)."""
    output = next(v.name for v in desc.variables if v.causality == "output")
    units = {name: unit for name, unit, _ in VALIDITY_QUANTITIES}
    return {q: [lo, hi, output if q == "level_mm" else q, units[q]]
            for q, (lo, hi) in validity_ranges(desc.provenance).items()}  # fmt: skip


@dataclass(frozen=True)
class CoSimulationFlags:
    """The ``CoSimulation`` element's capability flags of one backend."""

    needs_execution_tool: bool
    can_serialize_fmu_state: bool
    can_not_use_memory_management_functions: bool
    source_files: tuple[str, ...] = ()


def model_description_xml(desc: ComponentInterface, flags: CoSimulationFlags, tool: str) -> bytes:
    """``modelDescription.xml`` (FMI 2.0, co-simulation) for either backend, of a plant or of
    a controller.

    Every attribute passes through :func:`~gatetwin.fmu.checks.xml_text` and the result is
    parsed back, so the file is well-formed XML whatever text the model carried.
    """
    root = ET.Element(
        "fmiModelDescription",
        {
            "fmiVersion": "2.0",
            "modelName": desc.model_identifier,
            "guid": desc.guid,
            "description": desc.summary,
            "generationTool": tool,
            "variableNamingConvention": "structured",
            "numberOfEventIndicators": "0",
        },
    )
    cs = ET.SubElement(
        root,
        "CoSimulation",
        {
            "modelIdentifier": desc.model_identifier,
            "needsExecutionTool": xml_bool(flags.needs_execution_tool),
            "canHandleVariableCommunicationStepSize": "true",
            "canInterpolateInputs": "false",
            "maxOutputDerivativeOrder": "0",
            "canRunAsynchronuously": "false",
            "canBeInstantiatedOnlyOncePerProcess": "false",
            "canNotUseMemoryManagementFunctions": xml_bool(
                flags.can_not_use_memory_management_functions
            ),
            "canGetAndSetFMUstate": "true",
            "canSerializeFMUstate": xml_bool(flags.can_serialize_fmu_state),
            "providesDirectionalDerivative": "false",
        },
    )
    if flags.source_files:
        files = ET.SubElement(cs, "SourceFiles")
        for name in flags.source_files:
            ET.SubElement(files, "File", {"name": name})
    shared_elements(root, desc)
    _model_variables(root, desc)
    _model_structure(root, desc)
    return finished_xml(root, f"{desc.model_identifier}: modelDescription.xml")


def shared_elements(root: ET.Element, desc: ComponentInterface) -> None:
    """What both FMI versions write alike: units, log categories, default experiment."""
    _unit_definitions(root)
    categories = ET.SubElement(root, "LogCategories")
    for name, text in LOG_CATEGORIES.items():
        ET.SubElement(categories, "Category", {"name": name, "description": text})
    ET.SubElement(
        root, "DefaultExperiment", {"startTime": "0.0", "stepSize": repr(desc.step_size_s)}
    )


def finished_xml(root: ET.Element, what: str) -> bytes:
    """The document's bytes, every attribute escaped and the result parsed back."""
    for element in root.iter():
        for key, value in element.attrib.items():
            element.set(key, xml_text(value))
    ET.indent(root)
    xml = ET.tostring(root, encoding="UTF-8", xml_declaration=True) + b"\n"
    check_well_formed(xml, what)
    return xml


def xml_bool(value: bool) -> str:
    return "true" if value else "false"


def _unit_definitions(root: ET.Element) -> None:
    units = ET.SubElement(root, "UnitDefinitions")
    for name, (_, exponents, factor) in UNITS.items():
        unit = ET.SubElement(units, "Unit", {"name": name})
        base = {k: str(v) for k, v in exponents.items()}
        if factor != 1.0:
            base["factor"] = repr(factor)
        ET.SubElement(unit, "BaseUnit", base)


def _model_variables(root: ET.Element, desc: ComponentInterface) -> None:
    variables = ET.SubElement(root, "ModelVariables")
    for v in desc.variables:
        attrs = {
            "name": v.name,
            "valueReference": str(v.vr),
            "description": v.description,
            "causality": v.causality,
            "variability": v.variability,
        }
        if v.initial is not None:
            attrs["initial"] = v.initial
        sv = ET.SubElement(variables, "ScalarVariable", attrs)
        real = {"unit": v.unit}
        if v.start is not None:
            real["start"] = repr(float(v.start))
        ET.SubElement(sv, "Real", real)


def initial_dependencies(desc: ComponentInterface) -> list[VariableSpec]:
    """The inputs and parameters the output's initial value depends on: those marked
    ``initial_dependency`` but the dynamics-only columns (time constant, dead time, sample
    period); for a plant, what its equilibrium depends on."""
    dynamic_only = {"time_constant_s", "dead_time_s", "sample_period_s"}
    return [
        v
        for v in desc.variables
        if v.causality in ("input", "parameter")
        and v.initial_dependency
        and not any(v.name.startswith(f"schedule.{c}[") or v.name == c for c in dynamic_only)
    ]


def _model_structure(root: ET.Element, desc: ComponentInterface) -> None:
    """The outputs have no direct feedthrough; initially they depend on
    :func:`initial_dependencies` (a plant's output: the equilibrium of the inputs)."""
    index = {v.name: i for i, v in enumerate(desc.variables, start=1)}
    initial_deps = [index[v.name] for v in initial_dependencies(desc)]
    structure = ET.SubElement(root, "ModelStructure")
    # every output (a plant has one; a controller FMU has its command and diagnostics)
    outs = [index[v.name] for v in desc.variables if v.causality == "output"]
    outputs = ET.SubElement(structure, "Outputs")
    for out in outs:
        ET.SubElement(outputs, "Unknown", {"index": str(out), "dependencies": ""})
    initial = ET.SubElement(structure, "InitialUnknowns")
    for out in outs:
        ET.SubElement(
            initial,
            "Unknown",
            {
                "index": str(out),
                "dependencies": " ".join(map(str, initial_deps)),
            },
        )
