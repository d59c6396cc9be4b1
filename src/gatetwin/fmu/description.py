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

The renderings live in modules of their own: ``model_config.h`` in
:mod:`gatetwin.fmu.config_header`, ``modelDescription.xml`` in :mod:`gatetwin.fmu.description2`
(FMI 2.0) and :mod:`gatetwin.fmu.description3` (FMI 3.0); the variables' and units'
vocabulary every component shares in :mod:`gatetwin.fmu.interface`. Their public names are
importable from here too. This module builds nothing; see :mod:`gatetwin.fmu.c_build` and
:mod:`gatetwin.fmu.python_build`.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
import uuid
from dataclasses import dataclass, field, replace
from typing import Any

from gatetwin.errors import ExportError, ModelFileError
from gatetwin.fmu.checks import MAX_GAUGE_CHARS, gauge_name_ok, xml_text
from gatetwin.fmu.config_header import (
    _effect_limits,
    component_config_lines,
    model_config_header,
    variable_table_lines,
)
from gatetwin.fmu.description2 import (
    CoSimulationFlags,
    finished_xml,
    initial_dependencies,
    model_description_xml,
    shared_elements,
    xml_bool,
)
from gatetwin.fmu.interface import (
    COMMUNICATION_POINT_RTOL,
    LOG_CATEGORIES,
    UNITS,
    ComponentInterface,
    VariableSpec,
)
from gatetwin.fmu.limits import VALIDITY_QUANTITIES, check_parameter_values, validity_ranges
from gatetwin.plant import physical_kernel
from gatetwin.plant.effects import parameter_specs
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
_FOPDT_COLUMNS = {
    "gain_mm_per_mm": ("mm/mm", "Static gain K of level on opening"),
    "time_constant_s": ("s", "Time constant T (> 0)"),
    "dead_time_s": ("s", "Dead time L (>= 0; not above the largest at initialisation)"),
    "level_ref_mm": ("mm", "Rating level at opening_ref_mm"),
}
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")


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
