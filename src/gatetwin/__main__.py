"""``python -m gatetwin``: the same as the ``gatetwin`` command."""

import sys

from gatetwin.cli import main

__all__ = []

sys.exit(main())
