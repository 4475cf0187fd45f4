"""``drake-coop run``: simulate an experiment and write its outputs (logs, metrics, figures,
diagrams, the replay), with a progress bar."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from drake_coop.cli import signals as _signals
from drake_coop.cli.diagram import _write_block_diagrams
from drake_coop.console import error as _error
from drake_coop.scenario.resources import find_scenario


class ProgressBar:
    """A one-line progress bar on stderr: simulated time and realtime factor.

    Parameters
    ----------
    stream : file-like, optional
        Where the bar is written (default: ``sys.stderr``); a terminal gets a bar
        redrawn in place, anything else one line every 10 %.
    width : int
        The bar's length in characters (on a terminal).
    """

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


def cmd_run(args: argparse.Namespace) -> int:
    """The exit code of ``drake-coop run`` (0 completed, 1 diverged, 2 bad input or outputs not
    written, 130/143 interrupted), after simulating and writing logs, metrics, figures,
    diagrams and the replay.

    Everything before the simulation (imports, scenario, model files, run size, ``--out``)
    runs with signals deferred; the outputs are written into a staging folder that is renamed
    onto ``--out`` at the end, also with signals deferred (see :func:`_write_outputs`).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (:func:`build_parser`).
    """
    with _signals.SIGNALS.deferred():
        from drake_coop.experiment.simulate import simulate
        from drake_coop.results.export import MeshcatReplay, add_meshcat, live_meshcat
        from drake_coop.results.run_folder import OutputFolderError, RunFolder
        from drake_coop.results.viz import add_force_arrows, frame_workspace
        from drake_coop.scenario.loading import load_scenario
        from drake_coop.scenario.schema import ScenarioError
        from drake_coop.experiment.ticks import check_run_size, run_size

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
        if _signals.SIGNALS.received is not None:
            print(f"drake-coop: interrupted ({_signals.SIGNALS.name}) before the simulation started",
                  file=sys.stderr)
            return _signals.SIGNALS.exit_code()
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
                              hold_signals=_signals.SIGNALS.deferred)
        except ScenarioError as exc:      # refused before the run (a squeeze beyond limits)
            return _error(str(exc))
        if progress is not None:
            progress.close()
        if result.meta["status"] == "interrupted":
            result.meta["signal"] = _signals.SIGNALS.name
        with _signals.SIGNALS.deferred():
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
    if result.meta["status"] == "interrupted" or _signals.SIGNALS.received is not None:
        print(f"drake-coop: {result.meta['message']} ({_signals.SIGNALS.name}; logs up to the stop "
              f"are in {out})", file=sys.stderr)
        return _signals.SIGNALS.exit_code()
    if not result.ok:
        print(f"drake-coop: {result.meta['message']} (logs up to the stop are in {out})",
              file=sys.stderr)
        return 1
    return 0


def _print_summary(result, metrics: dict) -> None:
    """The circle phase's errors per robot (stdout) and failed sanity checks (stderr), printed
    even with ``--quiet``: they are the run's result (:mod:`drake_coop.results.summary`)."""
    from drake_coop.results.summary import sanity_warnings, summary_lines

    lines = summary_lines(metrics, result.meta, result.logs)
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
    signals_before = _signals.SIGNALS.count
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
        if _signals.SIGNALS.count > signals_before:
            skipped.append(name)
            continue
        write()
    if skipped:
        meta["outputs_incomplete"] = (
            f"{', '.join(skipped)} skipped after {_signals.SIGNALS.name} while writing; "
            f"`drake-coop plot {args.out}` redraws the figures")
        write_meta(staging, meta)
    return metrics
