"""``python -m dampersim``: the command line interface (see :mod:`dampersim.cli`)."""

import sys

from dampersim.cli import main

sys.exit(main())
