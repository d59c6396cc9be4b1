"""Validate FMUs against records: the fmpy harness (:mod:`gatetwin.validation`) as one call
whose result is a table, a verdict and a figure."""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from gatetwin.api._simulation import require_pandas
from gatetwin.records import Record, read_record

__all__ = ["ValidationReport", "validate"]


def _many(value: Any, single: tuple[type, ...]) -> list[Any]:
    return [value] if isinstance(value, single) else list(value)


def _limits(value: Mapping[str, float] | Sequence[str]) -> list[str]:
    """``{"fit_percent": 70}`` or ``["fit_percent=70"]`` as the harness's ``METRIC=VALUE``."""
    if isinstance(value, Mapping):
        return [f"{k}={v}" for k, v in value.items()]
    return [value] if isinstance(value, str) else list(value)


@dataclass(frozen=True, eq=False)
class ValidationReport:
    """FMUs validated against records (free run through fmpy, measured vs simulated).

    Attributes
    ----------
    results : tuple of FmuValidation
        One per FMU (:class:`gatetwin.validation.FmuValidation`): metrics, noise floor,
        validity and checks per record, with the signals in each record's ``trace``.

    Examples
    --------
    >>> from gatetwin import bundled_records_dir, identify, validate
    >>> fmu = identify(bundled_records_dir() / "A.csv").export_fmu("fopdt_3F.fmu")
    >>> report = validate(fmu, bundled_records_dir() / "A.csv", fail_under={"fit_percent": 70})
    >>> report.passed, len(report.cells)
    (True, 1)
    """

    results: tuple[Any, ...]

    @property
    def passed(self) -> bool:
        """True when every FMU passed fmpy's static validation and every threshold."""
        return all(r.passed for r in self.results)

    @property
    def cells(self) -> list[dict[str, Any]]:
        """One flat, JSON-ready dict per FMU × record (see
        :func:`gatetwin.validation.matrix_cells`): ``fit_percent``, ``rmse_mm``, ``passed``...
        """
        from gatetwin.validation import matrix_cells

        return [cell for r in self.results for cell in matrix_cells(r)]

    def to_dict(self) -> dict[str, Any]:
        """The JSON ``gatetwin validate --json`` writes, one document per FMU."""
        return {"fmus": [r.to_dict() for r in self.results], "passed": self.passed}

    def markdown(self) -> str:
        """The cells as the Markdown table ``gatetwin validate`` prints."""
        from gatetwin.validation import matrix_markdown

        return matrix_markdown(self.cells)

    def to_pandas(self) -> Any:
        """The cells as a :class:`pandas.DataFrame` (one row per FMU × record).

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify, validate
        >>> fmu = identify(bundled_records_dir() / "A.csv").export_fmu("fopdt_3F.fmu")
        >>> frame = validate(fmu, bundled_records_dir() / "A.csv").to_pandas()
        >>> list(frame[["fmu", "record"]].iloc[0])
        ['fopdt_3F.fmu', 'A.csv']
        """
        return require_pandas().DataFrame(self.cells)

    def plot(self) -> Any:
        """Measured and simulated level, one panel per FMU × record.

        Returns
        -------
        matplotlib.figure.Figure

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, identify, validate
        >>> fmu = identify(bundled_records_dir() / "A.csv").export_fmu("fopdt_3F.fmu")
        >>> fig = validate(fmu, bundled_records_dir() / "A.csv").plot()
        >>> fig.axes[0].get_title()
        'fopdt_3F.fmu on A.csv: fit 94.3 %'
        >>> import matplotlib.pyplot as plt; plt.close(fig)
        """
        import matplotlib.pyplot as plt

        pairs = [(r, rec) for r in self.results for rec in r.records]
        fig, axes = plt.subplots(len(pairs), 1, figsize=(8, 2.8 * len(pairs)), squeeze=False)
        for ax, (result, rec) in zip(axes[:, 0], pairs, strict=True):
            trace = rec.trace
            ax.plot(trace.time_s, trace.measured_mm, ".", ms=2, color="0.5", label="measured")
            ax.plot(trace.time_s, trace.simulated_mm, label="FMU (free run)")
            ax.set_title(f"{result.fmu.name} on {rec.record}: fit "
                         f"{rec.metrics.fit_percent:.1f} %")  # fmt: skip
            ax.set_ylabel(f"level_{rec.gauge}_mm (mm)")
            ax.legend(loc="best")
        axes[-1, 0].set_xlabel("time (s)")
        fig.tight_layout()
        return fig


def validate(fmus: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
             records: Record | str | os.PathLike[str] | Sequence[Record | str | os.PathLike[str]],
             *, gauge: str | None = None,
             fail_under: Mapping[str, float] | Sequence[str] = (),
             fail_over: Mapping[str, float] | Sequence[str] = (),
             fail_outside_validity: bool = False,
             variable_map: str | os.PathLike[str] | None = None) -> ValidationReport:  # fmt: skip
    """Drive FMUs with records' measured inputs through fmpy and score their free run.

    Parameters
    ----------
    fmus : str, PathLike or sequence of them
        FMI 2.0 co-simulation FMUs with inputs ``opening_mm``, ``flow_m3h`` and a level
        output (as :meth:`Model.export_fmu <gatetwin.Model.export_fmu>` writes).
    records : Record, str, PathLike or sequence of them
        Measured records (read once, shared by every FMU).
    gauge : str, optional
        Gauge to compare; default each FMU's only level output.
    fail_under, fail_over : mapping or sequence of str
        Thresholds, ``{"fit_percent": 70}`` or ``["fit_percent=70"]``: a record fails when
        the metric is below (above) the value. The metrics are those of
        ``gatetwin validate --fail-under / --fail-over``.
    fail_outside_validity : bool
        Fail a record lying outside the validity the FMU states.
    variable_map : str or PathLike, optional
        For FMUs gatetwin did not write: a TOML file naming their variable and unit behind
        each record column (``gatetwin validate --map``; :mod:`gatetwin.validation.mapping`).

    Returns
    -------
    ValidationReport

    Raises
    ------
    ValidationError
        An FMU that cannot be run, a record without the gauge, a malformed threshold or
        variable map.
    RecordError
        A record breaks the data-format contract.

    Examples
    --------
    >>> from gatetwin import bundled_records_dir, identify, validate
    >>> fmu = identify(bundled_records_dir() / "A.csv").export_fmu("fopdt_3F.fmu")
    >>> cell = validate(fmu, bundled_records_dir() / "A.csv").cells[0]
    >>> cell["fit_percent"] > 85, cell["inside_validity"]
    (True, True)
    """
    from gatetwin.validation import parse_thresholds, validate_fmu
    from gatetwin.validation.mapping import read_variable_map

    vmap = read_variable_map(os.fspath(variable_map)) if variable_map is not None else None
    paths = [os.fspath(p) for p in _many(fmus, (str, os.PathLike))]
    loaded = [r if isinstance(r, Record) else read_record(os.fspath(r))
              for r in _many(records, (str, os.PathLike, Record))]  # fmt: skip
    thresholds = parse_thresholds(_limits(fail_under), _limits(fail_over))
    return ValidationReport(tuple(
        validate_fmu(p, loaded, gauge=gauge, thresholds=thresholds,
                     fail_outside_validity=fail_outside_validity, variable_map=vmap)
        for p in paths
    ))  # fmt: skip
