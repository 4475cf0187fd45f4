"""Command line: ``drake-coop run | plot | bench`` (also ``python -m drake_coop``).

``drake-coop run [SCENARIO.yaml] --out DIR``
    Simulate the experiment (the paper's without a scenario) and write to DIR: the logs
    (``robot1.npz``/``.csv``, ``robot2.*``, ``run.json``), ``metrics.json``, Figures 2–6 (PNG and
    SVG), the reference figure, the system diagram (``.dot``, ``.svg`` when graphviz is
    installed) and a self-contained Meshcat replay ``replay.html``.
    Exit codes: 0 done, 1 the run diverged (what was logged is still written), 2 bad input,
    130 interrupted with Ctrl-C (what was logged is still written).
``drake-coop plot DIR``
    Redraw the figures and metrics from the logs in DIR.
``drake-coop diagram [SCENARIO.yaml] [--out diagrams]``
    Draw the block diagram (top level, and robot 1's control block) without loggers.
``drake-coop bench``
    Realtime factor and cost per controller tick (see ``bench/benchmark.py``).
``drake-coop study STUDY.yaml --out DIR`` / ``drake-coop study --plot DIR``
    Parameter studies and Monte Carlo (see :mod:`drake_coop.studies.cli`).
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

from drake_coop.scenario import ScenarioError, dump_scenario, load_scenario


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


def _error(message: str) -> int:
    print(f"drake-coop: error: {message}", file=sys.stderr)
    return 2


def _write_block_diagrams(experiment, out: Path, top: str, control: str, quiet: bool
                          ) -> list[Path]:
    """The top-level diagram (one level deep) and robot 1's control block, .dot and .svg;
    a missing graphviz is reported once, as a note."""
    from drake_coop.results.export import write_diagram, write_subsystem_diagram

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        files = [write_diagram(experiment.diagram, out, top, max_depth=1),
                 write_subsystem_diagram(experiment.robots[0].control, out, control)]
    if caught and not quiet:
        print(f"drake-coop: note: {caught[0].message}", file=sys.stderr)
    return [p for f in files for p in f.values() if p is not None]


def cmd_run(args: argparse.Namespace) -> int:
    """Simulate, then write logs, metrics, figures, diagrams and the replay."""
    from drake_coop.results import (
        compute_metrics,
        fig_references,
        plot_figures,
        save_logs,
        write_metrics,
    )
    from drake_coop.results.export import MeshcatReplay
    from drake_coop.results.io import atomic_write_text
    from drake_coop.simulate import simulate

    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        return _error(str(exc))
    if args.t_end is not None and not (args.t_end > 0):
        return _error(f"--t-end must be > 0, got {args.t_end}")
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return _error(f"--out {out}: {exc.strerror}")

    replay = None

    def before_build(builder, coop):
        nonlocal replay
        if not args.no_replay:
            replay = MeshcatReplay.add_to_builder(builder, coop.scene_graph)

    def on_start(experiment, simulator):
        if replay is not None:
            replay.start()

    progress = None if args.quiet else ProgressBar()
    label = args.scenario or "the paper's scenario"
    if not args.quiet:
        print(f"drake-coop: simulating {label} ({scenario.plant.object_mode} mode, "
              f"h = {scenario.control_period * 1e3:g} ms, plant step "
              f"{scenario.plant.time_step * 1e3:g} ms) -> {out}", file=sys.stderr)
    result = simulate(scenario, t_end=args.t_end, progress=progress,
                      before_build=before_build, on_start=on_start)
    if progress is not None:
        progress.close()
    started = time.perf_counter()
    atomic_write_text(out / "scenario.yaml", dump_scenario(scenario))
    save_logs(out, result.logs, result.meta)
    write_metrics(out, compute_metrics(result.logs, result.meta))
    plot_figures(result.logs, result.meta, out)
    fig_references(result.logs, result.meta, out)
    exp = result.experiment
    _write_block_diagrams(exp, out, "system_diagram", f"{exp.robots[0].name}_control_diagram",
                          args.quiet)
    if replay is not None:
        replay.finish(out / "replay.html")
    if not args.quiet:
        print(f"drake-coop: {result.meta['message']}; simulated in {result.wall_time:.1f} s "
              f"(realtime x{result.meta['realtime_factor']:.2f}), outputs written in "
              f"{time.perf_counter() - started:.1f} s to {out}", file=sys.stderr)
    if not result.ok:
        print(f"drake-coop: {result.meta['message']} (logs up to the stop are in {out})",
              file=sys.stderr)
        return 130 if result.meta["status"] == "interrupted" else 1
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    """Redraw figures and metrics from a run directory."""
    from drake_coop.results import replot

    try:
        paths = replot(Path(args.dir))
    except (FileNotFoundError, ValueError) as exc:
        return _error(str(exc))
    if not args.quiet:
        print(f"drake-coop: wrote {len(paths)} files to {args.dir}", file=sys.stderr)
    return 0


def cmd_diagram(args: argparse.Namespace) -> int:
    """Draw the experiment's block diagram (no loggers or visualizer) and one control block."""
    from drake_coop.diagram import build_experiment

    try:
        scenario = load_scenario(args.scenario)
    except ScenarioError as exc:
        return _error(str(exc))
    exp = build_experiment(scenario, log=False)
    written = _write_block_diagrams(exp, Path(args.out), "experiment",
                                    f"{exp.robots[0].name}_control", args.quiet)
    if not args.quiet:
        print("drake-coop: wrote " + ", ".join(map(str, written)), file=sys.stderr)
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    """Run the benchmark (realtime factor, cost per tick)."""
    from drake_coop.bench import run_benchmark

    run_benchmark(t_end=args.t_end, repeats=args.repeats)
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``drake-coop``."""
    parser = argparse.ArgumentParser(
        prog="drake-coop",
        description="Cooperative two-arm position/force control without velocity or force "
                    "measurements (paper's Section IV) on Drake.")
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="simulate an experiment and write its outputs")
    run.add_argument("scenario", nargs="?", default=None,
                     help="scenario YAML (default: the paper's, scenarios/paper.yaml)")
    run.add_argument("--out", required=True, help="output directory")
    run.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    run.add_argument("--no-replay", action="store_true", help="skip the Meshcat HTML replay")
    run.add_argument("--t-end", type=float, default=None,
                     help="stop the simulation earlier (s)")
    run.set_defaults(func=cmd_run)
    plot = sub.add_parser("plot", help="redraw figures and metrics from a run directory")
    plot.add_argument("dir")
    plot.add_argument("--quiet", action="store_true")
    plot.set_defaults(func=cmd_plot)
    diagram = sub.add_parser("diagram", help="draw the block diagram (top level and robot 1's "
                                             "control block)")
    diagram.add_argument("scenario", nargs="?", default=None)
    diagram.add_argument("--out", default="diagrams")
    diagram.add_argument("--quiet", action="store_true")
    diagram.set_defaults(func=cmd_diagram)
    bench = sub.add_parser("bench", help="realtime factor and cost per controller tick")
    bench.add_argument("--t-end", type=float, default=90.0)
    bench.add_argument("--repeats", type=int, default=1)
    bench.set_defaults(func=cmd_bench)
    from drake_coop.studies.cli import add_study_parser
    add_study_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``drake-coop`` console script."""
    parser = build_parser()
    args = parser.parse_args(argv)
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
