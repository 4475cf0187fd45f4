"""The command line's one-line error: ``drake-coop: error: <message>`` on stderr, exit code 2.

Shared by every command (``run``, ``study``, ``stability``, ``identify``, ...) so that each
sub-command's module imports it from here, below them all, instead of from :mod:`drake_coop.cli`
(which imports the sub-commands).
"""

from __future__ import annotations

import sys

from drake_coop.scenario.bounds import one_line

__all__ = ["error"]


def error(message: object, prog: str = "drake-coop") -> int:
    """Print ``<prog>: error: <message>`` (on one line) to stderr; return the exit code 2.

    Parameters
    ----------
    message : object
        What went wrong (its ``str``, folded onto one line).
    prog : str
        The command's name that starts the line.
    """
    print(f"{prog}: error: {one_line(message)}", file=sys.stderr)
    return 2
