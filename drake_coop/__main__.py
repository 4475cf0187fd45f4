"""``python -m drake_coop``: the same as the ``drake-coop`` console script.

Ctrl-C or SIGTERM while the command line is still being imported ends it quietly (130 / 143),
before :func:`drake_coop.cli.main` installs its own handlers.
"""

import signal
import sys


def _quiet_exit(signum, frame):
    sys.stderr.write(f"drake-coop: interrupted ({'SIGTERM' if signum == signal.SIGTERM else 'Ctrl-C'})\n")
    raise SystemExit(143 if signum == signal.SIGTERM else 130)


for _sig in (signal.SIGINT, signal.SIGTERM):
    signal.signal(_sig, _quiet_exit)

from drake_coop.cli import main  # noqa: E402  (after the handlers)

sys.exit(main())
