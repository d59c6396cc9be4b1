"""What an FMU carries about the model file it was exported from.

Built from the model file alone, so the command line, ``gatetwin run`` and the Python API
export the same ``resources/provenance.json`` for the same model. Building the FMU itself
is :func:`gatetwin.fmu.export_fmu`'s job.
"""

from __future__ import annotations

from typing import Any

from gatetwin.modelfile import ModelFile

__all__ = ["fmu_provenance"]


def fmu_provenance(model: ModelFile) -> dict[str, Any]:
    """The provenance an FMU of ``model`` stores (JSON data: lists, no tuples).

    ``validity`` is the model's validity envelope
    (:func:`gatetwin.modelfile.validity_envelope`): ``flow_m3h``, ``opening_mm`` and
    ``level_mm`` as ``[low, high]``, each only when the model file states it; the validation
    harness reads it back from ``resources/provenance.json``. ``validity_flow_m3h`` repeats
    the flow range for readers of earlier FMUs.

    Parameters
    ----------
    model : ModelFile
        A read model file (:func:`gatetwin.modelfile.read_model_file`); its ``sha256`` is
        that of the file's bytes.

    Returns
    -------
    dict
        ``model_name``, ``model_file_sha256``, ``method``, ``records``, ``metrics``,
        ``validity_flow_m3h``, ``validity`` and ``gatetwin_version``.

    Examples
    --------
    >>> from gatetwin import bundled_records_dir, identify, read_record
    >>> from gatetwin.fmu.provenance import fmu_provenance
    >>> model = identify(read_record(bundled_records_dir() / "A.csv"))
    >>> fmu_provenance(model.file)["model_file_sha256"] == model.sha256
    True
    """
    prov = model.content.get("provenance", {})
    return {
        "model_name": model.name,
        "model_file_sha256": model.sha256,
        "method": prov.get("method", ""),
        "records": list(prov.get("records", [])),
        "metrics": prov.get("metrics", {}),
        "validity_flow_m3h": list(model.validity_flow_m3h),
        "validity": {k: list(v) for k, v in model.validity_envelope.items()},
        "gatetwin_version": prov.get("gatetwin_version", ""),
    }
