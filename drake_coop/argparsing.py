"""The command line's parser: a bad argument is one line naming it and what is allowed.

``argparse``'s own :meth:`~argparse.ArgumentParser.error` prints the whole usage (4 lines
and more for ``study``) before the message. :class:`OneLineParser` prints only
``<prog>: error: argument --cases: invalid int value: 'x' (allowed: an integer)`` and exits
with 2. Sub-parsers made with ``add_subparsers().add_parser`` are of their parent's class,
so building the top-level parser with it covers every ``drake-coop`` command.
"""

from __future__ import annotations

import argparse
import re
import sys

from drake_coop.scenario.bounds import one_line

__all__ = ["OneLineParser"]

#: What argparse's built-in types accept, for ``invalid <type> value`` messages.
_ALLOWED = {"int": "an integer", "float": "a number"}


class OneLineParser(argparse.ArgumentParser):
    """An :class:`argparse.ArgumentParser` whose errors are one line (exit code 2)."""

    def error(self, message: str):
        """Print ``<prog>: error: <message>`` (one line, with what is allowed) and exit 2."""
        match = re.search(r"invalid (\w+) value", message)
        if match and match.group(1) in _ALLOWED:
            message = f"{message} (allowed: {_ALLOWED[match.group(1)]})"
        self.exit(2, f"{self.prog}: error: {one_line(message)}; see {self.prog} -h\n")
