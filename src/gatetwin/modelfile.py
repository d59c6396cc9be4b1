"""Model files: the versioned JSON form of an identified, scheduled plant.

A model file holds the plant (parameters with units, schedule on Q, operating point,
validity range), the per-condition identifications it was built from, the rating relation,
and provenance (records with their hashes, method, metrics). Its JSON Schema is
``models/schema.json`` in the repository (``gatetwin/data/model_schema.json`` in the
package); :func:`read_model_file` checks a file against it, and against the size and text
rules of :mod:`gatetwin.modelschema`, before building anything from it.
"""

from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from gatetwin._io import write_json_atomic, write_text_atomic
from gatetwin.errors import ModelFileError
from gatetwin.modelschema import MAX_FILE_BYTES, check_model_document, parse_model_json, show
from gatetwin.plant.model import Plant, check_operating_storage, plant_from_dict, plant_to_dict
from gatetwin.records.limits import open_regular
from gatetwin.version import __version__

__all__ = [
    "FLOW_METER_ACCURACY_M3H",
    "SCHEMA_ID",
    "SCHEMA_MAJOR",
    "SCHEMA_VERSION",
    "UNITS",
    "ModelFile",
    "applies_to",
    "model_document",
    "physical_document",
    "read_model_file",
    "schema_text",
    "validity_envelope",
    "write_model_file",
    "write_model_files",
]

SCHEMA_ID = "https://gatetwin.invalid/schema/model-1.json"
SCHEMA_VERSION = "1.0"
SCHEMA_MAJOR = SCHEMA_VERSION.split(".")[0]
#: The flow meter's accuracy, m³/h: a discharge this close to the validity range is inside it.
FLOW_METER_ACCURACY_M3H = 1.0

UNITS = {
    "opening": "mm",
    "flow": "m3/h",
    "level": "mm",
    "time": "s",
    "gain_mm_per_mm": "mm/mm",
    "time_constant_s": "s",
    "dead_time_s": "s",
    "level_ref_mm": "mm",
    "a_i, b_j": "dimensionless (ARX, deviations in mm and mm)",
}


@dataclass(frozen=True)
class ModelFile:
    """A read model file.

    Attributes
    ----------
    name : str
        Model name (also the FMU's name).
    plant : Plant
        The scheduled plant.
    content : dict
        The whole file (conditions, rating, provenance, ...).
    sha256 : str
        Hash of the file's bytes (for an FMU's provenance).
    path : str
        Where it was read from.
    """

    name: str
    plant: Plant
    content: dict[str, Any]
    sha256: str
    path: str = ""

    @property
    def validity_flow_m3h(self) -> tuple[float, float]:
        lo, hi = self.content["validity"]["flow_m3h"]
        return float(lo), float(hi)

    @property
    def validity_envelope(self) -> dict[str, list[float]]:
        """The ranges the model is valid over (see :func:`validity_envelope`)."""
        return validity_envelope(self.content)


def _pair(value: Any, what: str) -> list[float]:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ModelFileError(f"validity.{what}: expected [low, high], got {value!r}") from None
    if not lo <= hi:
        raise ModelFileError(f"validity.{what}: low {lo:g} above high {hi:g}")
    return [lo, hi]


def validity_envelope(content: dict[str, Any]) -> dict[str, list[float]]:
    """The box of operating conditions a model file declares itself valid over.

    Keys, each ``[low, high]`` and each present only when the file says it:

    * ``flow_m3h`` -- ``validity.flow_m3h``, m³/h;
    * ``opening_mm`` -- ``validity.opening_range_mm`` if given, else the operating openings
      at the knots widened by the band: ``[min(knots) - band, max(knots) + band]``, mm, from
      ``validity.opening_mm_at_knots`` and ``validity.opening_band_mm``;
    * ``level_mm`` -- ``validity.level_range_mm`` (the level at the model's gauge), mm.

    A missing key means unknown, not unbounded. The box is coarser than :func:`applies_to`,
    which follows the operating opening along Q.

    Raises
    ------
    ModelFileError
        A range that is not two numbers with low <= high.
    """
    validity = content.get("validity", {})
    out: dict[str, list[float]] = {}
    if "flow_m3h" in validity:
        out["flow_m3h"] = _pair(validity["flow_m3h"], "flow_m3h")
    if "opening_range_mm" in validity:
        out["opening_mm"] = _pair(validity["opening_range_mm"], "opening_range_mm")
    elif validity.get("opening_mm_at_knots") and "opening_band_mm" in validity:
        knots = [float(e) for e in validity["opening_mm_at_knots"]]
        band = float(validity["opening_band_mm"])
        out["opening_mm"] = [round(min(knots) - band, 6), round(max(knots) + band, 6)]
    if "level_range_mm" in validity:
        out["level_mm"] = _pair(validity["level_range_mm"], "level_range_mm")
    return out


def model_document(
    name: str, plant: Plant, *, description: str, conditions: list[dict[str, Any]],
    rating: dict[str, Any], provenance: dict[str, Any], operating_openings_mm: list[float],
    opening_band_mm: float, extra: dict[str, Any] | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Assemble a model file's content (no timestamps: identical inputs, identical file).

    ``operating_openings_mm`` are the openings the conditions were identified around (one a
    knot); the model is valid within ``opening_band_mm`` of them (interpolated in Q).
    """
    lo, hi = plant.schedule.flow_range_m3h
    doc: dict[str, Any] = {
        "$schema": SCHEMA_ID,
        "schema_version": SCHEMA_VERSION,
        "name": name,
        "description": description,
        "gauge": plant.gauge,
        "units": UNITS,
        "plant": plant_to_dict(plant),
        "operating_point": {
            "opening_ref_mm": plant.opening_ref_mm,
            "level_ref_mm": list(plant.schedule.values["level_ref_mm"]),
            "flow_m3h": list(plant.schedule.flow_m3h),
        },
        "validity": {
            "flow_m3h": [lo, hi],
            "opening_mm_at_knots": [round(float(e), 3) for e in operating_openings_mm],
            "opening_band_mm": opening_band_mm,
            "outside": "parameters clamped to the nearest knot; a warning is logged once. "
            "Openings farther than opening_band_mm from the operating opening at the record's "
            "Q are extrapolation: the model is linear around its operating line",
        },
        "conditions": conditions,
        "rating": rating,
        "provenance": {"gatetwin_version": __version__, **provenance},
    }
    doc.update(extra or {})
    return doc


def physical_document(
    name: str, plant: Plant, ranges: dict[str, list[float]], *, description: str,
    provenance: dict[str, Any],
) -> dict[str, Any]:  # fmt: skip
    """A physical model file's content: the validity is the envelope of the data it was
    identified from (discharge, opening and level ranges)."""
    from gatetwin.plant.physical_kernel import PARAMETERS

    return {
        "$schema": SCHEMA_ID,
        "schema_version": SCHEMA_VERSION,
        "name": name,
        "description": description,
        "gauge": plant.gauge,
        "units": {**UNITS, **{n: u for n, u, _ in PARAMETERS}},
        "plant": plant_to_dict(plant),
        "parameters": [{"name": n, "unit": u, "description": d} for n, u, d in PARAMETERS],
        "operating_point": {
            "opening_ref_mm": plant.opening_ref_mm,
            "level_ref_mm": list(plant.schedule.values["level_ref_mm"]),
            "flow_m3h": list(plant.schedule.flow_m3h),
        },
        "validity": {
            "flow_m3h": list(ranges["flow_m3h"]),
            "opening_range_mm": list(ranges["opening_mm"]),
            "level_range_mm": list(ranges["level_mm"]),
            "outside": "the gate law and storage are extrapolated; a warning is logged once "
            "when the discharge leaves the range",
        },
        "provenance": {"gatetwin_version": __version__, **provenance},
    }


def write_model_file(path: str | Path, content: dict[str, Any]) -> Path:
    return write_json_atomic(path, content)


def read_model_file(path: str | Path) -> ModelFile:
    """Read and check a model file; :class:`ModelFileError` names the file and the fault.

    Every rule of :mod:`gatetwin.modelschema` (size, nesting, text, the JSON Schema with its
    physical bounds) is checked before any plant is built from the content.
    """
    p = Path(path)
    try:
        # a FIFO, a device or a directory is refused before anything is read from it
        with open_regular(p, sys.maxsize, "a model file (JSON)", ModelFileError) as handle:
            raw = handle.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise ModelFileError(f"{p}: cannot read ({exc.strerror or exc})") from None
    try:
        content = parse_model_json(raw)
        if not isinstance(content, dict):
            raise ModelFileError("a model file is a JSON object")
        version = content.get("schema_version", "")
        if not (isinstance(version, str) and version.split(".")[0] == SCHEMA_MAJOR):
            raise ModelFileError(
                f"schema_version {show(version) if version else '(missing)'}; this gatetwin "
                f"reads {SCHEMA_VERSION}"
            )
        check_model_document(content)
        plant = plant_from_dict(content["plant"])
        box = validity_envelope(content)
        if "level_mm" in box and "flow_m3h" in box:
            check_operating_storage(plant, box["level_mm"], box["flow_m3h"])
    except ModelFileError as exc:
        raise ModelFileError(f"{p}: {exc}") from None
    return ModelFile(content["name"], plant, content, hashlib.sha256(raw).hexdigest(), str(p))


def applies_to(content: dict[str, Any], flow_m3h: float, openings_mm: Any) -> tuple[bool, str]:
    """Whether a model is valid for a record at ``flow_m3h`` with hold ``openings_mm``."""
    import numpy as np

    validity = content["validity"]
    lo, hi = validity["flow_m3h"]
    if not lo - FLOW_METER_ACCURACY_M3H <= flow_m3h <= hi + FLOW_METER_ACCURACY_M3H:
        return False, f"Q {flow_m3h:.1f} m³/h outside [{lo}, {hi}]"
    if "opening_range_mm" in validity:
        e_lo, e_hi = validity["opening_range_mm"]
        e = np.asarray(openings_mm, dtype=float)
        e = e[np.isfinite(e)]
        if e.size and not (e_lo <= e.min() and e.max() <= e_hi):
            return False, f"openings {e.min():g}–{e.max():g} mm outside [{e_lo}, {e_hi}]"
        return True, "within validity"
    knots = content["plant"]["schedule"]["flow_m3h"]
    centre = float(np.interp(flow_m3h, knots, validity["opening_mm_at_knots"]))
    band = float(validity["opening_band_mm"])
    e = np.asarray(openings_mm, dtype=float)
    e = e[np.isfinite(e)]
    worst = float(np.max(np.abs(e - centre))) if e.size else 0.0
    if worst > band:
        return False, (f"openings up to {worst:.0f} mm from the operating opening "
                       f"{centre:.1f} mm at this Q (band ±{band:g} mm)")  # fmt: skip
    return True, "within validity"


def schema_text() -> str:
    """The model-file JSON Schema shipped with the package."""
    return (resources.files("gatetwin") / "data" / "model_schema.json").read_text("utf-8")


def write_model_files(models: dict[str, dict[str, Any]], out: Path) -> list[Path]:
    """Write every model document and the schema into ``out`` (each file atomically)."""
    paths = [write_text_atomic(Path(out) / "schema.json", schema_text())]
    for name, doc in sorted(models.items()):
        paths.append(write_json_atomic(Path(out) / f"{name}.json", doc))
    return paths
