"""The validation harness's own error class.

Kept here so the harness is self-contained; it may move into :mod:`gatetwin.errors`.
"""

from __future__ import annotations

from gatetwin.errors import GatetwinError


class ValidationError(GatetwinError, ValueError):
    """An FMU, a record or a request that cannot be validated.

    Raised for a file that is not an FMU (not a zip, no ``modelDescription.xml``), an FMU
    without a binary for this platform or without the expected inputs and outputs, an
    FMU that refuses or fails an FMI call during the simulation (the message names the
    call, its status and the FMU's last log line), a record without the gauge the FMU
    computes, and a malformed threshold. It is *not* raised when an FMU simulates but
    misses a threshold: that is a finding, reported in the results.
    """
