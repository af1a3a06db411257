"""``python -m heatcurv.cli``: the same as ``python -m heatcurv``."""

import sys

from .main import main

sys.exit(main())
