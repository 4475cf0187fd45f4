"""``python -m drake_coop.cli``: :func:`drake_coop.cli.main`."""

import sys

from drake_coop.cli import main

sys.exit(main())
