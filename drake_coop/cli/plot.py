"""``drake-coop plot``: redraw the figures and metrics from a run directory."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from drake_coop.console import error as _error


def cmd_plot(args: argparse.Namespace) -> int:
    """The exit code of ``drake-coop plot`` (0 done, 2 bad input): figures and metrics redrawn
    from a run directory.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (:func:`build_parser`).
    """
    from drake_coop.results import replot

    try:
        paths = replot(Path(args.dir))
    except (OSError, ValueError) as exc:   # missing, unreadable, malformed; read-only folder
        return _error(str(exc))
    if not args.quiet:
        print(f"drake-coop: wrote {len(paths)} files to {args.dir}", file=sys.stderr)
    return 0
