"""Where the data shipped with gatetwin live (the bundled reference records).

Only locates files; reading them is :mod:`gatetwin.records`' job.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from gatetwin.errors import GatetwinError

__all__ = ["bundled_records_dir", "bundled_swmm_model"]


def bundled_records_dir() -> Path:
    """The folder of the bundled records (``gatetwin/data/records``).

    Returns
    -------
    Path
        A folder of records in the record format (docs/record_format.md): the virtual
        flume's step and PRBS tests, the validation records and the static rating table
        ``static.csv``.

    Raises
    ------
    GatetwinError
        The package is installed in a way that leaves its data off the file system (a zip).

    Examples
    --------
    >>> from gatetwin import bundled_records_dir
    >>> (bundled_records_dir() / "A.csv").is_file()
    True
    """
    root = resources.files("gatetwin").joinpath("data", "records")
    if not isinstance(root, Path):
        raise GatetwinError(f"bundled records at {root} are not on the file system")
    return root


def bundled_swmm_model() -> Path:
    """The shipped EPA SWMM model of ASCE test canal 1 (``data/swmm/asce_canal1.inp``)."""
    return Path(__file__).resolve().parent / "data" / "swmm" / "asce_canal1.inp"
