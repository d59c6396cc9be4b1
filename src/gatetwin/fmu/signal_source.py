"""A scenario as an FMI 2.0 co-simulation FMU (C): tabulated signals as outputs.

The closed loop's SSP (:mod:`gatetwin.ssp.write`) carries its scenario (the set-point and
the discharge over time) as this component, connected to the controller and the plant like
any other, so that any SSP engine runs the loop the package describes with nothing outside
the standard.

The FMU is built from the plant FMU's unchanged glue (``fmi2_glue.c``, ``component.h``,
``component.c``) around ``signal_data.h`` and ``signal_source.c``, which calls
``gt_signal_value``, generated from :func:`gatetwin.mpc.signal_law.signal_value` by
:mod:`gatetwin.plant.ast_render`.

Variables (value references in this order), for each signal ``X`` of ``n`` knots:

* output ``X`` (discrete if held, continuous if linear);
* fixed parameters ``X_table.linear`` (0: each value held from its knot on; 1: linear
  between knots), ``X_table.time_s[1]`` … ``X_table.time_s[n]`` (increasing strictly),
  ``X_table.value[1]`` … ``X_table.value[n]``.

The start values are the tables given; a parameter set may replace them (same number of
knots) before initialisation ends.
"""

from __future__ import annotations

import hashlib
import math
import os
import re
import shutil
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gatetwin.errors import ExportError
from gatetwin.fmu.c_build import (
    CFLAGS,
    FMI_APIS,
    build_description_xml,
    c_double,
    fmu_target,
    package_host_fmu,
    templates_dir,
    write_atomically,
)
from gatetwin.fmu.description import (
    UNITS,
    VariableSpec,
    component_config_lines,
    guid_of,
    variable_table_lines,
)
from gatetwin.fmu.limits import MAX_COMMUNICATION_STEP_S, check_parameter_values

#: The FMI API the scenario FMU carries.
FMI_API = FMI_APIS["2.0"]
#: The component's C files (``signal_law.*`` generated) and headers.
COMPONENT_SOURCES = ("component.c", "signal_source.c", "signal_law.c")
COMPONENT_HEADERS = ("component.h", "signal_data.h", "signal_law.h")
GENERATED = ("signal_law.c", "signal_law.h")
SOURCES = (*FMI_API.glue_sources, *COMPONENT_SOURCES)
HEADERS = (*FMI_API.glue_headers, *COMPONENT_HEADERS)
#: Prefix of the generated C function (as the PI's).
PREFIX = "gt_"
#: Knots per signal at most: each is two variables in ``modelDescription.xml`` (about 300
#: bytes each), so a signal at the limit adds 6 MB to it; a longer record belongs in a file
#: the master reads, not in an FMU's interface.
MAX_KNOTS = 10_000
_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,63}")


@dataclass(frozen=True)
class TableSignal:
    """One signal of a scenario: ``values[k]`` at ``times_s[k]``, held or linear between."""

    name: str
    unit: str
    times_s: tuple[float, ...]
    values: tuple[float, ...]
    linear: bool = False
    description: str = ""

    def check(self) -> None:
        """:class:`ExportError` unless the signal can be an FMU output (see the module)."""
        if not _IDENTIFIER.fullmatch(self.name):
            raise ExportError(f"signal name {self.name!r} must be a C identifier")
        if self.unit not in UNITS:
            raise ExportError(f"signal {self.name}: unit {self.unit!r} is not one of "
                              f"{', '.join(UNITS)}")  # fmt: skip
        n = len(self.times_s)
        if not 1 <= n <= MAX_KNOTS or len(self.values) != n:
            raise ExportError(f"signal {self.name}: {n} times and {len(self.values)} values; "
                              f"need as many of each, 1 to {MAX_KNOTS}")  # fmt: skip
        for k, (t, v) in enumerate(zip(self.times_s, self.values, strict=True), start=1):
            if not (math.isfinite(t) and math.isfinite(v)):
                raise ExportError(f"signal {self.name}: knot {k} ({t} s, {v} {self.unit}) is "
                                  "not finite")  # fmt: skip
            if k > 1 and not t > self.times_s[k - 2]:
                raise ExportError(f"signal {self.name}: time {k} ({t} s) must lie after time "
                                  f"{k - 1} ({self.times_s[k - 2]} s)")  # fmt: skip


@dataclass(frozen=True)
class SignalSourceDescription:
    """The interface of a scenario FMU (see the module for its variables)."""

    model_identifier: str
    guid: str
    summary: str
    step_size_s: float
    variables: tuple[VariableSpec, ...]
    #: per signal: (output vr, linear vr, vr of its first time, vr of its first value, knots)
    layout: tuple[tuple[int, int, int, int, int], ...]
    provenance: dict[str, Any] = field(default_factory=dict)

    @property
    def output(self) -> VariableSpec:
        return next(v for v in self.variables if v.causality == "output")


def _variables(signals: Sequence[TableSignal]) -> tuple[list[VariableSpec], list[tuple]]:
    rows: list[tuple[str, str, str, str | None, str, str, float | None]] = []
    layout = []
    for s in signals:
        n = len(s.times_s)
        out = len(rows)
        layout.append((out, out + 1, out + 2, out + 2 + n, n))
        how = "linear between its knots" if s.linear else "held from each knot on"
        rows.append((s.name, "output", "continuous" if s.linear else "discrete", "calculated",
                     s.unit, s.description or f"The signal {s.name}, {how}", None))  # fmt: skip
        table = f"{s.name}_table"
        rows.append((f"{table}.linear", "parameter", "fixed", "exact", "1",
                     "0: each value held from its knot on; 1: linear between knots",
                     1.0 if s.linear else 0.0))  # fmt: skip
        rows += [(f"{table}.time_s[{k}]", "parameter", "fixed", "exact", "s",
                  f"Time of knot {k} (increasing strictly)", t)
                 for k, t in enumerate(s.times_s, start=1)]  # fmt: skip
        rows += [(f"{table}.value[{k}]", "parameter", "fixed", "exact", s.unit,
                  f"Value at knot {k}", v) for k, v in enumerate(s.values, start=1)]  # fmt: skip
    variables = [VariableSpec(r[0], vr, *r[1:]) for vr, r in enumerate(rows)]
    return variables, layout


def describe_signal_source(
    signals: Sequence[TableSignal], model_identifier: str, step_size_s: float,
    provenance: dict[str, Any] | None = None,
) -> SignalSourceDescription:  # fmt: skip
    """The scenario FMU's description; :class:`ExportError` for a signal it cannot carry, two
    signals of one name, a name that is not a C identifier or a step that is not > 0."""
    if not _IDENTIFIER.fullmatch(model_identifier):
        raise ExportError(f"scenario name {model_identifier!r} must be a C identifier")
    if not signals:
        raise ExportError("a scenario needs one or more signals")
    names = [s.name for s in signals]
    twice = [n for n in names if names.count(n) > 1]
    if twice:
        raise ExportError(f"a scenario names signal {twice[0]} twice")
    for s in signals:
        s.check()
    if not 0 < step_size_s <= MAX_COMMUNICATION_STEP_S:
        raise ExportError(f"scenario step {step_size_s} s must be > 0 and at most "
                          f"{MAX_COMMUNICATION_STEP_S:g} s")  # fmt: skip
    variables, layout = _variables(signals)
    check_parameter_values(variables)  # the FMU checks the same at initialisation
    facts = {"signals": [s.name for s in signals], **(provenance or {})}
    summary = ("gatetwin scenario: " + ", ".join(
        f"{s.name} ({len(s.times_s)} knot(s), {'linear' if s.linear else 'held'})"
        for s in signals))  # fmt: skip
    guid = guid_of([[v.name for v in variables], [v.start for v in variables],
                    model_identifier, facts, f"c:{_code_digest()}"])  # fmt: skip
    return SignalSourceDescription(model_identifier, guid, summary, float(step_size_s),
                                   tuple(variables), tuple(layout), facts)  # fmt: skip


def config_header(desc: SignalSourceDescription) -> str:
    """``model_config.h``: the glue's head, the signals' layout and the variable table."""
    from gatetwin.mpc.signal_law import TIME_TOL_S

    rows = " ".join(f"X({o}u, {lin}u, {t}u, {v}u, {n})" for o, lin, t, v, n in desc.layout)
    lines = [
        *component_config_lines(desc, "signal_data.h"),
        f"#define GT_SIGNAL_TIME_TOL_S {c_double(TIME_TOL_S)}",
        f"#define GT_N_SIGNALS {len(desc.layout)}",
        "/* X(output vr, linear vr, vr of the first time, vr of the first value, knots) */",
        f"#define GT_SIGNALS(X) {rows}",
    ]
    return "\n".join(lines + variable_table_lines(desc.variables))


def generated_signal_law() -> dict[str, str]:
    """File name -> text of the C rendering of :mod:`gatetwin.mpc.signal_law`."""
    from gatetwin.mpc import signal_law
    from gatetwin.plant.ast_render import c_module

    source, header = c_module(signal_law, signal_law.RENDERED_C, PREFIX)
    return {"signal_law.c": source, "signal_law.h": header}


def _code_digest() -> str:
    """sha256 (first 16 hex digits) of the code the scenario FMU is built from."""
    templates = templates_dir()
    law = Path(__file__).resolve().parents[1] / "mpc" / "signal_law.py"
    digest = hashlib.sha256()
    names = sorted(set(SOURCES + HEADERS) - set(GENERATED))
    for path in [*(templates / n for n in names), law]:
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:16]


def build_signal_source(desc: SignalSourceDescription, work: Path, out: Path) -> None:
    """Lay out the scenario FMU in ``work/fmu`` (sources, the host's binary, resources,
    modelDescription.xml) and zip it into ``out``."""
    fmu_dir = work / "fmu"
    sources = fmu_dir / "sources"
    sources.mkdir(parents=True)
    templates = templates_dir()
    generated = generated_signal_law()
    for name in (*SOURCES, *HEADERS, FMI_API.license):
        if name not in generated:
            shutil.copyfile(templates / name, sources / name)
    for name, text in generated.items():
        (sources / name).write_text(text, encoding="utf-8")
    (sources / "model_config.h").write_text(config_header(desc), encoding="utf-8")
    line = " ".join(["cc", *CFLAGS, "-o", f"{desc.model_identifier}.so", *SOURCES, "-lm"])
    (sources / "BUILD.txt").write_text(
        "Build the FMU binary from this folder (any C99 compiler with the same flags):\n\n"
        f"    {line}\n\nmodel_config.h is generated by gatetwin (gatetwin.fmu.signal_source), "
        "signal_law.c and signal_law.h\nfrom gatetwin.mpc.signal_law; the other files are "
        "gatetwin's fixed FMU templates.\n",
        encoding="utf-8",
    )
    (sources / "buildDescription.xml").write_bytes(build_description_xml(desc, SOURCES))
    package_host_fmu(desc, fmu_dir, SOURCES, out, desc.provenance)


def parameter_values(desc: SignalSourceDescription) -> list[tuple[str, float, str]]:
    """Every parameter of the scenario FMU as ``(name, start value, unit)``: what a parameter
    set holding its tables carries."""
    return [(v.name, float(v.start), v.unit) for v in desc.variables
            if v.causality == "parameter" and v.start is not None]  # fmt: skip


def export_signal_source(
    signals: Sequence[TableSignal], out_path: str | os.PathLike[str], *,
    step_size_s: float, model_identifier: str = "scenario",
    provenance: dict[str, Any] | None = None,
) -> Path:  # fmt: skip
    """Build the scenario FMU of ``signals`` at ``out_path`` (written atomically).

    Raises
    ------
    ExportError
        A signal the FMU cannot carry (:func:`describe_signal_source`), no C compiler, a
        failed build.
    OutputError
        The FMU cannot be written where asked.
    """
    target = fmu_target(out_path)
    desc = describe_signal_source(signals, model_identifier, step_size_s, provenance)

    def build(work: Path, name: str) -> Path:
        build_signal_source(desc, work, work / name)
        return work / name

    return write_atomically(target, build)


__all__ = ["MAX_KNOTS", "SignalSourceDescription", "TableSignal", "describe_signal_source",
           "build_signal_source", "config_header", "export_signal_source",
           "generated_signal_law", "parameter_values"]  # fmt: skip
