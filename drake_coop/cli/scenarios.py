"""``drake-coop scenarios``: list the shipped scenarios, or print one."""

from __future__ import annotations

import argparse
import sys

from drake_coop.console import error as _error
from drake_coop.scenario.resources import scenario_summary, shipped_scenarios


def cmd_scenarios(args: argparse.Namespace) -> int:
    """The exit code of ``drake-coop scenarios`` (0 listed, 2 an unknown name), after listing
    the shipped scenarios or printing one.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (:func:`build_parser`).
    """
    shipped = shipped_scenarios()
    if args.name is None:
        width = max(map(len, shipped))
        for name, path in shipped.items():
            print(f"{name:<{width}}  {scenario_summary(path)}")
        return 0
    name = args.name[:-5] if args.name.endswith(".yaml") else args.name
    if name not in shipped:
        return _error(f"unknown scenario {args.name!r}; shipped: {', '.join(shipped)}")
    sys.stdout.write(shipped[name].read_text(encoding="utf-8"))
    return 0
