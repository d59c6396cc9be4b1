"""Whether a file is an FMU the validation harness can run, and what it needs to know of it.

:func:`inspect_fmu` checks the archive (a zip whose members all stay inside its folder, with
a readable ``modelDescription.xml``, FMI 2.0 or 3.0 co-simulation, a binary for this
platform, Real inputs ``opening_mm`` and ``flow_m3h``, or the variables a map names) and
returns its :class:`FmuInfo`; :func:`static_findings` runs fmpy's static validator and
:func:`output_for_gauge` picks the output to compare. Nothing here runs the FMU
(:mod:`gatetwin.validation.fmu_runner` does); every failure is a
:class:`~gatetwin.errors.ValidationError` with a one-line message.
"""

from __future__ import annotations

import hashlib
import sys
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gatetwin.errors import ValidationError
from gatetwin.records import gauge_of_column
from gatetwin.records.limits import check_archive, open_regular, unsafe_member
from gatetwin.validation.mapping import VariableMap

__all__ = [
    "FMI_VERSIONS",
    "INPUTS",
    "FmuInfo",
    "inspect_fmu",
    "output_for_gauge",
    "static_findings",
    "unsafe_member",
]

#: FMI versions the harness runs (co-simulation).
FMI_VERSIONS = ("2.0", "3.0")
#: The inputs every gatetwin plant FMU has, in the order they are set.
INPUTS = ("opening_mm", "flow_m3h")


@dataclass(frozen=True)
class FmuInfo:
    """What the harness needs to know about an FMU (read from its model description).

    Attributes
    ----------
    path : str
        The ``.fmu`` file.
    model_identifier : str
        The co-simulation ``modelIdentifier`` (names the binary).
    guid : str
        The FMU's GUID.
    generation_tool : str
        ``generationTool`` of the model description ("" if absent).
    description : str
        The model description's ``description`` attribute ("" if absent).
    inputs, outputs : tuple of str
        Names of the input and output variables.
    value_references : dict[str, int]
        Value reference of every variable, by name.
    sha256 : str
        Hash of the ``.fmu`` file, for provenance.
    """

    path: str
    model_identifier: str
    guid: str
    generation_tool: str
    description: str
    inputs: tuple[str, ...]
    outputs: tuple[str, ...]
    value_references: dict[str, int] = field(repr=False)
    sha256: str = ""
    fmi_version: str = "2.0"
    #: FMU value per record value of each mapped column (a foreign FMU's units; empty for
    #: gatetwin's FMUs, whose variables are the record's columns)
    scales: dict[str, float] = field(default_factory=dict, repr=False)
    #: the variable map a foreign FMU was opened with (for the report), else None
    variable_map: dict[str, Any] | None = None

    def scale(self, column: str) -> float:
        """FMU value per record value of ``column`` (1 for gatetwin's own FMUs)."""
        return self.scales.get(column, 1.0)

    @property
    def name(self) -> str:
        """The FMU's file name."""
        return Path(self.path).name

    @property
    def gauges(self) -> tuple[str, ...]:
        """Gauges of the ``level_<G>_mm`` outputs."""
        found = (gauge_of_column(name) for name in self.outputs)
        return tuple(g for g in found if g is not None)

    def to_dict(self) -> dict[str, Any]:
        return {
            "file": self.name,
            "sha256": self.sha256,
            "model_identifier": self.model_identifier,
            "guid": self.guid,
            "fmi_version": self.fmi_version,
            "generation_tool": self.generation_tool,
            "inputs": list(self.inputs),
            "outputs": list(self.outputs),
            **({"variable_map": self.variable_map} if self.variable_map else {}),
        }


def _archive_names(fmu: Path) -> set[str]:
    try:
        what = "an FMI 2.0 co-simulation FMU"
        with open_regular(fmu, sys.maxsize, what, ValidationError) as handle, \
                zipfile.ZipFile(handle) as archive:  # fmt: skip
            names = check_archive(archive, str(fmu), ValidationError)
    except ValidationError:
        raise
    except Exception as exc:  # noqa: BLE001 - zipfile raises several kinds on a bad archive
        raise ValidationError(f"{fmu}: not an FMU (not a readable zip archive: {exc})") from None
    return set(names)


def _model_description(fmu: Path) -> Any:
    from fmpy import read_model_description

    try:
        return read_model_description(str(fmu), validate=False)
    except Exception as exc:  # fmpy and lxml raise many kinds; all mean "unreadable"
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise ValidationError(f"{fmu}: modelDescription.xml cannot be read ({text})") from None


def _check_binary(fmu: Path, names: set[str], identifier: str, fmi_version: str) -> None:
    from fmpy import platform, platform_tuple, sharedLibraryExtension

    if fmi_version != "2.0":
        platform = platform_tuple  # FMI 3.0 names binary folders by platform tuple
    if f"binaries/{platform}/{identifier}{sharedLibraryExtension}" in names:
        return
    found = sorted(
        {n.split("/")[1] for n in names if n.startswith("binaries/") and n.count("/") > 1}
    )
    raise ValidationError(
        f"{fmu}: no binary for this platform (expected binaries/{platform}/{identifier}"
        f"{sharedLibraryExtension}; the FMU has binaries for: {', '.join(found) or 'none'})"
    )


def _check_inputs(fmu: Path, variables: list[Any]) -> None:
    inputs = {v.name: v.type for v in variables if v.causality == "input"}
    for name in INPUTS:
        if inputs.get(name) not in ("Real", "Float64"):  # FMI 2.0, FMI 3.0
            raise ValidationError(
                f"{fmu}: no Real input '{name}'; expected inputs {', '.join(INPUTS)} "
                f"(found: {', '.join(sorted(inputs)) or 'none'})"
            )


def inspect_fmu(path: str | Path, variable_map: VariableMap | None = None) -> FmuInfo:
    """Check that ``path`` is an FMU the harness can run, and describe it.

    Parameters
    ----------
    path : str or Path
        The ``.fmu`` file.
    variable_map : VariableMap, optional
        For an FMU whose variables are not the record's columns: the FMU variable (and its
        unit) behind each column (:mod:`gatetwin.validation.mapping`). The returned info then
        names the mapped variables by their columns.

    Returns
    -------
    FmuInfo

    Raises
    ------
    ValidationError
        Missing file, not a zip archive, a member with an absolute path or a ``..`` part,
        no or unreadable ``modelDescription.xml``, not FMI 2.0 or 3.0 co-simulation, no binary for
        this platform, no Real inputs ``opening_mm`` and ``flow_m3h`` (or, with a map, a mapped
        variable missing or of the wrong causality or type).
    """
    fmu = Path(path)
    names = _archive_names(fmu)
    if "modelDescription.xml" not in names:
        raise ValidationError(f"{fmu}: not an FMU (the archive has no modelDescription.xml)")
    md = _model_description(fmu)
    if md.fmiVersion not in FMI_VERSIONS or md.coSimulation is None:
        raise ValidationError(
            f"{fmu}: FMI {md.fmiVersion} without co-simulation; expected an FMI 2.0 or 3.0 "
            "co-simulation FMU"
        )
    identifier = md.coSimulation.modelIdentifier
    _check_binary(fmu, names, identifier, md.fmiVersion)
    variables = list(md.modelVariables)
    if variable_map is not None:
        variables = _mapped(fmu, variables, variable_map)
    _check_inputs(fmu, variables)
    return FmuInfo(
        path=str(fmu),
        model_identifier=identifier,
        guid=md.guid,
        generation_tool=md.generationTool or "",
        description=md.description or "",
        inputs=tuple(v.name for v in variables if v.causality == "input"),
        outputs=tuple(v.name for v in variables if v.causality == "output"),
        value_references={v.name: v.valueReference for v in variables},
        sha256=hashlib.sha256(fmu.read_bytes()).hexdigest(),
        fmi_version=md.fmiVersion,
        scales={c: variable_map.scale(c) for c in variable_map.variables} if variable_map else {},
        variable_map=variable_map.to_dict() if variable_map else None,
    )


@dataclass(frozen=True)
class _Variable:
    """A model variable as the harness sees it (a mapped one under its record column)."""

    name: str
    causality: str
    type: str
    valueReference: int  # noqa: N815 (fmpy's attribute name)


def _mapped(fmu: Path, variables: list[Any], variable_map: VariableMap) -> list[_Variable]:
    """The FMU's variables with each mapped one renamed to its record column (the FMU's own
    variables of the columns' names, if any, step aside)."""
    by_name = {v.name: v for v in variables}
    taken = {*variable_map.variables, *variable_map.variables.values()}
    out = [_Variable(v.name, v.causality, v.type, v.valueReference) for v in variables
           if v.name not in taken]  # fmt: skip
    for column, name in variable_map.variables.items():
        v = by_name.get(name)
        want = "input" if column in INPUTS else "output"
        if v is None or v.causality != want or v.type not in ("Real", "Float64"):
            found = "none" if v is None else f"a {v.type} {v.causality}"
            raise ValidationError(f"{fmu}: the map's [{column}] names {name!r}, which must be "
                                  f"a Real {want} of the FMU (found: {found})")  # fmt: skip
        out.append(_Variable(column, v.causality, v.type, v.valueReference))
    return out


def static_findings(path: str | Path) -> tuple[str, ...]:
    """Problems fmpy's static validator finds in the FMU (empty when none).

    Runs :func:`fmpy.validation.validate_fmu`: the model description against the XML
    schema, variable names, model structure, start values, causality/variability
    combinations and units. Call :func:`inspect_fmu` first: this expects a zip archive.
    """
    from fmpy.validation import validate_fmu

    return tuple(" ".join(str(p).split()) for p in validate_fmu(str(path)))


def output_for_gauge(info: FmuInfo, gauge: str | None) -> str:
    """The output variable to compare: ``level_<gauge>_mm``, or the FMU's only level output.

    Raises
    ------
    ValidationError
        The FMU has no such output, no level output, or several and ``gauge`` is None.
    """
    levels = info.gauges
    if gauge is not None:
        if gauge not in levels:
            raise ValidationError(
                f"{info.path}: no output level_{gauge}_mm (its level outputs: "
                f"{', '.join(f'level_{g}_mm' for g in levels) or 'none'})"
            )
        return f"level_{gauge}_mm"
    if len(levels) == 1:
        return f"level_{levels[0]}_mm"
    if not levels:
        raise ValidationError(
            f"{info.path}: no level_<G>_mm output (outputs: {', '.join(info.outputs) or 'none'})"
        )
    raise ValidationError(
        f"{info.path}: several level outputs ({', '.join(levels)}); choose one with --gauge"
    )
