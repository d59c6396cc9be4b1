"""What an FMU build refuses or escapes before it writes anything.

* :func:`check_finite_response` -- a plant whose output is not a finite number at its own
  operating points (a gain or reference opening near the float range, a kernel parameter of
  1e308) is refused: its FMU would only ever output NaN or infinity.
* :func:`xml_text` -- text bound for ``modelDescription.xml`` with every character XML 1.0
  cannot carry (controls, lone surrogates, U+FFFE/U+FFFF) written as a ``\\uXXXX`` escape;
  :func:`check_well_formed` parses the rendered bytes back.
* :func:`c_string_literal` -- text bound for a C string literal in ``model_config.h``,
  refused unless it is made of the few characters such names use.

This module checks and escapes; the renderings are in :mod:`gatetwin.fmu.description`.
"""

from __future__ import annotations

import math
import re
import warnings
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

from gatetwin.errors import ExportError, GatetwinError
from gatetwin.plant.model import OPENING_RANGE_MM, ArxPlant, PhysicalPlant, Plant

__all__ = [
    "MAX_GAUGE_CHARS",
    "c_string_literal",
    "check_finite_response",
    "check_well_formed",
    "gauge_name_ok",
    "xml_text",
]

#: Characters XML 1.0 cannot hold (tab, newline and carriage return it can).
_NOT_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")
#: What a string literal of model_config.h may contain (variable names, GUID, identifier).
_C_LITERAL = re.compile(r"[A-Za-z0-9_.\[\]{}\-]{1,200}")
#: Longest gauge name an FMU takes (its output is ``level_<gauge>_mm``, other characters
#: than [A-Za-z0-9_] written as ``_``; model files hold only those characters).
MAX_GAUGE_CHARS = 32
#: Opening moves (mm) and steps of the short run :func:`check_finite_response` makes.
_PROBE_MOVE_MM = 10.0
_PROBE_STEPS = 5
#: Most discharges probed: the knots and the midpoints between them.
_PROBE_FLOWS = 16


def gauge_name_ok(gauge: object) -> bool:
    """A gauge name an FMU can carry: 1 to 32 characters, none a control character."""
    from gatetwin.modelschema import text_problem

    return isinstance(gauge, str) and 0 < len(gauge) <= MAX_GAUGE_CHARS and not text_problem(gauge)


def xml_text(text: str) -> str:
    """``text`` with the characters XML cannot carry written as ``\\uXXXX``."""
    return _NOT_XML.sub(lambda m: f"\\u{ord(m.group()):04x}", text)


def check_well_formed(xml: bytes, what: str) -> None:
    """Parse ``xml`` back; :class:`ExportError` when it is not well-formed XML."""
    try:
        ET.fromstring(xml)
    except ET.ParseError as exc:
        raise ExportError(f"{what}: generated XML is not well formed ({exc})") from None


def c_string_literal(text: str) -> str:
    """``"text"`` for model_config.h; :class:`ExportError` for anything but a name."""
    if not _C_LITERAL.fullmatch(text):
        shown = text[:60].encode("unicode_escape").decode("ascii")
        raise ExportError(f"'{shown}' cannot be a C string literal of the FMU (allowed: "
                          "letters, digits, _ . [ ] { } -; at most 200)")  # fmt: skip
    return f'"{text}"'


def _probe_points(plant: Plant, provenance: dict[str, Any]) -> list[tuple[float, float]]:
    """(opening mm, discharge m³/h) where the plant is started: the schedule's knots and the
    midpoints between them, at the reference opening (or the ends of a stated opening
    range)."""
    validity = provenance.get("validity") if isinstance(provenance, dict) else None
    stated = validity.get("opening_mm") if isinstance(validity, dict) else None
    if isinstance(stated, (list, tuple)) and len(stated) == 2:
        openings = [float(stated[0]), float(stated[1])]
    elif isinstance(plant, PhysicalPlant):
        # opening ratios e/h of 1/400 and 1/40 of the plant's deepest bracketed depth
        top_mm = 1000.0 * plant.parameters["depth_max_m"]
        openings = [top_mm / 400.0, top_mm / 40.0]
    else:
        openings = [plant.opening_ref_mm]
    lo, hi = OPENING_RANGE_MM
    openings = [min(max(e, lo), hi - _PROBE_MOVE_MM) for e in openings if math.isfinite(e)]
    knots = list(plant.schedule.flow_m3h)
    flows = knots + [0.5 * (a + b) for a, b in zip(knots, knots[1:], strict=False)]
    if len(flows) > _PROBE_FLOWS:  # a long schedule: its ends and evenly spread points
        flows = [flows[round(i * (len(flows) - 1) / (_PROBE_FLOWS - 1))]
                 for i in range(_PROBE_FLOWS)]  # fmt: skip
    return [(e, q) for e in openings for q in sorted(set(flows))]


def _run_probe(plant: Plant, opening_mm: float, flow_m3h: float) -> list[float]:
    from gatetwin.plant.simulate import simulator_for

    sim = simulator_for(plant)
    step_s = plant.sample_period_s if isinstance(plant, ArxPlant) else 1.0
    sim.initialize(opening_mm, flow_m3h)
    out = [sim.level_mm]
    for _ in range(_PROBE_STEPS):
        out.append(sim.do_step(step_s, opening_mm + _PROBE_MOVE_MM, flow_m3h))
    return out


def check_finite_response(plant: Plant, model_name: str, provenance: dict[str, Any]) -> None:
    """Refuse a plant whose output is not finite when started at its knots (and between
    them) and moved by 10 mm for five steps (:class:`ExportError`, one line).

    Inputs the plant itself refuses (:class:`~gatetwin.errors.GatetwinError`, e.g. an ARX
    without equilibrium) are left to the FMU, which refuses them the same way.
    """
    for opening, flow in _probe_points(plant, provenance):
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            try:
                levels = _run_probe(plant, opening, flow)
            except GatetwinError:
                continue
            except (ArithmeticError, ValueError):
                levels = [math.nan]
        if not all(math.isfinite(y) for y in levels):
            raise ExportError(
                f"{model_name}: the plant's output is not a finite number when started at "
                f"opening {opening:g} mm and Q {flow:g} m3/h (a parameter beyond double "
                "precision's range?); not exported"
            )
