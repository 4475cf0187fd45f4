"""``drake-coop study``: run a study file, resume it, redraw its figures.

``drake-coop study STUDY.yaml --out DIR [--workers N] [--ray [ADDRESS]] [--max-cases N] [--max-workers N] [--quiet]``
    Check the study's size (at most ``--max-cases``, default 10 000), expand and validate
    every case as ``run`` would (exit 2 naming the field on a bad path or value), claim and
    lock ``DIR`` (:mod:`drake_coop.studies.folder`: new, empty or this study's folder), skip
    the cases already finished in ``DIR/cases/``, run the others (one fresh process each)
    with a progress bar, and write ``results.csv``, ``study.json`` and the figures.
    Exit codes: 0 every case finished (diverged cases are results, not failures); 1 after
    work: a case's process died (it runs again on the next resume), the engine failed, or
    writing failed (full disk); 2 bad input or an unusable ``DIR``, before any case ran;
    130 Ctrl-C, 143 SIGTERM (finished cases are kept; rerun to resume). A case's file and
    the tables that list it are written in one block no signal cuts, and the tables are
    written once more from the case files on disk when the run stops: ``results.csv`` lists
    every finished case as finished, whenever the study is stopped.
``drake-coop study STUDY.yaml --out DIR --stale rerun|keep``
    Resume a folder some of whose finished cases were computed by other code (another
    version of the package or of Drake, or written before cases carried a code stamp:
    :mod:`drake_coop.studies.code_stamp`). Without ``--stale`` such a resume is refused
    (exit 2, one line with the counts); ``rerun`` runs those cases again, replacing their
    files; ``keep`` keeps their numbers, says so at the start, and records their count in
    ``study.json`` (``stale_kept``): the results then mix code versions.
``drake-coop study STUDY.yaml --out DIR [--t-end S] [--draws N] [--cases N]``
    The study sized from the command line (:mod:`drake_coop.studies.size`): recorded in
    ``DIR``; a resume without these options keeps that size, one with another is refused.
``drake-coop study --plot DIR``
    Redraw the figures from ``DIR/study.json`` (exit 2 with one line if it is missing or
    damaged, or the folder is read-only).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
import threading
import time
from pathlib import Path

from drake_coop.console import error
from drake_coop.studies.code_stamp import STALE_CHOICES, reusable_records
from drake_coop.studies.expand import MAX_CASES, Case, expand
from drake_coop.studies.size import OPTIONS, apply_size, given_size, size_text
from drake_coop.studies.spec import StudyError, load_study
from drake_coop.studies.store import FINISHED, ResultStore, check_metric_names

__all__ = ["CaseProgress", "add_study_parser", "cmd_study"]


class Terminated(KeyboardInterrupt):
    """Raised by the SIGTERM handler: stop like Ctrl-C, exit 143."""


class CaseProgress:
    """Progress over cases on stderr: a bar with counts and ETA (a line per case off a tty).

    Parameters
    ----------
    total : int
        The study's cases.
    already : int
        Those finished in an earlier run.
    stream : file or None
        Where to draw; None for stderr.
    width : int
        The bar's width, characters.
    """

    def __init__(self, total: int, already: int, stream=None, width: int = 30):
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()
        self.total, self.already, self.width = total, already, width
        self.done, self.diverged = 0, 0
        self.start = time.perf_counter()

    def update(self, case: Case, record: dict) -> None:
        """Count one finished case and redraw.

        Parameters
        ----------
        case : Case
            The case finished.
        record : dict
            Its record (its ``status``).
        """
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
    return error(message, "drake-coop study")


#: Set by the signal handler: Ray's ``ray.wait`` turns any exception raised in a signal
#: handler into a plain KeyboardInterrupt, so the exit code is taken from this flag.
_SIGTERM_SEEN = False
#: Inside :func:`_writing` (a case's file and the tables being written) a signal is only
#: recorded here, and raised when the block ends.
_DEFER = 0
_PENDING: int | None = None


#: Set once a signal has been raised: the study is stopping, and a second signal (an
#: impatient Ctrl-C) is only recorded, so that it cannot cut the last tables.
_STOPPING = False


#: Where an exception raised by a signal handler is printed ("Exception ignored in ...") and
#: dropped by Python instead of propagating: an object's ``__del__`` and the finalizers that
#: ``weakref`` and ``multiprocessing.util`` run when an object is collected.
_FINALIZER_FILES = (os.path.join("multiprocessing", "util.py"), "weakref.py")


def _in_finalizer(frame) -> bool:
    """Whether ``frame`` (the one a signal interrupted) runs inside a finalizer."""
    while frame is not None:
        code = frame.f_code
        if code.co_name == "__del__" or (code.co_name in ("__call__", "_run_finalizers")
                                         and code.co_filename.endswith(_FINALIZER_FILES)):
            return True
        frame = frame.f_back
    return False


def _on_signal(signum, frame):
    global _SIGTERM_SEEN, _PENDING, _STOPPING
    _SIGTERM_SEEN = _SIGTERM_SEEN or signum == signal.SIGTERM
    if _DEFER or _STOPPING:
        _PENDING = _PENDING or signum
        return
    if _in_finalizer(frame):
        # Raised here, the stop would be printed and dropped, and the study would run on
        # (a case's process collected while the signal arrived did just that): the signal is
        # sent again once the finalizer has returned.
        threading.Timer(0.01, os.kill, (os.getpid(), signum)).start()
        return
    _STOPPING = True
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


@contextlib.contextmanager
def _writing(raise_pending: bool = True):
    """A block that a SIGINT/SIGTERM does not cut: a finished case's file and the tables
    that list it are written together (the signal is raised when the block ends, or left in
    :data:`_PENDING` with ``raise_pending=False``)."""
    global _DEFER, _PENDING, _STOPPING
    _DEFER += 1
    try:
        yield
    finally:
        _DEFER -= 1
    if raise_pending and not _DEFER and _PENDING is not None and not _STOPPING:
        signum, _PENDING, _STOPPING = _PENDING, None, True
        raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def _default_max_workers() -> int:
    return 4 * (os.cpu_count() or 1)


def _one_line(exc: BaseException) -> str:
    text = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return " ".join(str(text).split())[:300]


def _plot_only(args: argparse.Namespace) -> int:
    from drake_coop.studies.folder import StudyFolder, StudyFolderError
    from drake_coop.studies.plots import plot_study

    folder = StudyFolder(args.plot)
    try:
        folder.lock_existing()
        paths = plot_study(args.plot)
    except (StudyFolderError, FileNotFoundError, ValueError) as exc:
        return _error(_one_line(exc))
    except OSError as exc:
        return _error(f"--plot {args.plot}: writing the figures failed ({_one_line(exc)})")
    finally:
        folder.release()
    if not args.quiet:
        print(f"drake-coop study: wrote {len(paths)} figures to {args.plot}", file=sys.stderr)
    return 0


def cmd_study(args: argparse.Namespace) -> int:
    """The exit code of ``drake-coop study`` (see the module's docstring: 0 done, 1 a case
    died or writing failed, 2 bad input, 130/143 interrupted), after running (or resuming) a
    study, or redrawing its figures with ``--plot``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from drake_coop.studies.folder import StudyFolder, StudyFolderError

    if args.plot is not None:
        return _plot_only(args)
    if args.study is None or args.out is None:
        return _error("give a study file and --out DIR (or --plot DIR)")
    if args.max_cases < 1:
        return _error(f"--max-cases must be >= 1, got {args.max_cases}")
    max_workers = args.max_workers if args.max_workers is not None else _default_max_workers()
    if max_workers < 1:
        return _error(f"--max-workers must be >= 1, got {max_workers}")
    if not 1 <= args.workers <= max_workers:
        return _error(f"--workers must be between 1 and {max_workers} (4 per CPU; raise the "
                      f"bound on purpose with --max-workers), got {args.workers}")
    out = Path(args.out)
    folder = StudyFolder(out)
    try:
        study = load_study(args.study)
        given = given_size(args)
        ours = folder.owner() == study.name
        recorded = folder.recorded_size() if ours else None
        problem = _size_problem(out, given, recorded)
        if problem:
            return _error(problem)
        size = given if given or recorded is None else recorded
        study, first = apply_size(study, size)
        # A resume reads the reachability checks the folder stored: it checks nothing again.
        reach = folder.stored_reach() if ours else {}
        cases = expand(study, max_cases=args.max_cases, first=first, cache=reach)
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
    try:
        folder.claim(study.name)
    except StudyFolderError as exc:
        return _error(str(exc))
    try:
        problem = _size_problem(out, size, folder.recorded_size())   # again, under the lock
        if problem:
            return _error(problem)
        try:
            folder.record_size(study.name, size)
            folder.store_reach(reach)
        except OSError as exc:
            return _error(f"--out {out}: {_one_line(exc)}")
        if size and not given and not args.quiet:
            print(f"drake-coop study: resuming at the size recorded in {out}: "
                  f"{size_text(size)}", file=sys.stderr)
        return _run_study(args, study, cases, folder)
    finally:
        folder.release()


def _run_study(args, study, cases: list[Case], folder) -> int:
    from drake_coop.studies.plots import plot_study

    out = folder.out
    store = ResultStore(out)
    try:
        records = store.load()
        died = store.died()
    except OSError as exc:
        return _error(f"--out {out}: cannot read the finished cases ({_one_line(exc)})")
    try:
        records, stale = reusable_records(records, (c.hash for c in cases), store.stamp,
                                          args.stale, f"--out {out}")
    except ValueError as exc:
        return _error(str(exc))
    if not args.quiet:
        for warning in store.skipped[:20]:
            print(f"drake-coop study: warning: {warning}", file=sys.stderr)
        if len(store.skipped) > 20:
            print(f"drake-coop study: warning: {len(store.skipped) - 20} more damaged case "
                  "files skipped", file=sys.stderr)
    engine = "local" if args.ray is None else f"ray:{args.ray or 'local'}"
    todo, seen = [], set(records)
    for case in cases:
        if case.hash not in seen:
            todo.append(case)
            seen.add(case.hash)
    unique = len({c.hash for c in cases})
    retried = sum(c.hash in died for c in todo)
    try:
        store.write_tables(study, cases, records, engine, died)
    except OSError as exc:
        return _error(f"--out {out}: writing results.csv failed ({_one_line(exc)})")
    if not args.quiet:
        again = f" ({retried} again: their process died before)" if retried else ""
        if stale and args.stale == "keep":
            again += (f"; {stale} of the finished computed by other code, kept (--stale "
                      "keep): the results mix code versions")
        elif stale:
            again += f"; {stale} computed by other code run again (--stale rerun)"
        print(f"drake-coop study: {study.name}: {len(cases)} cases ({unique} distinct), "
              f"{unique - len(todo)} already finished, running {len(todo)}{again} on {engine} "
              f"({args.workers} workers) -> {out}", file=sys.stderr)
        warning = phase_warning(study, cases[0], folder.stored_reach()) if todo else ""
        if warning:
            print(f"drake-coop study: warning: {warning}", file=sys.stderr)
    progress = None if args.quiet else CaseProgress(unique, unique - len(todo))
    lost: list[str] = []

    def on_result(case: Case, result: dict) -> None:
        if result["status"] == "interrupted":
            return
        with _writing():
            if result["status"] not in FINISHED:          # its process died: not a result
                message = f"{result['message']}; it runs again on the next resume"
                died[case.hash] = message
                lost.append(case.hash)
                store.mark_died(case, message)
                if not args.quiet:
                    print(f"\ndrake-coop study: case {case.index}: {message}", file=sys.stderr)
            else:
                records[case.hash] = store.save(case, result, study.t_end)
                died.pop(case.hash, None)
                if progress is not None:
                    progress.update(case, result)
            store.write_tables(study, cases, records, engine, died)

    global _SIGTERM_SEEN, _PENDING, _STOPPING
    _SIGTERM_SEEN, _PENDING, _STOPPING = False, None, False
    previous = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    code = 0
    started = time.perf_counter()
    try:
        try:
            if args.ray is None:
                from drake_coop.studies.engines import run_local
                run_local(todo, study.t_end, on_result, workers=args.workers)
            else:
                from drake_coop.studies.engines import run_ray
                run_ray(todo, study.t_end, on_result, address=args.ray or None,
                        workers=args.workers)
        except KeyboardInterrupt as exc:
            # this module's handler, or drake_coop.cli's before it was installed
            code = 143 if type(exc).__name__ == "Terminated" or _SIGTERM_SEEN else 130
        except OSError as exc:        # writing a case or a table failed (full disk, read-only)
            print(f"\ndrake-coop study: writing to --out {out} failed ({_one_line(exc)}); the "
                  "cases finished before are kept; free the space and run again to resume",
                  file=sys.stderr)
            code = 1
        except Exception as exc:      # the engine itself failed (Ray down)
            print(f"\ndrake-coop study: engine failed: {type(exc).__name__}: "
                  f"{_one_line(exc)}", file=sys.stderr)
            code = 1
        elapsed = time.perf_counter() - started
        # The tables once more, from every case file on disk (one saved as the run was cut
        # is listed finished, never pending), not cut by a signal.
        try:
            with _writing(raise_pending=False):
                for key, record in _reload(store).items():
                    if record.get("code") == store.stamp:    # not one left to run again
                        records.setdefault(key, record)
                store.write_tables(study, cases, records, engine, died)
        except OSError as exc:
            if code != 1:                 # not said already
                print(f"drake-coop study: writing results.csv to --out {out} failed "
                      f"({_one_line(exc)})", file=sys.stderr)
            return code or 1
        if _PENDING is not None and not code:     # a signal during the last tables
            code = 143 if _PENDING == signal.SIGTERM else 130
        _PENDING, _STOPPING = None, False
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    done = sum(c.hash in records for c in cases)
    if code:
        if code != 1:
            print(f"\ndrake-coop study: interrupted; {done} of {len(cases)} cases finished "
                  f"and kept in {out}; run the same command again to resume", file=sys.stderr)
        return code
    try:
        paths = plot_study(out)
    except (OSError, ValueError) as exc:
        print(f"drake-coop study: drawing the figures in {out} failed ({_one_line(exc)}); "
              f"`drake-coop study --plot {out}` redraws them", file=sys.stderr)
        paths, code = [], 1
    missing = [c for c in cases if c.hash not in records]
    if missing:
        print(f"drake-coop study: {len(missing)} of {len(cases)} cases did not finish (their "
              f"process died: killed or out of memory); run the same command again to "
              "retry them", file=sys.stderr)
        code = 1
    if not args.quiet:
        bad = sum(records[c.hash]["status"] != "ok" for c in cases if c.hash in records)
        print(f"drake-coop study: {done} cases finished ({bad} diverged or failed), "
              f"{len(todo)} run in {elapsed:.1f} s; wrote results.csv, study.json and "
              f"{len(paths)} figures to {out}", file=sys.stderr)
    return code


def _size_problem(out: Path, given: dict, recorded: dict | None) -> str | None:
    """The one-line refusal of a size other than the one ``out`` was run at, or None."""
    if recorded is None or not given or given == recorded:
        return None
    differ = [k for k in OPTIONS if given.get(k) != recorded.get(k)]
    key = next((k for k in differ if k in given), differ[0])
    return (f"{OPTIONS[key]}: --out {out} was run at {size_text(recorded)}; resume it at that "
            "size (the same options, or none), or choose another --out")


def _reload(store: ResultStore) -> dict[str, dict]:
    """The finished cases on disk ({} when they cannot be read: the tables keep what the run
    knew)."""
    try:
        return store.load()
    except OSError:
        return {}


def phase_warning(study, case: Case, cache: dict | None = None) -> str:
    """A warning when the study's ``t_end`` stops its cases before the phase it measures.

    Parameters
    ----------
    study : Study
        The study (its ``phase`` and ``t_end``; None: the scenario's own).
    case : Case
        A case (its scenario's phase times).
    cache : dict or None
        The study's reachability checks (its folder's
        :meth:`~drake_coop.studies.folder.StudyFolder.stored_reach`): reading the case
        checks nothing the study already checked. None: checked again.

    Returns
    -------
    str
        One line, e.g. ``the cases stop at t_end = 5 s, before phase circle starts (25 s):
        ...; give --t-end > 25 ...``; ``''`` if the phase is reached.
    """
    from drake_coop.experiment.simulate import phases
    from drake_coop.scenario.loading import load_scenario

    if study.phase == "all" or study.t_end is None:
        return ""
    spans = {name: a for name, a, _ in phases(load_scenario(data=case.scenario_yaml,
                                                            cache=cache))}
    start = spans.get(study.phase)
    if start is None or study.t_end > start:
        return ""
    return (f"the cases stop at t_end = {study.t_end:g} s, before phase {study.phase} starts "
            f"({start:g} s): its metrics in results.csv and the plots will be empty; give "
            f"--t-end > {start:g} (or a study with an earlier phase)")


def _robot_names(case: Case) -> list[str]:
    """The robots' names of a case's scenario (validated when the case was built: read, not
    validated again)."""
    from pydrake.common.yaml import yaml_load

    return [r["name"] for r in yaml_load(data=case.scenario_yaml)["robots"]]


def add_study_parser(sub) -> None:
    """Register ``study`` on the ``drake-coop`` subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``drake-coop`` subparsers.
    """
    p = sub.add_parser("study", help="run a parameter study / Monte Carlo (or --plot DIR)")
    p.add_argument("study", nargs="?", default=None, help="study YAML (see studies/)")
    p.add_argument("--out", default=None, help="study folder: new or empty, or this study's "
                                                "(resumed)")
    p.add_argument("--workers", type=int, default=2, help="parallel processes (default 2)")
    p.add_argument("--max-cases", type=int, default=MAX_CASES, metavar="N",
                   help=f"refuse a study of more than N cases (default {MAX_CASES}); raise "
                        "it on purpose for a larger study")
    p.add_argument("--max-workers", type=int, default=None, metavar="N",
                   help="a bound, not a worker count: refuse --workers above N "
                        "(default 4 per CPU); --workers sets the count")
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help="run on Ray: a local instance, or the cluster at ADDRESS")
    p.add_argument("--t-end", type=float, default=None, metavar="S",
                   help="stop every case at S seconds (the study's t_end)")
    p.add_argument("--draws", type=int, default=None, metavar="N",
                   help="N Monte Carlo samples per grid point (the study's monte_carlo.n)")
    p.add_argument("--cases", type=int, default=None, metavar="N",
                   help="run only the first N cases (grid outer, samples inner); the size "
                        "given is recorded in --out, and a resume keeps it")
    p.add_argument("--stale", choices=STALE_CHOICES, default=None,
                   help="finished cases in --out computed by other code (another version, or "
                        "unstamped): run them again (rerun) or keep their numbers (keep); "
                        "default: refuse")
    p.add_argument("--plot", default=None, metavar="DIR", help="only redraw DIR's figures")
    p.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    p.set_defaults(func=cmd_study)
