"""SSP 1.0 documents: namespaces, validation against the standard's schemas, parameter sets.

The schemas are the SSP 1.0 XSDs fmpy ships (``fmpy/ssp/schema``), read with lxml (an fmpy
dependency). This module writes and reads XML; it builds and runs nothing.
"""

from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path
from typing import Any

from gatetwin.errors import SspError

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
SSV = "http://ssp-standard.org/SSP1/SystemStructureParameterValues"
NS = {"ssd": SSD, "ssc": SSC, "ssv": SSV}
SSD_SCHEMA = "SystemStructureDescription.xsd"
SSV_SCHEMA = "SystemStructureParameterValues.xsd"


def schema_dir() -> Path:
    """fmpy's copy of the SSP 1.0 schemas."""
    import fmpy.ssp

    return Path(fmpy.ssp.__file__).resolve().parent / "schema"


@lru_cache(maxsize=4)
def _schema(name: str) -> Any:
    from lxml import etree

    return etree.XMLSchema(file=str(schema_dir() / name))


def schema_problems(xml: bytes, schema: str) -> list[str]:
    """What ``schema`` (an SSP 1.0 XSD file name) finds wrong with ``xml``; empty if valid."""
    from lxml import etree

    try:
        root = etree.fromstring(xml, parser=etree.XMLParser(resolve_entities=False,
                                                           no_network=True))  # fmt: skip
    except etree.XMLSyntaxError as exc:
        return [f"not well-formed XML: {exc}"]
    checker = _schema(schema)
    if checker.validate(root):
        return []
    return [f"line {e.line}: {e.message}" for e in checker.error_log]


def parameter_set_xml(name: str, values: list[tuple[str, float, str]]) -> bytes:
    """An SSV parameter set: ``(name, value, unit)`` Real parameters."""
    from lxml import etree

    root = etree.Element(f"{{{SSV}}}ParameterSet", nsmap={"ssv": SSV, "ssc": SSC},
                         version="1.0", name=name)  # fmt: skip
    parameters = etree.SubElement(root, f"{{{SSV}}}Parameters")
    for pname, value, unit in values:
        if not math.isfinite(value):
            raise SspError(f"parameter set {name}: {pname} = {value} is not finite")
        p = etree.SubElement(parameters, f"{{{SSV}}}Parameter", name=pname)
        etree.SubElement(p, f"{{{SSV}}}Real", value=repr(float(value)), unit=unit)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def read_parameter_set(xml: bytes, where: str) -> dict[str, float]:
    """The Real parameters of an SSV document, checked against the schema."""
    from lxml import etree

    problems = schema_problems(xml, SSV_SCHEMA)
    if problems:
        raise SspError(f"{where}: not an SSP 1.0 parameter set: {problems[0]}")
    root = etree.fromstring(xml)
    out = {}
    for p in root.iterfind("ssv:Parameters/ssv:Parameter", NS):
        real = p.find("ssv:Real", NS)
        if real is None:
            raise SspError(f"{where}: parameter {p.get('name')} is not Real (only Real is used)")
        value = float(real.get("value"))
        if not math.isfinite(value):
            raise SspError(f"{where}: parameter {p.get('name')} = {value} is not finite")
        out[p.get("name")] = value
    return out


__all__ = [
    "NS",
    "SSC",
    "SSD",
    "SSD_SCHEMA",
    "SSV",
    "SSV_SCHEMA",
    "parameter_set_xml",
    "read_parameter_set",
    "schema_dir",
    "schema_problems",
]
