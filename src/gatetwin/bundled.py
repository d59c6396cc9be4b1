"""Where the data shipped with the package lives (records, model-file schema).

A library module may locate bundled data through here without importing the ``gatetwin
run`` orchestration (:mod:`gatetwin.pipeline`). It locates files; it does not read them.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from gatetwin.errors import PipelineError


def bundled_data_dir() -> Path:
    """The package data directory (``gatetwin/data``)."""
    root = resources.files("gatetwin").joinpath("data")
    if not isinstance(root, Path):
        raise PipelineError(f"bundled data at {root} are not on the file system")
    return root


def bundled_records_dir() -> Path:
    """The package data directory of bundled records (``gatetwin/data/records``)."""
    return bundled_data_dir() / "records"


def bundled_schema_path() -> Path:
    """The model-file JSON schema shipped with the package."""
    return bundled_data_dir() / "model_schema.json"


__all__ = ["bundled_data_dir", "bundled_records_dir", "bundled_schema_path"]
