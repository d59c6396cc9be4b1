"""The MPC package's exception (a :class:`~gatetwin.errors.GatetwinError`).

Kept here rather than in ``gatetwin/errors.py`` only because that file has another owner;
it can move there unchanged.
"""

from __future__ import annotations

from gatetwin.errors import GatetwinError


class ControlError(GatetwinError, ValueError):
    """A controller, model rendering or closed-loop scenario cannot be set up as asked."""


__all__ = ["ControlError"]
