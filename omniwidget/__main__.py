"""Run the command line: ``python -m omniwidget``."""

import sys

from .cli import main

sys.exit(main())
