"""Reading and rewriting EPA SWMM input files (``.inp``) for the SWMM plant.

Only what the plant needs: the sections as lists of lines, the gate orifice and its cross
section, node invert elevations, the flow units, the inflows at given nodes, and a
rewritten copy in which the plant drives the gate and the inflow itself. The user's file
is never modified. Not a general ``.inp`` editor.
"""

from __future__ import annotations

import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from gatetwin.errors import PlantError
from gatetwin.records.limits import open_regular

__all__ = ["LINK_SECTIONS", "METRIC_FLOW_UNITS_M3S", "NODE_SECTIONS", "InpFile", "Orifice"]

#: Flow units whose lengths are metres, and their size in m³/s.
METRIC_FLOW_UNITS_M3S = {"CMS": 1.0, "LPS": 1e-3, "MLD": 1e6 / 1e3 / 86400.0}
#: Sections whose first word names a node.
NODE_SECTIONS = ("JUNCTIONS", "OUTFALLS", "STORAGE", "DIVIDERS")
#: Sections whose first word names a link, and what such a link is.
LINK_SECTIONS = {"CONDUITS": "conduit", "PUMPS": "pump", "ORIFICES": "orifice",
                 "WEIRS": "weir", "OUTLETS": "outlet"}  # fmt: skip
_HEADER = re.compile(r"^\s*\[([A-Za-z_]+)\]\s*$")


@dataclass(frozen=True)
class Orifice:
    """The gate: a rectangular closed side orifice.

    Attributes
    ----------
    name, inlet_node, outlet_node : str
        Link and its end nodes.
    height_m, width_m : float
        Full opening and width of the rectangular opening, m.
    sill_elevation_m : float
        Elevation of the bottom of the opening (the gate's bed), m.
    discharge_coefficient : float
        SWMM's orifice discharge coefficient.
    """

    name: str
    inlet_node: str
    outlet_node: str
    height_m: float
    width_m: float
    sill_elevation_m: float
    discharge_coefficient: float


class InpFile:
    """An ``.inp`` read into sections (upper-case name -> data lines, comments dropped).

    Parameters
    ----------
    path : str or Path
        The input file.

    Raises
    ------
    PlantError
        The file cannot be read or has no ``[OPTIONS]``/``[JUNCTIONS]`` structure.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            with open_regular(self.path, sys.maxsize, "a SWMM input file (.inp)",
                              PlantError) as handle:  # fmt: skip
                self.text = handle.read().decode("utf-8", errors="replace")
        except OSError as exc:
            raise PlantError(
                f"{self.path}: cannot read the SWMM model ({exc.strerror or exc})"
            ) from None
        self.sections: dict[str, list[list[str]]] = {}
        current = None
        for line in self.text.splitlines():
            head = _HEADER.match(line)
            if head:
                current = head.group(1).upper()
                self.sections.setdefault(current, [])
                continue
            words = line.split(";", 1)[0].split()
            if current is not None and words:
                self.sections[current].append(words)
        if not self.sections:
            raise PlantError(f"{self.path}: not a SWMM input file (no [SECTION] headers)")

    def option(self, name: str, default: str = "") -> str:
        """An ``[OPTIONS]`` value (upper case), or ``default``."""
        for words in self.sections.get("OPTIONS", []):
            if words[0].upper() == name and len(words) > 1:
                return words[1].upper()
        return default

    def flow_to_m3s(self) -> float:
        """Size of the model's flow unit in m³/s; refuses US units."""
        units = self.option("FLOW_UNITS", "CFS")
        if units not in METRIC_FLOW_UNITS_M3S:
            raise PlantError(
                f"{self.path.name}: FLOW_UNITS {units} are US customary units; the SWMM plant "
                f"reads metric models only ({', '.join(METRIC_FLOW_UNITS_M3S)})"
            )
        return METRIC_FLOW_UNITS_M3S[units]

    def node_names(self) -> set[str]:
        return {w[0] for s in NODE_SECTIONS for w in self.sections.get(s, [])}

    def link_kind(self, name: str) -> str | None:
        for section, kind in LINK_SECTIONS.items():
            if any(w[0] == name for w in self.sections.get(section, [])):
                return kind
        return None

    def invert_m(self, node: str) -> float:
        """Invert elevation of ``node``, m (second field of its node line)."""
        for section in NODE_SECTIONS:
            for words in self.sections.get(section, []):
                if words[0] == node:
                    return _number(self.path, section, words, 1)
        raise PlantError(f"{self.path.name}: no node {node!r}")

    def check_nodes(self, nodes: list[str], what: str) -> None:
        known = self.node_names()
        for node in nodes:
            if node not in known:
                raise PlantError(
                    f"{self.path.name}: {what} {node!r} is not a node of the model "
                    f"(it has {len(known)} nodes, e.g. {', '.join(sorted(known)[:5])})"
                )

    def orifice(self, name: str) -> Orifice:
        """The gate link ``name``: must be a SIDE orifice of shape RECT_CLOSED."""
        kind = self.link_kind(name)
        if kind is None:
            raise PlantError(f"{self.path.name}: no link {name!r} (the gate must be an orifice)")
        if kind != "orifice":
            raise PlantError(
                f"{self.path.name}: gate {name!r} is a {kind}; the gate must be an [ORIFICES] "
                "link (SIDE, RECT_CLOSED)"
            )
        words = next(w for w in self.sections["ORIFICES"] if w[0] == name)
        if len(words) < 6 or words[3].upper() != "SIDE":
            raise PlantError(f"{self.path.name}: orifice {name!r} must be of type SIDE")
        xs = [w for w in self.sections.get("XSECTIONS", []) if w[0] == name]
        if not xs or len(xs[0]) < 4 or xs[0][1].upper() != "RECT_CLOSED":
            raise PlantError(
                f"{self.path.name}: orifice {name!r} needs a RECT_CLOSED cross section"
            )
        height = _number(self.path, "XSECTIONS", xs[0], 2)
        width = _number(self.path, "XSECTIONS", xs[0], 3)
        offset = _number(self.path, "ORIFICES", words, 4)
        coeff = _number(self.path, "ORIFICES", words, 5)
        if not (height > 0 and width > 0 and coeff > 0):
            raise PlantError(f"{self.path.name}: orifice {name!r}: need height, width, Cd > 0")
        inlet, outlet = words[1], words[2]
        by_elevation = self.option("LINK_OFFSETS", "DEPTH") == "ELEVATION"
        sill = offset if by_elevation else self.invert_m(inlet) + offset
        return Orifice(name, inlet, outlet, height, width, sill, coeff)

    def baseline_inflow(self, node: str) -> float:
        """Constant FLOW baseline of ``node`` in ``[INFLOWS]`` and ``[DWF]``, model units."""
        total = 0.0
        for words in self.sections.get("INFLOWS", []):
            if words[0] == node and words[1].upper() == "FLOW" and len(words) >= 7:
                total += _number(self.path, "INFLOWS", words, 6) * _number(
                    self.path, "INFLOWS", words, 5
                )
        for words in self.sections.get("DWF", []):
            if words[0] == node and words[1].upper() == "FLOW" and len(words) >= 3:
                total += _number(self.path, "DWF", words, 2)
        return total

    def gate_rules(self, gate: str) -> list[str]:
        """Names of the ``[CONTROLS]`` rules that act on the orifice ``gate``."""
        return [name for name, body in _rules(self.text) if _acts_on(body, gate)]

    def driven_copy(self, gate: str, inflow_nodes: list[str], duration_s: float) -> str:
        """The text of a copy in which the plant drives ``gate`` and the inflow at
        ``inflow_nodes``: their ``[INFLOWS]``/``[DWF]`` FLOW lines and the rules acting on
        the gate are dropped, the end date moved ``duration_s`` after the start, and the
        report step set to the duration (nothing is reported in between)."""
        out, section, skipping = [], "", False
        for line in self.text.splitlines():
            head = _HEADER.match(line)
            if head:
                section, skipping = head.group(1).upper(), False
                out.append(line)
                continue
            words = line.split(";", 1)[0].split()
            if section in ("INFLOWS", "DWF") and len(words) > 1 and words[0] in inflow_nodes:
                if words[1].upper() == "FLOW":
                    continue
            if section == "CONTROLS":
                if words and words[0].upper() == "RULE":
                    skipping = _acts_on(_rule_body(self.text, words[1]), gate)
                if skipping:
                    continue
            if section == "OPTIONS" and words and words[0].upper() in _TIME_OPTIONS:
                continue
            out.append(line)
        return _with_times("\n".join(out) + "\n", self, duration_s)


_TIME_OPTIONS = ("END_DATE", "END_TIME", "REPORT_STEP", "REPORT_START_DATE", "REPORT_START_TIME")


def _with_times(text: str, inp: InpFile, duration_s: float) -> str:
    from datetime import datetime, timedelta

    date = inp.option("START_DATE", "01/01/2000")
    time = inp.option("START_TIME", "00:00:00")
    try:
        start = datetime.strptime(f"{date} {time}", "%m/%d/%Y %H:%M:%S")
    except ValueError:
        try:
            start = datetime.strptime(f"{date} {time}", "%m/%d/%Y %H:%M")
        except ValueError:
            msg = f"{inp.path.name}: START_DATE/START_TIME {date} {time} unreadable"
            raise PlantError(msg) from None
    end = start + timedelta(seconds=math.ceil(duration_s))
    step = min(int(math.ceil(duration_s)), 86399)
    lines = [
        f"END_DATE             {end:%m/%d/%Y}",
        f"END_TIME             {end:%H:%M:%S}",
        f"REPORT_START_DATE    {start:%m/%d/%Y}",
        f"REPORT_START_TIME    {start:%H:%M:%S}",
        f"REPORT_STEP          {step // 3600:02d}:{step % 3600 // 60:02d}:{step % 60:02d}",
    ]
    head = re.search(r"^\s*\[OPTIONS\]\s*$", text, flags=re.MULTILINE | re.IGNORECASE)
    if head is None:
        return "[OPTIONS]\n" + "\n".join(lines) + "\n\n" + text
    return text[: head.end()] + "\n" + "\n".join(lines) + text[head.end() :]


def _rules(text: str) -> list[tuple[str, str]]:
    """(name, body) of every rule in ``[CONTROLS]``."""
    body = re.search(r"^\s*\[CONTROLS\]\s*$(.*?)(?=^\s*\[|\Z)", text,
                     flags=re.MULTILINE | re.DOTALL | re.IGNORECASE)  # fmt: skip
    if body is None:
        return []
    parts = re.split(r"^\s*RULE\s+", body.group(1), flags=re.MULTILINE | re.IGNORECASE)
    return [(p.split(None, 1)[0], p) for p in parts[1:] if p.strip()]


def _rule_body(text: str, name: str) -> str:
    return next((body for rule, body in _rules(text) if rule == name), "")


def _acts_on(body: str, gate: str) -> bool:
    """Whether a rule's THEN/ELSE actions set the orifice ``gate``."""
    actions = re.split(r"\bTHEN\b", body, maxsplit=1, flags=re.IGNORECASE)
    if len(actions) < 2:
        return False
    pattern = rf"\bORIFICE\s+{re.escape(gate)}\s+SETTING\b"
    return re.search(pattern, actions[1], flags=re.IGNORECASE) is not None


def _number(path: Path, section: str, words: list[str], index: int) -> float:
    try:
        value = float(words[index])
    except (IndexError, ValueError):
        raise PlantError(
            f"{path.name}: [{section}] {words[0]}: field {index + 1} must be a number"
        ) from None
    if not math.isfinite(value):
        raise PlantError(f"{path.name}: [{section}] {words[0]}: field {index + 1} is not finite")
    return value
