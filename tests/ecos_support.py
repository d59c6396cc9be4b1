"""ecos (the ``ecospy`` package), the foreign co-simulation engine the tests run FMUs and
SSPs in."""

from __future__ import annotations

import os
from typing import Any

import pytest


def load_ecospy() -> Any:
    """The ``ecospy`` module; the test is skipped where it cannot be loaded (it needs Debian's
    ``libtbb12``), and fails instead where ``GATETWIN_REQUIRE_ECOS`` is set (CI)."""
    try:
        import ecospy
    except (ImportError, OSError) as exc:  # OSError: libecosc.so without libtbb12
        if os.environ.get("GATETWIN_REQUIRE_ECOS"):
            pytest.fail(f"ecos cannot be loaded here: {exc}")
        pytest.skip(f"ecos cannot be loaded here ({exc}); pip install ecospy, apt install "
                    "libtbb12")  # fmt: skip
    return ecospy
