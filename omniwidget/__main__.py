"""Run the command line: ``python -m omniwidget``."""

import sys

from .app.cli import main

sys.exit(main())
