"""The ``drake-coop`` argument parser (:func:`build_parser`: each command's own, and the
subpackages' commands) and its entry point (:func:`main`)."""

from __future__ import annotations

import argparse
import signal
import sys

from drake_coop.cli import signals as _signals
from drake_coop.cli.diagram import cmd_diagram
from drake_coop.cli.identify import cmd_identify
from drake_coop.cli.plot import cmd_plot
from drake_coop.cli.run import cmd_run
from drake_coop.cli.scenarios import cmd_scenarios
from drake_coop.cli.signals import Signals

#: ``identify --estimator``'s choices: :data:`drake_coop.identification.report.ESTIMATORS`
#: (a test checks they are the same; named here so that the parser imports no Drake).
IDENTIFY_ESTIMATORS = ("map_sdp", "idim_iv", "didim")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``drake-coop``.
    """
    from drake_coop.console import OneLineParser

    parser = OneLineParser(
        prog="drake-coop",
        description="Decentralized position/force control of cooperating robot arms holding "
                    "an object, without joint-velocity or contact-force measurements, on "
                    "Drake: run the paper's experiment and your own scenarios, studies and "
                    "benchmarks.")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="simulate an experiment and write its outputs")
    run.add_argument("scenario", nargs="?", default=None,
                     help="scenario YAML file or shipped scenario name (default: paper)")
    run.add_argument("--out", required=True,
                     help="output directory (a new or empty one, or a previous run's with "
                          "--force)")
    run.add_argument("--force", action="store_true",
                     help="replace the previous run held in --out")
    run.add_argument("--quiet", action="store_true",
                     help="no progress bar or messages (the summary is still printed)")
    run.add_argument("--no-replay", action="store_true", help="skip the Meshcat HTML replay")
    run.add_argument("--t-end", type=float, default=None,
                     help="stop the simulation earlier (s)")
    run.add_argument("--meshcat", action="store_true",
                     help="watch the run live in Meshcat (prints its URL)")
    run.add_argument("--realtime-rate", type=float, default=None,
                     help="pace the simulation (1 = real time, 0 = as fast as possible; "
                          "default 1 with --meshcat, else 0)")
    run.set_defaults(func=cmd_run)
    scen = sub.add_parser("scenarios", help="list the shipped scenarios, or print one")
    scen.add_argument("name", nargs="?", default=None, help="print this scenario's YAML")
    scen.set_defaults(func=cmd_scenarios)
    plot = sub.add_parser("plot", help="redraw figures and metrics from a run directory")
    plot.add_argument("dir", help="a run's output directory (drake-coop run --out DIR)")
    plot.add_argument("--quiet", action="store_true", help="no messages")
    plot.set_defaults(func=cmd_plot)
    diagram = sub.add_parser("diagram", help="draw the paper's block diagram, and the "
                                             "port-level diagrams (top level, robot 1's "
                                             "control block)")
    diagram.add_argument("scenario", nargs="?", default=None,
                         help="scenario YAML file or shipped scenario name (default: paper)")
    diagram.add_argument("--out", default="diagrams",
                         help="output directory of the .dot (and, with graphviz, .svg) files "
                              "(default: diagrams)")
    diagram.add_argument("--quiet", action="store_true", help="no messages")
    diagram.set_defaults(func=cmd_diagram)
    ident = sub.add_parser("identify", help="identify the arms' dynamic parameters and write "
                                            "identified URDFs and scenario")
    ident.add_argument("scenario", help="scenario YAML file or shipped scenario name")
    ident.add_argument("--out", required=True, help="output directory")
    ident.add_argument("--robots", default=None, help="robot numbers, e.g. 1,2 (default: all)")
    ident.add_argument("--duration", type=float, default=10.0,
                       help="excitation length in seconds (1 to 120, default 10)")
    ident.add_argument("--seed", type=int, default=0, help="seed of the excitation's design")
    ident.add_argument("--estimator", choices=IDENTIFY_ESTIMATORS, default="map_sdp",
                       help="map_sdp (default: least squares under the physical-consistency "
                            "LMIs), idim_iv (instrumental variables from the simulated closed "
                            "loop) or didim (the simulated loop's regressor); all three keep "
                            "the LMIs")
    ident.add_argument("--wire", default=None, metavar="URL",
                       help="drive the excitation through each arm's driver over LCM at URL "
                            "(tcpq://, udpm://; 'lockstep': the in-process simulated driver, "
                            "stepped tick by tick) and record the wire to DIR/recording.npz")
    ident.add_argument("--recording", default=None, metavar="FILE",
                       help="identify from a recording of the wire (a recording.npz of "
                            "--wire) instead of running an experiment")
    ident.add_argument("--quiet", action="store_true", help="no progress messages")
    ident.set_defaults(func=cmd_identify)
    from drake_coop.studies.cli import add_study_parser
    add_study_parser(sub)
    from drake_coop.studies.reference_engine import add_reference_table_parser
    add_reference_table_parser(sub)
    from drake_coop.stability.cli import add_stability_parser
    add_stability_parser(sub)
    from drake_coop.stability.gains_cli import add_gains_parser
    add_gains_parser(sub)
    from drake_coop.scenario.arms_cli import add_arms_parser
    add_arms_parser(sub)
    from drake_coop.robot.cli import add_robot_parsers
    add_robot_parsers(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``drake-coop`` console script.

    Installs the SIGINT/SIGTERM handlers of :data:`SIGNALS` (restored on return) so that a
    signal at any moment ends the command with 130 (SIGINT) or 143 (SIGTERM), one message and
    no traceback.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program's name (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        The process's exit code (0 done, 1 a run that failed, 2 bad input).
    """
    SIGNALS = _signals.SIGNALS = Signals()
    previous = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, SIGNALS.handler)
    except ValueError:          # not the main thread: leave the handlers alone
        pass
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        return args.func(args)
    except KeyboardInterrupt as exc:
        code = SIGNALS.exit_code(exc)
        print(f"drake-coop: interrupted ({'SIGTERM' if code == 143 else 'Ctrl-C'})",
              file=sys.stderr)
        return code
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
