"""``python -m gatetwin.cli`` runs the command line."""

import sys

from gatetwin.cli import main

__all__ = []

sys.exit(main())
