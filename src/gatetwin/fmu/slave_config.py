"""What every part of the pythonfmu slave shares: its CONFIG, the refusal it raises and the
number format of its messages.

Spliced into the slave at export like ``slave_guard.py`` (between the BEGIN/END markers of
``slave_template.py``), without its imports of gatetwin: the slave defines those names
itself, so this file too uses the standard library only once embedded.
``CONFIG_JSON``'s line is replaced at export by the model's description (gatetwin.fmu.
python_build); here it is empty. Not the plant (``slave_template.py`` and its family parts)
nor the FMI layer (``slave_guard.py``), whose RefusedError ``PlantError`` specialises.
"""

from __future__ import annotations

import json
from typing import Any

# BEGIN gatetwin imports (removed at export: the slave defines these names)
from gatetwin.fmu.slave_guard import RefusedError

# END gatetwin imports

__all__ = ["CONFIG", "CONFIG_JSON", "PlantError"]

CONFIG_JSON = "{}"  # replaced at export by gatetwin.fmu.python_build
CONFIG: dict[str, Any] = json.loads(CONFIG_JSON)


class PlantError(RefusedError):
    """An input, parameter, state or step the plant refuses (the message says why)."""


def _g(value: float) -> str:
    """C's %.17g for the messages."""
    return f"{value:.17g}"
