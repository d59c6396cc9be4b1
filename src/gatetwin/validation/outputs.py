"""Render validation results: JSON document, JUnit XML, PNG plots, and write them.

Rendering is separate from writing: :func:`write_outputs` renders every file in memory
first and only then writes each one atomically (temporary file renamed into place), so a
failure while rendering leaves no output file. This module computes no metrics.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import numpy as np

from gatetwin._io import write_bytes_atomic, write_json_atomic, write_text_atomic
from gatetwin.errors import ValidationError
from gatetwin.validation.harness import VALIDITY_CHECK, FmuValidation, RecordValidation
from gatetwin.validation.thresholds import FAILED, NOT_APPLICABLE
from gatetwin.version import __version__

__all__ = [
    "JUNIT_PREFIX",
    "OutputPaths",
    "junit_xml",
    "outside_message",
    "plot_name",
    "plot_record",
    "validation_document",
    "write_outputs",
]

#: JUnit ``classname`` prefix of every test case.
JUNIT_PREFIX = "gatetwin.validate"


def validation_document(result: FmuValidation) -> dict[str, Any]:
    """The JSON document ``gatetwin validate --json`` writes."""
    return {"tool": "gatetwin validate", "gatetwin_version": __version__, **result.to_dict()}


# --------------------------------------------------------------------------- JUnit


def _testcase(suite: ET.Element, classname: str, name: str) -> ET.Element:
    return ET.SubElement(suite, "testcase", classname=classname, name=name)


def _static_case(suite: ET.Element, result: FmuValidation) -> None:
    case = _testcase(
        suite, f"{JUNIT_PREFIX}.{Path(result.fmu.name).stem}", "fmpy static validation"
    )
    if result.static_findings:
        failure = ET.SubElement(
            case,
            "failure",
            message=f"{len(result.static_findings)} finding(s): {result.static_findings[0]}",
            type="StaticValidation",
        )
        failure.text = "\n".join(result.static_findings)


def _metrics_text(rec: RecordValidation) -> str:
    lines = [f"{k} = {v}" for k, v in rec.metrics.to_dict().items()]
    floor = rec.noise_floor_dict()
    lines.append(f"noise floor: sigma_mm = {floor['sigma_mm']}, fit_percent = "
                 f"{floor['fit_percent']} ({floor['method']})")  # fmt: skip
    lines.append(f"inside_validity = {_validity_value(rec)}" + (
        f" ({outside_message(rec)})" if rec.inside_validity is False else ""))  # fmt: skip
    for step in rec.steps:
        diff = step.to_dict()["difference"]
        lines.append(f"step {step.step_index}: FMU - measured {diff}" + (
            f" ({step.note})" if step.note else ""))  # fmt: skip
    return "\n".join(lines)


def _validity_value(rec: RecordValidation) -> str:
    """``true``, ``false`` or ``unknown``."""
    inside = rec.inside_validity
    return "unknown" if inside is None else str(inside).lower()


def outside_message(rec: RecordValidation) -> str:
    """What lies outside the envelope, e.g. ``opening 12.0 mm below 15.0 mm`` ("" if none)."""
    return ", ".join(rec.validity.problems()) if rec.validity is not None else ""


def _validity_case(suite: ET.Element, classname: str, rec: RecordValidation) -> None:
    """The envelope as a test case (only when it is enforced)."""
    case = _testcase(suite, classname, VALIDITY_CHECK)
    if rec.inside_validity is False:
        message = f"{rec.record} lies outside the FMU's validity: {outside_message(rec)}"
        ET.SubElement(case, "failure", message=message, type="OutsideValidity")
    elif rec.inside_validity is None:
        unknown = ", ".join(rec.validity.unknown) if rec.validity is not None else "all"
        ET.SubElement(case, "skipped", message=f"validity unknown (no range for: {unknown})")


def _record_cases(suite: ET.Element, fmu_stem: str, rec: RecordValidation) -> None:
    classname = f"{JUNIT_PREFIX}.{fmu_stem}.{Path(rec.record).stem}"
    case = _testcase(suite, classname, f"free run vs level_{rec.gauge}_mm")
    if rec.failure_cause:
        ET.SubElement(case, "failure", message=rec.failure_cause, type="FmuRunFailure")
    ET.SubElement(case, "system-out").text = _metrics_text(rec)
    for check in rec.checks:
        case = _testcase(suite, classname, check.threshold.text)
        if check.status == FAILED:
            ET.SubElement(case, "failure", message=check.message, type="ThresholdFailure")
        elif check.status == NOT_APPLICABLE:
            ET.SubElement(case, "skipped", message=check.message)
    if rec.fail_outside_validity:
        _validity_case(suite, classname, rec)


def junit_xml(results: Sequence[FmuValidation]) -> str:
    """JUnit XML: one ``testsuite`` per FMU, one ``testcase`` per record × check.

    Per FMU: a case for fmpy's static validation (failed when it has findings); per record
    a case for the free run (a ``failure`` of type ``FmuRunFailure`` whose message is the
    cause when the FMU crashed, exited, gave no result in time or output NaN or infinity;
    the metrics, noise floor and validity in ``system-out``), one per threshold
    (``failure`` when missed, ``skipped`` when not applicable to the record) and, when the
    envelope is enforced, one ``inside validity`` (``failure`` outside it, ``skipped`` when
    unknown). The suite's properties carry each record's ``inside_validity`` (``true``,
    ``false``, ``unknown``).
    """
    root = ET.Element("testsuites", name="gatetwin validate")
    totals = {"tests": 0, "failures": 0, "skipped": 0}
    for result in results:
        stem = Path(result.fmu.name).stem
        suite = ET.SubElement(root, "testsuite", name=f"{JUNIT_PREFIX}.{stem}")
        props = ET.SubElement(suite, "properties")
        for key, value in (("fmu", result.fmu.name), ("guid", result.fmu.guid)):
            ET.SubElement(props, "property", name=key, value=value)
        for rec in result.records:
            ET.SubElement(props, "property", name=f"{rec.record}: inside_validity",
                          value=_validity_value(rec))  # fmt: skip
        _static_case(suite, result)
        for rec in result.records:
            _record_cases(suite, stem, rec)
        cases = suite.findall("testcase")
        counts = {
            "tests": len(cases),
            "failures": sum(c.find("failure") is not None for c in cases),
            "skipped": sum(c.find("skipped") is not None for c in cases),
        }
        suite.attrib.update({k: str(v) for k, v in counts.items()}, errors="0")
        for key, value in counts.items():
            totals[key] += value
    root.attrib.update({k: str(v) for k, v in totals.items()}, errors="0")
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"


# --------------------------------------------------------------------------- plots


def plot_record(result: FmuValidation, rec: RecordValidation) -> bytes:
    """PNG of one record: measured vs FMU level, the residual, and the opening input.

    Uses matplotlib's Agg canvas directly (no pyplot state, no display needed).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    tr = rec.trace
    fig = Figure(figsize=(9.0, 7.0), layout="constrained")
    FigureCanvasAgg(fig)
    ax_level, ax_res, ax_open = fig.subplots(3, 1, sharex=True, height_ratios=(3, 1.5, 1))
    ax_level.plot(tr.time_s, tr.measured_mm, ".", ms=2.5, color="0.45", label="measured")
    ax_level.plot(tr.time_s, tr.simulated_mm, "-", lw=1.6, color="C0", label="FMU (free run)")
    ax_level.set_ylabel(f"level {rec.gauge} (mm)")
    ax_level.legend(loc="best")
    m = rec.metrics
    ax_level.set_title(
        f"{result.fmu.name} on {rec.record}: fit {m.fit_percent:.1f} % (noise floor "
        f"{rec.noise_floor_fit_percent:.1f} %), R² {m.r2:.3f}, RMSE {m.rmse_mm:.2f} mm"
        + (" — outside validity" if rec.inside_validity is False else "")
        + (f"\nFMU run failed: {rec.failure_cause}" if rec.failure_cause else ""),
        fontsize=10,
    )
    ax_res.plot(tr.time_s, tr.residual_mm, "-", lw=0.8, color="C3")
    ax_res.axhline(0.0, color="0.3", lw=0.6)
    ax_res.set_ylabel("measured − FMU (mm)")
    ax_open.plot(tr.time_s, tr.opening_mm, "-", color="C2", lw=1.2, label="opening given")
    moving = ~np.asarray(tr.hold, dtype=bool)
    ax_open.plot(tr.time_s[moving], tr.opening_mm[moving], "o", ms=3, color="C1",
                 label="reconstructed (gate moving)")  # fmt: skip
    ax_open.set_ylabel("opening (mm)")
    ax_open.set_xlabel("time (s)")
    ax_open.legend(loc="best", fontsize=8)
    for ax in (ax_level, ax_res, ax_open):
        ax.grid(True, lw=0.4, alpha=0.6)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()


def plot_name(result: FmuValidation, rec: RecordValidation) -> str:
    """File name of a record's plot: ``<fmu stem>__<record stem>_<gauge>.png``."""
    return f"{Path(result.fmu.name).stem}__{Path(rec.record).stem}_{rec.gauge}.png"


# --------------------------------------------------------------------------- writing


@dataclass(frozen=True)
class OutputPaths:
    """Where ``gatetwin validate`` writes; ``None`` means "do not write this one"."""

    json_path: Path | None = None
    junit_path: Path | None = None
    plots_dir: Path | None = None


def _rendered_plots(result: FmuValidation, folder: Path) -> dict[Path, bytes]:
    plots: dict[Path, bytes] = {}
    for rec in result.records:
        path = folder / plot_name(result, rec)
        n = 2
        while path in plots:  # two records of the same name from different folders
            path = folder / f"{Path(plot_name(result, rec)).stem}-{n}.png"
            n += 1
        plots[path] = plot_record(result, rec)
    return plots


def write_outputs(result: FmuValidation, paths: OutputPaths) -> list[Path]:
    """Render the requested outputs in memory, then write each atomically.

    Returns the paths written, JSON first. Raises :class:`ValidationError` when a file
    cannot be written.
    """
    plots = _rendered_plots(result, paths.plots_dir) if paths.plots_dir is not None else {}
    junit = junit_xml([result]) if paths.junit_path is not None else None
    written: list[Path] = []
    target = None
    try:
        if paths.json_path is not None:
            target = paths.json_path
            written.append(write_json_atomic(target, validation_document(result)))
        if junit is not None and paths.junit_path is not None:
            target = paths.junit_path
            written.append(write_text_atomic(target, junit))
        for target, data in plots.items():
            written.append(write_bytes_atomic(target, data))
    except OSError as exc:
        raise ValidationError(f"{target}: cannot write ({exc.strerror or exc})") from None
    return written
