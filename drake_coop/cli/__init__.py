"""Command line: ``drake-coop run | scenarios | plot | diagram | study | stability | gains |
identify | serve | sim-driver`` (also
``python -m drake_coop``).

``drake-coop run [SCENARIO] --out DIR [--meshcat]``
    Simulate the experiment (SCENARIO: a YAML file or a shipped scenario's name; the shipped
    ``paper.yaml`` without one) and write to DIR: the logs
    (``robot1.npz``/``.csv``, ``robot2.*``, ``run.json``), ``metrics.json``, Figures 2–7 (PNG and
    SVG), the reference figure, the system diagram (``.dot``, ``.svg`` when graphviz is
    installed) and a self-contained Meshcat replay ``replay.html``.
    A previous run held in DIR is replaced only with ``--force`` (else exit 2, nothing
    simulated). The command ends with a summary of the circle phase's errors per robot and a
    warning line per failed physical sanity check (:mod:`drake_coop.results.summary`).
    Exit codes: 0 done, 1 the run diverged (what was logged is still written), 2 bad input
    (scenario, model files, ``--out``), 130 interrupted with Ctrl-C (SIGINT), 143 stopped by
    SIGTERM (in both cases what was logged is still written). The outputs are staged in a
    hidden sibling of DIR and renamed into place at the end (:mod:`drake_coop.results.run_folder`).
    ``--meshcat`` also shows the run live in Meshcat (its URL is printed; paced at real time
    unless ``--realtime-rate`` says otherwise).
``drake-coop scenarios [NAME]``
    List the shipped scenarios (name and first comment line), or print one to copy and edit.
``drake-coop plot DIR``
    Redraw the figures and metrics from the logs in DIR.
``drake-coop diagram [SCENARIO.yaml] [--out diagrams]``
    Draw the paper's block diagram (``block_diagram``) and, for debugging, the port-level
    diagrams of the top level (``experiment``) and robot 1's control block, without loggers.
``drake-coop study STUDY.yaml --out DIR`` / ``drake-coop study --plot DIR``
    Parameter studies and Monte Carlo (see :mod:`drake_coop.studies.cli`).
``drake-coop stability SCENARIO --out DIR [--grid PATH=v1,v2,...] [--point free|held|both]``
    Spectral radius of the loop's one-period map over a grid (see :mod:`drake_coop.stability`).
``drake-coop gains SCENARIO --out DIR [--force]``
    Each robot's gains derived from its controller model and checked with the stability map
    (see :mod:`drake_coop.stability.gains_cli`).
``drake-coop identify SCENARIO --out DIR [--robots 1,2] [--duration 10]``
    Identify each robot's dynamic parameters on the simulated true arm from encoder readings
    and commanded torques; write ``robotN_identified.urdf``, ``identify.json``,
    ``identify_fit.png`` and ``identified.yaml`` (see :mod:`drake_coop.identification.report`).
``drake-coop serve SCENARIO --lcm-url URL --out DIR`` / ``drake-coop sim-driver SCENARIO --lcm-url URL``
    The control blocks against the wall clock over each arm's LCM driver, with a watchdog and
    the pacing figures; the scenario's simulated arms behind the same messages (see
    :mod:`drake_coop.robot.cli`).

One module per command of this package (run, scenarios, plot, diagram, identify), the
signals (signals) and the parser with the entry point (parser); every name is imported from
here.
"""

from __future__ import annotations

from drake_coop.cli import signals as _signals
from drake_coop.cli.diagram import cmd_diagram
from drake_coop.cli.identify import cmd_identify
from drake_coop.cli.parser import build_parser, main
from drake_coop.cli.plot import cmd_plot
from drake_coop.cli.run import ProgressBar, cmd_run
from drake_coop.cli.scenarios import cmd_scenarios
from drake_coop.cli.signals import Signals, Terminated

__all__ = [
    "Terminated",
    "Signals",
    "ProgressBar",
    "cmd_run",
    "cmd_plot",
    "cmd_scenarios",
    "cmd_diagram",
    "cmd_identify",
    "build_parser",
    "main",
]


def __getattr__(name: str):
    # SIGNALS, the running command's: main replaces it at each call (drake_coop.cli.signals).
    if name == "SIGNALS":
        return _signals.SIGNALS
    raise AttributeError(f"module 'drake_coop.cli' has no attribute {name!r}")
