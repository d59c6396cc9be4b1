"""Diagnose a record against a model: :func:`gatetwin.diagnosis.diagnose_record` as one call
whose result has named fields."""

from __future__ import annotations

import copy
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gatetwin.api._model import Model
from gatetwin.errors import GatetwinError
from gatetwin.records import Record

__all__ = ["Diagnosis", "diagnose"]


@dataclass(frozen=True)
class Diagnosis:
    """Where a model and a record disagree, and which missing effect explains it.

    Attributes
    ----------
    record : str
        The record's file name.
    gauge : str
        The gauge diagnosed.
    named_effect : str
        The effect block that earns its parameters (``"none"`` if none does).
    rmse_before_mm, rmse_after_mm : float
        Free-run RMSE of the baseline and of the baseline with the named effect, mm.
    noise_floor_mm : float
        Level noise SD from the record's steady holds, mm.
    gap_reduction : float
        Share of the gap above the noise floor the named effect closes (0 to 1).
    baseline_source : str
        Where the baseline came from, in words.
    details : dict
        Everything the diagnosis found (candidates, windows, regions, ...): the JSON of
        ``gatetwin diagnose``.

    Examples
    --------
    >>> from gatetwin import bundled_records_dir, diagnose
    >>> found = diagnose(bundled_records_dir() / "Q55.csv")
    >>> found.record, found.named_effect
    ('Q55.csv', 'none')
    """

    record: str
    gauge: str
    named_effect: str
    rmse_before_mm: float
    rmse_after_mm: float
    noise_floor_mm: float
    gap_reduction: float
    baseline_source: str
    details: dict[str, Any] = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        """A copy of :attr:`details` (JSON-ready).

        Examples
        --------
        >>> from gatetwin import bundled_records_dir, diagnose
        >>> sorted(diagnose(bundled_records_dir() / "Q55.csv").to_dict())[:3]
        ['augmented_model', 'baseline', 'candidates']
        """
        return copy.deepcopy(self.details)


def _record_path(record: Record | str | os.PathLike[str]) -> str:
    if isinstance(record, Record):
        if not record.path:
            raise GatetwinError("diagnose: the record has no file (built from arrays); "
                                "write it as CSV and pass its path")  # fmt: skip
        return record.path
    return os.fspath(record)


def diagnose(record: Record | str | os.PathLike[str],
             model: Model | str | os.PathLike[str] | None = None, *, gauge: str | None = None,
             plots_dir: str | os.PathLike[str] | None = None,
             fmu_dir: str | os.PathLike[str] | None = None) -> Diagnosis:  # fmt: skip
    """Find where ``model`` and ``record`` disagree beyond the noise floor, and why.

    Parameters
    ----------
    record : Record, str or PathLike
        The record (read from a file).
    model : Model, str or PathLike, optional
        The baseline (FOPDT or ARX; an envelope FOPDT is diagnosed in its local form);
        default one identified from the record itself.
    gauge : str, optional
        Gauge to diagnose; default the model's, else ``3F`` if logged, else the first.
    plots_dir : str or PathLike, optional
        Write the diagnosis figure there.
    fmu_dir : str or PathLike, optional
        Write the augmented model file and its FMUs (re-validated) there.

    Returns
    -------
    Diagnosis

    Raises
    ------
    GatetwinError
        A bad record or model, or a record the diagnosis cannot use.

    Examples
    --------
    >>> from gatetwin import bundled_records_dir, diagnose, identify
    >>> model = identify(bundled_records_dir() / "A.csv")
    >>> found = diagnose(bundled_records_dir() / "A.csv", model)
    >>> found.gauge, found.rmse_after_mm <= found.rmse_before_mm
    ('3F', True)
    """
    from gatetwin.diagnosis import DiagnosisSettings, diagnose_record

    settings = DiagnosisSettings(gauge=gauge)
    places = {"plots_dir": plots_dir, "fmu_dir": fmu_dir, "settings": settings}
    if isinstance(model, Model) and not model.path:
        with tempfile.TemporaryDirectory(prefix="gatetwin-") as tmp:
            path = model.save(Path(tmp) / f"{model.name}.json")
            found = diagnose_record(_record_path(record), path, **places)
    else:
        path = model.path if isinstance(model, Model) else model
        found = diagnose_record(_record_path(record), path, **places)
    return Diagnosis(found["record"], found["gauge"], found["named_effect"],
                     found["rmse_before_mm"], found["rmse_after_mm"], found["noise_floor_mm"],
                     found["gap_reduction"], found["baseline"]["source"], found)  # fmt: skip
