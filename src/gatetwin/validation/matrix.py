"""The FMU × record validation matrix as flat cells and as a Markdown table.

:func:`matrix_cells` flattens one FMU's validation (:class:`~gatetwin.validation.results.
FmuValidation`) into JSON-ready cells, one per record; :func:`matrix_markdown` renders cells
as a table. Running the FMUs is :func:`gatetwin.validation.harness.validate_matrix`'s.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from gatetwin.identification.serial import finite_or_none
from gatetwin.validation.results import FmuValidation, RecordValidation

__all__ = [
    "MATRIX_METRICS",
    "RUN_CHECK",
    "VALIDITY_CHECK",
    "matrix_cells",
    "matrix_markdown",
    "validity_text",
]

#: Columns of a matrix cell, in table order (besides ``fmu`` and ``record``).
MATRIX_METRICS = ("fit_percent", "r2", "rmse_mm", "mae_mm", "max_abs_error_mm", "bias_mm")

#: Name of the failed check of a record outside the envelope (with ``fail_outside_validity``).
VALIDITY_CHECK = "inside validity"
#: Prefix of the failed check of a record whose FMU run failed (followed by the cause).
RUN_CHECK = "FMU run failed"


def matrix_cells(result: FmuValidation) -> list[dict[str, Any]]:
    """Flat, JSON-ready cells (one per record) of one FMU's validation."""
    cells = []
    for rec in result.records:
        metrics = rec.metrics.to_dict()
        cells.append(
            {
                "fmu": result.fmu.name,
                "record": rec.record,
                "gauge": rec.gauge,
                "test": rec.test,
                **{name: metrics[name] for name in MATRIX_METRICS},
                "noise_floor_fit_percent": finite_or_none(rec.noise_floor_fit_percent),
                "fit_vs_floor": finite_or_none(rec.fit_vs_floor),
                "noise_sigma_mm": rec.noise_floor_dict()["sigma_mm"],
                "inside_validity": rec.inside_validity,
                "outside_validity": rec.validity.problems() if rec.validity else [],
                "failure_cause": rec.failure_cause or None,
                "static_passed": result.static_passed,
                "failed_checks": _failed_checks(result, rec),
                "passed": result.static_passed and rec.passed,
            }
        )
    return cells


def _failed_checks(result: FmuValidation, rec: RecordValidation) -> list[str]:
    static = [] if result.static_passed else ["fmpy static validation"]
    run = [f"{RUN_CHECK}: {rec.failure_cause}"] if rec.failure_cause else []
    validity = [VALIDITY_CHECK] if rec.validity_failed else []
    return static + run + [c.threshold.text for c in rec.checks if c.failed] + validity


def _cell_text(value: Any) -> str:
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "pass" if value else "**FAIL**"
    if isinstance(value, float):
        return f"{value:.3f}" if abs(value) < 10 else f"{value:.1f}"
    return str(value).replace("|", "\\|")


def _fit_and_floor(cell: dict[str, Any]) -> str:
    """``fit / floor`` in %, one decimal (– where unknown)."""
    parts = [cell.get("fit_percent"), cell.get("noise_floor_fit_percent")]
    return " / ".join("–" if v is None else f"{v:.1f}" for v in parts)


def validity_text(cell: dict[str, Any]) -> str:
    """A cell's place in the envelope: ``inside``, ``unknown`` or ``outside: <what>``."""
    inside = cell.get("inside_validity")
    if inside is None:
        return "unknown"
    if inside:
        return "inside"
    return "outside: " + ", ".join(cell.get("outside_validity", []))


def matrix_markdown(cells: Sequence[dict[str, Any]]) -> str:
    """The validation matrix as a Markdown table (one row per FMU × record).

    ``fit / floor %`` is the free-run fit next to the noise floor's fit (the best a perfect
    model can expect on that record); ``validity`` says whether the record lies inside the
    envelope the FMU states (``unknown`` when it states none, or not every range).
    """
    header = ["FMU", "record", "gauge", "fit / floor %", "R²", "RMSE (mm)", "MAE (mm)",
              "max abs error (mm)", "bias (mm)", "validity", "result"]  # fmt: skip
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for cell in cells:
        values = [cell["fmu"], cell["record"], cell["gauge"]]
        row = [_cell_text(v) for v in values] + [_fit_and_floor(cell)]
        row += [_cell_text(cell[m]) for m in MATRIX_METRICS[1:]]
        row += [_cell_text(validity_text(cell)), _cell_text(cell["passed"])]
        if cell.get("failed_checks"):
            row[-1] += " (" + "; ".join(cell["failed_checks"]) + ")"
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines) + "\n"
