"""Running the reference table: batches of cases per worker process, locally or on Ray.

``drake-coop reference-table --out DIR [--draws N] [--rows ...] [--columns ...] [--workers W]
[--ray [ADDRESS]] [--t-end S]`` expands the table (:mod:`drake_coop.studies.reference_table`),
skips every case whose file is already in ``DIR/cases/`` (the study store,
:class:`~drake_coop.studies.store.ResultStore`: one atomic file per case, resumable), runs the
rest and writes ``DIR/table.json``, ``DIR/table.md`` (the squeeze error and the estimate's
error) and ``DIR/cases.csv`` (one row per case: its numbers and CPU seconds). A stored case
computed by other code (:mod:`~drake_coop.studies.code_stamp`) is not reused silently: the
resume is refused unless ``--stale rerun`` (run it again) or ``--stale keep`` (keep it;
``table.json`` then counts it in ``stale_kept``).

Per-worker reuse
----------------
A batch (up to ``--batch`` cases of one cell, in draw order) runs in one process: pydrake and
the package are imported once per batch (about 0.9 s of CPU, plus the process's start, against
1.3–1.7 s for an 8 s case), and on Ray once per worker, which takes batch after batch (no
``max_calls``). The diagram itself is rebuilt for every draw: each column's draw changes
arguments the systems are constructed with (the controller's model, the plant's friction, the
torque limits, the noise seeds that the sensor models hold); the rebuild costs about 0.04 s of
CPU per case (2–3 % of an 8 s case, measured by ``bench/reference_table.py --cost``).

A killed worker loses only its batch in flight: finished batches are saved as they arrive, a
batch whose process died is noted (``cases/<hash>.died``) and runs again on the next resume.
The same seeds give the same numbers: every random value is a function of the table's seed,
the column and the draw (:func:`~drake_coop.studies.reference_table.expand_table`), and the
simulation is deterministic.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import sys
import time
from pathlib import Path

from drake_coop.results.io import atomic_write_text
from drake_coop.studies.code_stamp import (
    STALE_CHOICES,
    check_stale_choice,
    code_stamp,
    count_stale,
    reusable_records,
)
from drake_coop.studies.expand import Case
from drake_coop.studies.reference_table import (
    ALL_COLUMNS,
    ALL_ROWS,
    COLUMNS,
    FRICTION_COLUMNS,
    IDENTIFIED,
    OPTIONAL_ROWS,
    ROWS,
    T_SHORT,
    base_scenario,
    cell_statistics,
    check_optional_rows,
    default_columns,
    expand_table,
    identified_name,
    markdown_table,
    per_draw,
    torque_peaks,
)
from drake_coop.studies.store import FINISHED, ResultStore

__all__ = ["add_reference_table_parser", "calibrate", "identify_columns", "identify_task",
           "run_batch", "run_table", "write_table"]


class Batch:
    """Cases run one after another in one worker process.

    Parameters
    ----------
    cases : list of Case
        The cases (one cell's draws).
    """

    def __init__(self, cases: list[Case]):
        self.cases = cases
        self.hash = cases[0].hash
        self.index = cases[0].index


def run_batch(items: list[tuple], t_end: float) -> list[tuple[str, dict]]:
    """Run cases one after another in this process; each record gets its CPU seconds.

    Parameters
    ----------
    items : list of tuple
        ``(hash, scenario YAML)`` or ``(hash, scenario YAML, variant)`` of each case (the
        variant: :mod:`~drake_coop.studies.reference_variants`).
    t_end : float
        The cases' end, s.

    Returns
    -------
    list of (str, dict)
        ``(hash, record)`` per case (:func:`~drake_coop.studies.engines.run_case`'s record
        with ``cpu_time_s``).
    """
    from drake_coop.studies.reference_variants import run_variant_case

    out = []
    for key, text, *variant in items:
        start = time.process_time()
        record = run_variant_case(text, t_end, variant[0] if variant else None)
        record["cpu_time_s"] = time.process_time() - start
        out.append((key, record))
    return out


def _batch_died(message: str) -> list:
    return [("", {"status": "died", "message": message})]


def calibrate(out: Path, base, t_end: float) -> dict:
    """The saturation column's peaks: the exact model with observer (22), run once and kept
    in ``out/calibration.json`` (read back on a resume); on a base in ``contact`` mode each
    robot's also carries ``need``, the torque the grasp check needs per joint
    (:func:`~drake_coop.experiment.squeeze_check.required_torques`).

    Parameters
    ----------
    out : Path
        The table's folder.
    base : Scenario
        The base scenario.
    t_end : float
        The cases' end, s.

    Returns
    -------
    dict
        :func:`~drake_coop.studies.reference_table.torque_peaks` of that run.
    """
    from drake_coop.studies.reference_table import compress

    path = out / "calibration.json"
    write = not path.exists()
    if not write:
        peaks = json.loads(path.read_text())["peaks"]
    else:
        from drake_coop.experiment.simulate import simulate

        result = simulate(compress(base), t_end=t_end)
        if not result.ok:
            raise RuntimeError(f"the calibration run (exact model) did not complete: "
                               f"{result.meta['message']}")
        peaks = torque_peaks(result.logs, result.meta)
    if base.plant.object_mode == "contact" and any("need" not in p for p in peaks.values()):
        # the box held by friction: what the grasp check needs (a floor of the limits)
        from drake_coop.experiment.plan import plan_run
        from drake_coop.experiment.squeeze_check import required_torques

        for robot, need in required_torques(plan_run(compress(base), t_end)).items():
            peaks[robot]["need"] = need
        write = True
    if write:
        atomic_write_text(path, json.dumps({"t_end": t_end, "peaks": peaks}, indent=1) + "\n")
    return peaks


def identify_task(scenario_yaml: str, folder: str, estimator: str, duration: float,
                  seed: int) -> dict:
    """Identify every arm of one draw; write the URDFs and ``models.json`` in ``folder``.

    Parameters
    ----------
    scenario_yaml : str
        The draw's scenario (its controller models are the prior).
    folder : str
        Where the identified URDFs go.
    estimator : str
        ``map_sdp``, ``idim_iv`` or ``didim``.
    duration : float
        The excitation's length, s.
    seed : int
        The excitation's seed.

    Returns
    -------
    dict
        Robot name -> its identified URDF (absolute path), or ``{"error": message}``.
    """
    from drake_coop.identification.report import identify_robot
    from drake_coop.scenario.loading import load_scenario

    scenario = load_scenario(data=scenario_yaml)
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    models = {}
    try:
        for i, robot in enumerate(scenario.robots):
            ident = identify_robot(scenario, i, duration, seed=seed, estimator=estimator)
            path = out / f"{ident.name}_identified.urdf"
            atomic_write_text(path, ident.urdf_text)
            models[robot.name] = str(path.resolve())
    except Exception as exc:                       # a result: the column's draw is missing
        return {"error": f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"}
    atomic_write_text(out / "models.json", json.dumps(models) + "\n")
    return models


class _Task:
    """One identification (a column's draw), as the engines take it."""

    def __init__(self, key: tuple, args: tuple):
        self.key, self.args = key, args
        self.hash = f"{key[0]}_{key[1]}"
        self.index = key[1]


def identify_columns(out: Path, base, cols: list[str], draws: int, seed: int, *,
                     workers: int, ray: str | None, quiet: bool) -> dict:
    """The identified columns' models, identified once per column and draw and kept in
    ``out/identified/<column>/<draw>/`` (a resume reads them back).

    Parameters
    ----------
    out : Path
        The table's folder.
    base : Scenario
        The base scenario.
    cols : list of str
        The identified columns.
    draws : int
        Draws per cell.
    seed : int
        The draws' seed.
    workers : int
        Parallel processes.
    ray : str or None
        As :func:`run_table`'s.
    quiet : bool
        No progress messages.

    Returns
    -------
    dict
        ``models[(column, draw)][robot]``: the URDF's path.

    Raises
    ------
    RuntimeError
        An identification failed (its message).
    """
    import numpy as np

    from drake_coop.scenario.loading import dump_scenario
    from drake_coop.studies.reference_table import _encoders, _model_30, compress

    spec = {identified_name(m, b): (m, b) for m, b in IDENTIFIED}
    k = list(ALL_COLUMNS).index("model_30")
    k_enc = list(ALL_COLUMNS).index("encoders")
    models, tasks = {}, []
    for col in cols:
        for draw in range(draws):
            folder = out / "identified" / col / str(draw)
            if (folder / "models.json").is_file():
                models[(col, draw)] = json.loads((folder / "models.json").read_text())
                continue
            s = compress(base)
            _model_30(s, np.random.default_rng([seed, k, draw]), draw)
            # the excitation read as the encoders column's draw reads the arm
            _encoders(s, np.random.default_rng([seed, k_enc, draw]), draw)
            tasks.append(_Task((col, draw), (dump_scenario(s), str(folder), *spec[col],
                                             draw)))
    failed = []

    def on_result(task: _Task, result: dict) -> None:
        if "error" in result:
            failed.append(f"{task.key[0]} draw {task.key[1]}: {result['error']}")
        else:
            models[task.key] = result
        if not quiet:
            print(f"reference table: identified {len(models)} of {len(cols) * draws}",
                  file=sys.stderr)

    if tasks:
        _run(tasks, identify_task, lambda t: t.args, on_result,
             lambda message: {"error": message}, ray=ray, workers=workers)
    if failed:
        raise RuntimeError(f"identification failed: {failed[0]}")
    return models


def _run(tasks: list, work, args_of, on_result, on_death, *, ray: str | None,
         workers: int) -> None:
    if ray is None:
        from drake_coop.studies.engines import run_in_processes

        run_in_processes(tasks, work, args_of, on_result, on_death, workers=workers)
    else:
        _run_ray(tasks, work, args_of, on_result, on_death, address=ray or None,
                 workers=workers)


def _batches(cases: list[Case], size: int) -> list[Batch]:
    cells: dict = {}
    for case in cases:
        cells.setdefault((case.params["row"], case.params["column"]), []).append(case)
    out = []
    for group in cells.values():
        out += [Batch(group[i:i + size]) for i in range(0, len(group), size)]
    return out


def run_table(out: str | Path, *, rows: list[str] | None = None,
              cols: list[str] | None = None, draws: int = 20, seed: int = 1,
              t_end: float = T_SHORT, workers: int = 2, ray: str | None = None,
              batch: int = 5, base: str | None = None, quiet: bool = False,
              stale: str | None = None) -> dict:
    """Run (or resume) the table into ``out`` and write its tables.

    Parameters
    ----------
    out : str or Path
        The table's folder (new, or this table's: resumed).
    rows, cols : list of str or None
        Rows and columns; None for the default rows
        (:data:`~drake_coop.studies.reference_table.ROWS`, not the optional ones) and the base's
        default columns
        (:func:`~drake_coop.studies.reference_table.default_columns`: a base holding the box
        by friction takes the friction-held part's).
    draws : int
        Draws per cell.
    seed : int
        The draws' seed.
    t_end : float
        Every case's end, s.
    workers : int
        Parallel processes (local) or CPUs of a local Ray instance.
    ray : str or None
        None: local processes; ``""``: a local Ray instance; else a Ray cluster's address.
    batch : int
        Cases per batch (one process, or one Ray task).
    base : str or None
        Base scenario file; None for the paper's.
    quiet : bool
        No progress messages.
    stale : str or None
        Stored cases of this table computed by other code, or carrying no code stamp:
        None refuses (ValueError, before any case runs), ``"rerun"`` runs them again,
        ``"keep"`` keeps their numbers (the command's ``--stale``;
        :func:`~drake_coop.studies.code_stamp.reusable_records`).

    Returns
    -------
    dict
        The table (:func:`write_table`), with ``"missing"``: the cases not finished,
        ``"errored"``: those whose record is an error, and ``"diverged"``: how many cases
        diverged or were stopped by a failure guard.
    """
    out = Path(out)
    rows = list(rows or [r.name for r in ROWS])
    scenario = base_scenario(base)
    cols = list(cols or default_columns(scenario))
    if batch < 1 or workers < 1:
        raise ValueError(f"batch and workers: must be >= 1, got {batch} and {workers}")
    for given, known, what in ((rows, [r.name for r in ALL_ROWS], "rows"),
                               (cols, list(ALL_COLUMNS), "columns")):
        for name in given:
            if name not in known:
                raise ValueError(f"{what}: unknown name {name!r}; allowed: {', '.join(known)}")
    check_optional_rows(rows, cols)
    if isinstance(draws, bool) or not isinstance(draws, int) or draws < 1:
        raise ValueError(f"draws: must be an integer >= 1, got {draws!r}")
    check_stale_choice(stale)
    out.mkdir(parents=True, exist_ok=True)
    peaks = calibrate(out, scenario, t_end) if "saturation" in cols else None
    id_cols = [c for c in cols if c.startswith("id_")]
    models = (identify_columns(out, scenario, id_cols, draws, seed, workers=workers, ray=ray,
                               quiet=quiet) if id_cols else None)
    cases = expand_table(scenario, rows, cols, draws, seed=seed, t_end=t_end, peaks=peaks,
                         models=models)
    store = ResultStore(out)
    records, n_stale = reusable_records(store.load(), (c.hash for c in cases), store.stamp,
                                        stale, f"--out {out}")
    todo, queued = [], set()       # a case two rows share (the applied-torque residual
    for c in cases:                # without torque limits is the momentum row's): once
        if c.hash not in records and c.hash not in queued:
            queued.add(c.hash)
            todo.append(c)
    if not quiet:
        said = ""
        if n_stale:
            said = (f" ({n_stale} computed by other code, kept: the table mixes code versions)"
                    if stale == "keep" else f"; {n_stale} computed by other code run again")
        print(f"reference table: {len(cases)} cases, {len(cases) - len(todo)} already "
              f"finished{said}, running {len(todo)} -> {out}", file=sys.stderr)

    def on_result(batch_: Batch, results: list) -> None:
        by_hash = {c.hash: c for c in batch_.cases}
        for key, record in results:
            if record["status"] not in FINISHED:
                for case in batch_.cases:
                    if case.hash not in records:
                        store.mark_died(case, record["message"])
                continue
            records[key] = store.save(by_hash[key], record, t_end)
        if not quiet:
            print(f"reference table: {sum(c.hash in records for c in cases)} of {len(cases)}",
                  file=sys.stderr)

    _run(_batches(todo, batch), run_batch,
         lambda b: ([(c.hash, c.scenario_yaml, c.values["variant"]) for c in b.cases],
                    t_end), on_result,
         _batch_died, ray=ray, workers=workers)
    table = write_table(out, cases, records, rows, cols, store.stamp)
    table["missing"] = [c.hash for c in cases if c.hash not in records]
    status = {c.hash: records[c.hash]["status"] for c in cases if c.hash in records}
    table["errored"] = [c.hash for c in cases if status.get(c.hash) == "error"]
    table["diverged"] = sum(status.get(c.hash) in ("diverged", "failed") for c in cases)
    return table


def _run_ray(tasks: list, work, args_of, on_result, on_death, *, address: str | None,
             workers: int) -> None:
    """The tasks as Ray tasks (workers reused across tasks); a failed task gives
    ``on_death(message)``, which is not saved."""
    import ray

    started = not ray.is_initialized()
    if started:
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                     configure_logging=False)
        else:
            ray.init(address=address, log_to_driver=False, configure_logging=False)
    remote = ray.remote(num_cpus=1, max_retries=0)(work)
    refs = {remote.remote(*args_of(t)): t for t in tasks}
    pending = list(refs)
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                try:
                    result = ray.get(ref)
                except (ray.exceptions.RayError, OSError) as exc:
                    result = on_death(f"its Ray task failed: {type(exc).__name__}")
                on_result(refs[ref], result)
    finally:
        if started:
            ray.shutdown()


def write_table(out: Path, cases: list[Case], records: dict, rows: list[str],
                cols: list[str], stamp: str | None = None) -> dict:
    """``table.json``, ``table.md`` and ``cases.csv`` from the finished records.

    Parameters
    ----------
    out : Path
        The table's folder.
    cases : list of Case
        The table's cases.
    records : dict
        Hash -> finished record.
    rows, cols : list of str
        The table's rows and columns.
    stamp : str or None
        The running code's stamp; None:
        :func:`~drake_coop.studies.code_stamp.code_stamp`.

    Returns
    -------
    dict
        ``{"rows", "columns", "cells": {row: {column: statistics}}, "cpu_time_s",
        "code", "stale_kept"}``: ``stale_kept`` counts the distinct cases whose record
        other code wrote (or that carry no stamp), kept by ``--stale keep``.
    """
    stamp = stamp or code_stamp()
    cells: dict = {}
    for row in rows:
        for col in cols:
            done = [records[c.hash] for c in cases if c.params["row"] == row
                    and c.params["column"] == col and c.hash in records]
            if done:
                cells.setdefault(row, {})[col] = cell_statistics(done)
    cpu = [records[c.hash].get("cpu_time_s") for c in cases if c.hash in records]
    cpu = [v for v in cpu if v is not None]
    table = {"rows": rows, "columns": cols, "cells": cells,
             "cases": len(cases), "finished": sum(c.hash in records for c in cases),
             "code": stamp,
             "stale_kept": count_stale(records, (c.hash for c in cases), stamp),
             "cpu_time_s": {"sum": float(sum(cpu)), "per_case_mean":
                            float(sum(cpu) / len(cpu)) if cpu else None}}
    atomic_write_text(out / "table.json", json.dumps(table, indent=1) + "\n")
    text = ("## Squeeze error λ − λ_d, circle RMS, worst robot (N): median [95 %] / "
            "p90 [95 %]\n\n" + markdown_table(table, "squeeze")
            + "\n\n## Estimate error λ̂ − λ, circle RMS, worst robot (N)\n\n"
            + markdown_table(table, "estimate") + "\n")
    atomic_write_text(out / "table.md", text)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["row", "column", "draw", "hash", "status", "squeeze", "estimate",
                     "cpu_time_s"])
    for c in cases:
        r = records.get(c.hash)
        v = per_draw(r) if r else {}
        writer.writerow([c.params["row"], c.params["column"], c.params["draw"], c.hash,
                         r["status"] if r else "pending", v.get("squeeze", ""),
                         v.get("estimate", ""), r.get("cpu_time_s", "") if r else ""])
    atomic_write_text(out / "cases.csv", buffer.getvalue())
    return table


def cmd_reference_table(args: argparse.Namespace) -> int:
    """``drake-coop reference-table``: run or resume the table.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        0 every case finished: a diverged (or guard-stopped) draw is data, counted in its
        cell, and the summary line says how many; 1 cases did not finish (a worker died:
        the same command resumes them) or ended in an error (a case that could not be built
        or run), said in one line, or the calibration or an identification failed; 2 bad
        input. As ``drake-coop study``, whose diverged cases are results too.
    """
    def split(text):
        return [s for s in text.split(",") if s] if text else None

    try:
        table = run_table(args.out, rows=split(args.rows), cols=split(args.columns),
                          draws=args.draws, seed=args.seed, t_end=args.t_end,
                          workers=args.workers, ray=args.ray, batch=args.batch,
                          base=args.base, quiet=args.quiet, stale=args.stale)
    except ValueError as exc:
        print(f"drake-coop reference-table: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except RuntimeError as exc:            # the calibration or an identification failed
        print(f"drake-coop reference-table: {' '.join(str(exc).split())}", file=sys.stderr)
        return 1
    if not args.quiet:
        print((Path(args.out) / "table.md").read_text())
        print(f"drake-coop reference-table: {table['finished']} of {table['cases']} cases "
              f"finished, {table['diverged']} of them diverged (counted in their cells)",
              file=sys.stderr)
    missing, errored = len(table["missing"]), len(table["errored"])
    if missing or errored:
        what = [f"{missing} did not finish (a worker died)"] if missing else []
        what += [f"{errored} ended in an error (their records in {Path(args.out) / 'cases'} "
                 "say why)"] if errored else []
        print(f"drake-coop reference-table: of {table['cases']} cases {' and '.join(what)}; "
              "run the same command again to resume the unfinished ones", file=sys.stderr)
        return 1
    return 0


def add_reference_table_parser(sub) -> None:
    """Register ``reference-table`` on the ``drake-coop`` subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``drake-coop`` subparsers.
    """
    p = sub.add_parser("reference-table", help="force sources x error sources on the short "
                                               "segment (resumable)")
    p.add_argument("--out", required=True, help="the table's folder (resumed if it exists)")
    p.add_argument("--draws", type=int, default=20, help="paired draws per cell (default 20)")
    p.add_argument("--rows", default=None, help="comma-separated rows (default: "
                   + ",".join(r.name for r in ROWS) + "; also "
                   + ",".join(r.name for r in OPTIONAL_ROWS) + ")")
    p.add_argument("--columns", default=None, help="comma-separated columns (default: "
                   + ",".join(COLUMNS) + "; on a base in contact mode "
                   + ",".join(FRICTION_COLUMNS) + "; also " + ",".join(
                       c for c in ALL_COLUMNS if c not in COLUMNS) + ")")
    p.add_argument("--seed", type=int, default=1, help="the draws' seed (default 1)")
    p.add_argument("--t-end", type=float, default=T_SHORT, metavar="S",
                   help=f"every case's end (default {T_SHORT:g} s)")
    p.add_argument("--workers", type=int, default=2, help="parallel processes (default 2)")
    p.add_argument("--batch", type=int, default=5, help="cases per process / Ray task")
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help="run on Ray: a local instance, or the cluster at ADDRESS")
    p.add_argument("--base", default=None, help="base scenario file (default: the paper's)")
    p.add_argument("--stale", choices=STALE_CHOICES, default=None,
                   help="stored cases computed by other code (another version, or "
                        "unstamped): run them again (rerun) or keep their numbers (keep); "
                        "default: refuse")
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_reference_table)
