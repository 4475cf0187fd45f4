"""``python -m drake_coop``: the same as the ``drake-coop`` console script."""

import sys

from drake_coop.cli import main

sys.exit(main())
