"""``drake-coop study``: run a study file, resume it, redraw its figures.

``drake-coop study STUDY.yaml --out DIR [--workers N] [--ray [ADDRESS]] [--quiet]``
    Expand and validate every case (exit 2 naming the field on a bad path or value), skip the
    cases already finished in ``DIR/cases/``, run the others (one fresh process each) with a
    progress bar, and write ``results.csv``, ``study.json`` and the figures.
    Exit codes: 0 done (diverged cases are results, not failures), 1 the engine failed,
    2 bad input, 130 Ctrl-C, 143 SIGTERM (finished cases are kept; rerun to resume).
``drake-coop study --plot DIR``
    Redraw the figures from ``DIR/study.json``.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path

from drake_coop.studies.expand import Case, expand
from drake_coop.studies.spec import StudyError, load_study
from drake_coop.studies.store import ResultStore, check_metric_names

__all__ = ["CaseProgress", "add_study_parser", "cmd_study"]


class Terminated(KeyboardInterrupt):
    """Raised by the SIGTERM handler: stop like Ctrl-C, exit 143."""


class CaseProgress:
    """Progress over cases on stderr: a bar with counts and ETA (a line per case off a tty)."""

    def __init__(self, total: int, already: int, stream=None, width: int = 30):
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.total, self.already, self.width = total, already, width
        self.done, self.diverged = 0, 0
        self.start = time.perf_counter()

    def update(self, case: Case, record: dict) -> None:
        """Count one finished case and redraw."""
        self.done += 1
        self.diverged += record["status"] != "ok"
        finished = self.already + self.done
        elapsed = time.perf_counter() - self.start
        eta = elapsed / self.done * (self.total - finished)
        frac = finished / self.total if self.total else 1.0
        filled = int(round(frac * self.width))
        text = (f"{finished}/{self.total} cases, {self.diverged} not ok, elapsed "
                f"{_clock(elapsed)}, ETA {_clock(eta)}")
        if self.tty:
            self.stream.write(f"\r[{'#' * filled}{'.' * (self.width - filled)}] {text}")
            if finished == self.total:
                self.stream.write("\n")
        else:
            self.stream.write(f"{text}  (case {case.index}: {record['status']})\n")
        self.stream.flush()


def _clock(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


def _error(message: str) -> int:
    print(f"drake-coop study: error: {message}", file=sys.stderr)
    return 2


def _on_sigterm(signum, frame):
    raise Terminated()


def cmd_study(args: argparse.Namespace) -> int:
    """Run (or resume) a study, or redraw its figures with ``--plot``."""
    from drake_coop.studies.plots import plot_study

    if args.plot is not None:
        try:
            paths = plot_study(args.plot)
        except FileNotFoundError as exc:
            return _error(str(exc))
        if not args.quiet:
            print(f"drake-coop study: wrote {len(paths)} figures to {args.plot}",
                  file=sys.stderr)
        return 0
    if args.study is None or args.out is None:
        return _error("give a study file and --out DIR (or --plot DIR)")
    if args.workers < 1:
        return _error(f"--workers must be >= 1, got {args.workers}")
    try:
        study = load_study(args.study)
        cases = expand(study)
    except StudyError as exc:
        return _error(str(exc))
    robots = _robot_names(cases[0])
    problem = check_metric_names(study.metrics, robots)
    if problem:
        return _error(problem)
    if args.ray is not None:
        try:
            import ray  # noqa: F401
        except ImportError:
            return _error('--ray needs ray: pip install "drake_coop[ray]"')
    out = Path(args.out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        return _error(f"--out {out}: {exc.strerror}")
    store = ResultStore(out)
    records = store.load()
    engine = "local" if args.ray is None else f"ray:{args.ray or 'local'}"
    todo, seen = [], set(records)
    for case in cases:
        if case.hash not in seen:
            todo.append(case)
            seen.add(case.hash)
    unique = len({c.hash for c in cases})
    store.write_tables(study, cases, records, engine)
    if not args.quiet:
        print(f"drake-coop study: {study.name}: {len(cases)} cases ({unique} distinct), "
              f"{unique - len(todo)} already finished, running {len(todo)} on {engine} "
              f"({args.workers} workers) -> {out}", file=sys.stderr)
    progress = None if args.quiet else CaseProgress(unique, unique - len(todo))

    def on_result(case: Case, result: dict) -> None:
        if result["status"] == "interrupted":
            return
        records[case.hash] = store.save(case, result, study.t_end)
        store.write_tables(study, cases, records, engine)
        if progress is not None:
            progress.update(case, result)

    previous = signal.signal(signal.SIGTERM, _on_sigterm)
    code = 0
    started = time.perf_counter()
    try:
        if args.ray is None:
            from drake_coop.studies.engines import run_local
            run_local(todo, study.t_end, on_result, workers=args.workers)
        else:
            from drake_coop.studies.engines import run_ray
            run_ray(todo, study.t_end, on_result, address=args.ray or None,
                    workers=args.workers)
    except KeyboardInterrupt as exc:
        code = 143 if isinstance(exc, Terminated) else 130
    except Exception as exc:      # the engine itself failed (a worker crashed, Ray down)
        print(f"\ndrake-coop study: engine failed: {type(exc).__name__}: "
              f"{' '.join(str(exc).split())[:300]}", file=sys.stderr)
        code = 1
    finally:
        signal.signal(signal.SIGTERM, previous)
    elapsed = time.perf_counter() - started
    store.write_tables(study, cases, records, engine)
    done = sum(c.hash in records for c in cases)
    if code:
        if code != 1:
            print(f"\ndrake-coop study: interrupted; {done} of {len(cases)} cases finished "
                  f"and kept in {out}; run the same command again to resume", file=sys.stderr)
        return code
    paths = plot_study(out)
    if not args.quiet:
        bad = sum(records[c.hash]["status"] != "ok" for c in cases)
        print(f"drake-coop study: {done} cases finished ({bad} diverged or failed), "
              f"{len(todo)} run in {elapsed:.1f} s; wrote results.csv, study.json and "
              f"{len(paths)} figures to {out}", file=sys.stderr)
    return 0


def _robot_names(case: Case) -> list[str]:
    from drake_coop.scenario.loading import load_scenario

    return [r.name for r in load_scenario(data=case.scenario_yaml).robots]


def add_study_parser(sub) -> None:
    """Register ``study`` on the ``drake-coop`` subparsers."""
    p = sub.add_parser("study", help="run a parameter study / Monte Carlo (or --plot DIR)")
    p.add_argument("study", nargs="?", default=None, help="study YAML (see studies/)")
    p.add_argument("--out", default=None, help="study directory (resumed if it exists)")
    p.add_argument("--workers", type=int, default=2, help="parallel processes (default 2)")
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help="run on Ray: a local instance, or the cluster at ADDRESS")
    p.add_argument("--plot", default=None, metavar="DIR", help="only redraw DIR's figures")
    p.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    p.set_defaults(func=cmd_study)
