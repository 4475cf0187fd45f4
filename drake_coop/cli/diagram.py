"""``drake-coop diagram``: the paper's block diagram and the port-level diagrams of the top
level and robot 1's control block (also written by ``drake-coop run``)."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from drake_coop.console import error as _error
from drake_coop.scenario.resources import find_scenario


def _write_block_diagrams(experiment, out: Path, top: str, control: str, quiet: bool
                          ) -> list[Path]:
    """The paper's block diagram (``block_diagram``), and for debugging the top-level
    diagram (one level deep) and robot 1's control block with their connected ports; .dot and
    .svg; a missing graphviz is reported once, as a note."""
    from drake_coop.results.export import write_diagram, write_subsystem_diagram

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        files = [write_diagram(experiment.diagram, out, "block_diagram", style="paper"),
                 write_diagram(experiment.diagram, out, top, style="connected"),
                 write_subsystem_diagram(experiment.robots[0].control, out, control,
                                         style="connected")]
    if caught and not quiet:
        print(f"drake-coop: note: {caught[0].message}", file=sys.stderr)
    return [p for f in files for p in f.values() if p is not None]


def cmd_diagram(args: argparse.Namespace) -> int:
    """The exit code of ``drake-coop diagram`` (0 drawn, 2 bad input), after drawing the
    experiment's block diagram (no loggers or visualizer) and one control block.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (:func:`build_parser`).
    """
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.schema import ScenarioError

    try:
        scenario = load_scenario(args.scenario and find_scenario(args.scenario))
    except ScenarioError as exc:
        return _error(str(exc))
    exp = build_experiment(plan_run(scenario), log=False)
    written = _write_block_diagrams(exp, Path(args.out), "experiment",
                                    f"{exp.robots[0].name}_control", args.quiet)
    if not args.quiet:
        print("drake-coop: wrote " + ", ".join(map(str, written)), file=sys.stderr)
    return 0
