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
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import time
import warnings
from pathlib import Path

from drake_coop.console import error as _error
from drake_coop.scenario.resources import (
    find_scenario,
    scenario_summary,
    shipped_scenarios,
)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C's KeyboardInterrupt: the same code stops the run and keeps
    what was logged."""


class Signals:
    """SIGINT and SIGTERM of the command: raised as :class:`KeyboardInterrupt` /
    :class:`Terminated`, or only recorded inside :meth:`deferred` (start-up, writing)."""

    EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}

    def __init__(self):
        self.received: int | None = None
        self.count = 0
        self._defer = 0

    def handler(self, signum, frame) -> None:
        """The signal handler: record, then raise unless deferred."""
        self.count += 1
        if self.received is None:
            self.received = signum
        if not self._defer:
            raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()

    @contextlib.contextmanager
    def deferred(self):
        """Signals inside the block are recorded only (see :attr:`received`)."""
        self._defer += 1
        try:
            yield self
        finally:
            self._defer -= 1

    def exit_code(self, exc: BaseException | None = None) -> int:
        """130 for SIGINT, 143 for SIGTERM."""
        if isinstance(exc, Terminated):
            return 143
        return self.EXIT_CODES.get(self.received, 130)

    @property
    def name(self) -> str:
        return "SIGTERM" if self.received == signal.SIGTERM else "Ctrl-C"


#: The signals of the running command (installed by :func:`main`).
SIGNALS = Signals()


class ProgressBar:
    """A one-line progress bar on stderr: simulated time and realtime factor."""

    def __init__(self, stream=None, width: int = 30):
        self.stream = stream or sys.stderr
        self.width = width
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self._last_report = -1
        self._open = False

    def __call__(self, t: float, t_end: float, wall: float) -> None:
        frac = min(1.0, t / t_end) if t_end > 0 else 1.0
        rtf = t / wall if wall > 0 else float("inf")
        if self.tty:
            filled = int(round(frac * self.width))
            bar = "#" * filled + "." * (self.width - filled)
            self.stream.write(f"\r[{bar}] {t:6.2f}/{t_end:g} s  realtime x{rtf:5.2f}")
            self._open = True
        else:  # a log file: one line every 10 %
            decile = int(frac * 10)
            if decile > self._last_report:
                self._last_report = decile
                self.stream.write(f"{t:6.2f}/{t_end:g} s  realtime x{rtf:.2f}\n")
        self.stream.flush()

    def close(self) -> None:
        """End the bar's line (on a terminal)."""
        if self._open:
            self.stream.write("\n")
            self.stream.flush()
            self._open = False


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


def cmd_run(args: argparse.Namespace) -> int:
    """Simulate, then write logs, metrics, figures, diagrams and the replay.

    Everything before the simulation (imports, scenario, model files, run size, ``--out``)
    runs with signals deferred; the outputs are written into a staging folder that is renamed
    onto ``--out`` at the end, also with signals deferred (see :func:`_write_outputs`).
    """
    with SIGNALS.deferred():
        from drake_coop.experiment.simulate import simulate
        from drake_coop.results.export import MeshcatReplay, add_meshcat, live_meshcat
        from drake_coop.results.run_folder import OutputFolderError, RunFolder
        from drake_coop.results.viz import add_force_arrows, frame_workspace
        from drake_coop.scenario.loading import load_scenario
        from drake_coop.scenario.schema import ScenarioError
        from drake_coop.experiment.plan import check_run_size, run_size

        if args.t_end is not None and not (0 < args.t_end < float("inf")):
            return _error(f"--t-end must be a finite number > 0, got {args.t_end}")
        if args.realtime_rate is not None and not (0 <= args.realtime_rate < float("inf")):
            return _error(f"--realtime-rate must be a finite number >= 0, got "
                          f"{args.realtime_rate}")
        try:
            scenario = load_scenario(args.scenario and find_scenario(args.scenario))
            check_run_size(scenario, args.t_end)
        except ScenarioError as exc:
            return _error(str(exc))
        folder = RunFolder(args.out)
        try:
            staging = folder.prepare(run_size(scenario, args.t_end)[0],
                                     robots=len(scenario.robots), replace=args.force)
        except OutputFolderError as exc:
            return _error(str(exc))
    try:
        if SIGNALS.received is not None:
            print(f"drake-coop: interrupted ({SIGNALS.name}) before the simulation started",
                  file=sys.stderr)
            return SIGNALS.exit_code()
        out = folder.out
        replay = None

        def before_build(builder, coop):
            nonlocal replay
            if args.meshcat:
                print(f"drake-coop: Meshcat live at {live_meshcat().web_url()}",
                      file=sys.stderr, flush=True)
            if not args.no_replay:
                replay = MeshcatReplay.add_to_builder(builder, coop.scene_graph,
                                                      live=args.meshcat)
            if args.meshcat or replay is not None:
                meshcat = replay.meshcat if replay else add_meshcat(builder, coop.scene_graph)
                add_force_arrows(builder, coop, meshcat)
                frame_workspace(meshcat, [h.arm for h in coop.arms],
                                scenario.task.circle_top_z - scenario.task.circle_radius)

        def on_start(experiment, simulator):
            if replay is not None:
                replay.start()
            rate = args.realtime_rate if args.realtime_rate is not None else float(args.meshcat)
            simulator.set_target_realtime_rate(rate)

        progress = None if args.quiet else ProgressBar()
        label = args.scenario or "the paper's scenario"
        if not args.quiet:
            print(f"drake-coop: simulating {label} ({scenario.plant.object_mode} mode, "
                  f"h = {scenario.control_period * 1e3:g} ms, plant step "
                  f"{scenario.plant.time_step * 1e3:g} ms) -> {out}", file=sys.stderr)
        try:
            result = simulate(scenario, t_end=args.t_end, progress=progress,
                              before_build=before_build, on_start=on_start,
                              hold_signals=SIGNALS.deferred)
        except ScenarioError as exc:      # refused before the run (a squeeze beyond limits)
            return _error(str(exc))
        if progress is not None:
            progress.close()
        if result.meta["status"] == "interrupted":
            result.meta["signal"] = SIGNALS.name
        with SIGNALS.deferred():
            started = time.perf_counter()
            try:
                metrics = _write_outputs(args, scenario, result, replay, staging)
                folder.commit()
            except OSError as exc:
                return _error(f"--out {out}: writing the outputs failed "
                              f"({exc.strerror or exc}); nothing was replaced")
    finally:
        folder.discard()
    if not args.quiet:
        print(f"drake-coop: {result.meta['message']}; simulated in {result.wall_time:.1f} s "
              f"(realtime x{result.meta['realtime_factor'] or 0:.2f}), outputs written in "
              f"{time.perf_counter() - started:.1f} s to {out}", file=sys.stderr)
    _print_summary(result, metrics)
    if result.meta.get("outputs_incomplete"):
        print(f"drake-coop: {result.meta['outputs_incomplete']}", file=sys.stderr)
    if result.meta["status"] == "interrupted" or SIGNALS.received is not None:
        print(f"drake-coop: {result.meta['message']} ({SIGNALS.name}; logs up to the stop "
              f"are in {out})", file=sys.stderr)
        return SIGNALS.exit_code()
    if not result.ok:
        print(f"drake-coop: {result.meta['message']} (logs up to the stop are in {out})",
              file=sys.stderr)
        return 1
    return 0


def _print_summary(result, metrics: dict) -> None:
    """The circle phase's errors per robot (stdout) and failed sanity checks (stderr), printed
    even with ``--quiet``: they are the run's result (:mod:`drake_coop.results.summary`)."""
    from drake_coop.results.summary import sanity_warnings, summary_lines

    lines = summary_lines(metrics, result.meta)
    print(f"drake-coop: {lines[0]}", *lines[1:], sep="\n", flush=True)
    for warning in sanity_warnings(result.logs):
        print(f"drake-coop: warning: {warning}", file=sys.stderr)


def _write_outputs(args, scenario, result, replay, staging: Path) -> dict:
    """Logs, ``run.json``, metrics, then figures, diagrams and the replay into ``staging``;
    returns the metrics.

    Runs with signals deferred: the logs, ``run.json`` and metrics are always written whole;
    a signal received meanwhile skips the figures, diagrams and replay still to come, and
    ``run.json`` then says so (``outputs_incomplete``).
    """
    from drake_coop.results import (
        compute_metrics,
        fig_references,
        plot_figures,
        save_logs,
        write_metrics,
    )
    from drake_coop.results.io import atomic_write_text
    from drake_coop.results.logs import write_meta
    from drake_coop.scenario.loading import dump_scenario

    meta = result.meta
    signals_before = SIGNALS.count
    atomic_write_text(staging / "scenario.yaml", dump_scenario(scenario))
    save_logs(staging, result.logs, meta)
    metrics = compute_metrics(result.logs, meta)
    write_metrics(staging, metrics)
    exp = result.experiment
    optional = [
        ("figures", lambda: plot_figures(result.logs, meta, staging)),
        ("reference figure", lambda: fig_references(result.logs, meta, staging)),
        ("diagrams", lambda: _write_block_diagrams(
            exp, staging, "system_diagram", f"{exp.robots[0].name}_control_diagram",
            args.quiet)),
    ]
    if replay is not None:
        optional.append(("replay", lambda: replay.finish(staging / "replay.html")))
    skipped = []
    for name, write in optional:
        if SIGNALS.count > signals_before:
            skipped.append(name)
            continue
        write()
    if skipped:
        meta["outputs_incomplete"] = (
            f"{', '.join(skipped)} skipped after {SIGNALS.name} while writing; "
            f"`drake-coop plot {args.out}` redraws the figures")
        write_meta(staging, meta)
    return metrics


def cmd_plot(args: argparse.Namespace) -> int:
    """Redraw figures and metrics from a run directory."""
    from drake_coop.results import replot

    try:
        paths = replot(Path(args.dir))
    except (OSError, ValueError) as exc:   # missing, unreadable, malformed; read-only folder
        return _error(str(exc))
    if not args.quiet:
        print(f"drake-coop: wrote {len(paths)} files to {args.dir}", file=sys.stderr)
    return 0


def cmd_scenarios(args: argparse.Namespace) -> int:
    """List the shipped scenarios, or print one."""
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


def cmd_diagram(args: argparse.Namespace) -> int:
    """Draw the experiment's block diagram (no loggers or visualizer) and one control block."""
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.schema import ScenarioError

    try:
        scenario = load_scenario(args.scenario and find_scenario(args.scenario))
    except ScenarioError as exc:
        return _error(str(exc))
    exp = build_experiment(scenario, log=False)
    written = _write_block_diagrams(exp, Path(args.out), "experiment",
                                    f"{exp.robots[0].name}_control", args.quiet)
    if not args.quiet:
        print("drake-coop: wrote " + ", ".join(map(str, written)), file=sys.stderr)
    return 0


def cmd_identify(args: argparse.Namespace) -> int:
    """Identify the scenario's robots and write DIR (exit 2 on bad input, one line)."""
    import math

    from drake_coop.identification.report import (
        IdentifyInputError,
        parse_robots,
        run_identify,
    )
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.schema import ScenarioError

    if not math.isfinite(args.duration):
        return _error(f"--duration must be a finite number of seconds, got {args.duration}")
    try:
        scenario = load_scenario(find_scenario(args.scenario))
        robots = parse_robots(args.robots, len(scenario.robots))
        report = run_identify(scenario, args.out, robots, args.duration, seed=args.seed,
                              log=(lambda *a: None) if args.quiet else
                              (lambda m: print(m, flush=True)))
    except (ScenarioError, IdentifyInputError) as exc:
        return _error(str(exc))
    except OSError as exc:                 # a full disk while writing: nothing was replaced
        _error(f"--out {args.out}: writing the outputs failed ({exc.strerror or exc}); "
               "nothing was replaced")
        return 1
    if not args.quiet:
        for name, r in report["robots"].items():
            v = r["validation"]
            share = v['torque_error_rms_identified'] / max(v['torque_rms'], 1e-300)
            print(f"{name}: model torque error {v['torque_error_rms_identified']:.3g} N·m RMS "
                  f"({100 * share:.2g} % of the torque RMS on fresh data; nominal model "
                  f"{v['torque_error_rms_nominal']:.3g}), base parameters "
                  f"{r['identifiable_combinations']}, residual "
                  f"{max(r['residual_torque_rms']):.3g} N·m, condition number "
                  f"{r['regressor_condition_number']:.3g}")
        print(f"wrote {args.out}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``drake-coop``."""
    parser = argparse.ArgumentParser(
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
    ident.add_argument("--quiet", action="store_true", help="no progress messages")
    ident.set_defaults(func=cmd_identify)
    from drake_coop.studies.cli import add_study_parser
    add_study_parser(sub)
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
    """
    global SIGNALS
    SIGNALS = Signals()
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


if __name__ == "__main__":
    sys.exit(main())
