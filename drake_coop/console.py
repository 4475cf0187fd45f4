"""The command line's one-line error: ``drake-coop: error: <message>`` on stderr, exit code 2.

:class:`OneLineParser` does the same for argparse's own errors (a type error, an unknown
option): argparse prints the whole usage (4 lines and more) before the message; this parser
prints ``drake-coop study: error: argument --cases: invalid int value: 'x' (allowed: an
integer); see drake-coop study -h`` and exits with 2. Sub-parsers made with
``add_subparsers().add_parser`` are of their parent's class, so building the top-level parser
with it covers every ``drake-coop`` command.

Shared by every command (``run``, ``study``, ``stability``, ``identify``, ...) so that each
sub-command's module imports it from here, below them all, instead of from :mod:`drake_coop.cli`
(which imports the sub-commands).
"""

from __future__ import annotations

import argparse
import re
import sys

from drake_coop.scenario.bounds import one_line

__all__ = ["OneLineParser", "error"]


def error(message: object, prog: str = "drake-coop") -> int:
    """Print ``<prog>: error: <message>`` (on one line) to stderr; return the exit code 2.

    Parameters
    ----------
    message : object
        What went wrong (its ``str``, folded onto one line).
    prog : str
        The command's name that starts the line.

    Returns
    -------
    int
        2.
    """
    print(f"{prog}: error: {one_line(message)}", file=sys.stderr)
    return 2


#: What argparse's built-in types accept, for its ``invalid <type> value`` messages.
_ALLOWED = {"int": "an integer", "float": "a number"}


class OneLineParser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` whose errors are one line (exit code 2)."""

    def error(self, message: str):
        """Print ``<prog>: error: <message>`` (one line, with what is allowed) and exit 2."""
        match = re.search(r"invalid (\w+) value", message)
        if match and match.group(1) in _ALLOWED:
            message = f"{message} (allowed: {_ALLOWED[match.group(1)]})"
        self.exit(2, f"{self.prog}: error: {one_line(message)}; see {self.prog} -h\n")
