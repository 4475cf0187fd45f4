"""Does the reference table's short segment rank the force sources as the full run does?

``python bench/reference_table.py --out DIR [--draws 6] [--workers 2]`` runs the short table
(``drake-coop reference-table``, 8 s: lift and grasp compressed, the first 3 s of the circle)
on the cells that shipped studies cover with the full task, and compares the order of the
sources' squeeze errors (median over the draws, worst robot, circle RMS of λ − λ_d):

* exact model (``docs/figures/studies/force_sensing_results.csv``, study 4, circle 25–65 s):
  observer (22), F/T sensor σ = 0.3 N and 3 N, none;
* ±30 % model (``docs/figures/studies/identified_sources.csv``, study 5's draws, circle to
  35 s, 12 draws): observer (22), momentum observer, F/T sensor (σ = 0 there, 0.3 N here),
  none.

For each pair of sources the verdict is ``agrees`` (the same order), ``tied`` (the orders
differ but the short run's 95 % intervals of the two medians overlap, or the full run's do),
or ``disagrees``. Writes ``DIR/agreement.json`` and prints the pairs. ``--cost`` prints instead
the CPU seconds per case of the finished cases in ``DIR`` and the extrapolated CPU and 2-core
wall time of the full 20-draw table; ``--table DIR`` writes the table of ``DIR``'s finished
cases at ``--draws`` to ``--out`` (nothing runs); ``--rerun DIR`` runs some finished cases
again and compares their numbers; ``--page JSON`` prints a table file's tables as Markdown
with ``{result}`` roles.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import math
from pathlib import Path

import numpy as np

from drake_coop.studies.reference_engine import run_table
from drake_coop.studies.reference_table import COLUMNS, ROWS, bootstrap_interval

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures" / "studies"


def full_exact() -> dict[str, list[float]]:
    """Study 4's worst-robot circle RMS per source (one run each: no interval)."""
    out = {}
    names = {("observer", 0.0): "observer", ("sensor", 0.3): "sensor_0p3",
             ("sensor", 3.0): "sensor_3", ("none", 0.0): "none"}
    for r in csv.DictReader(open(FIGURES / "force_sensing_results.csv")):
        key = (r["robots.*.force_source"], float(r["robots.*.force_sensor.noise_std"]))
        if key in names:
            v = float(r["worst.force_error.rms"])
            out[names[key]] = [v, v, v]
    return out


def full_model_30() -> dict[str, list[float]]:
    """Study 5's draws with the nominal models: median and its 95 % bootstrap interval."""
    rows = list(csv.DictReader(open(FIGURES / "identified_sources.csv")))
    names = {"observer": "observer", "momentum": "momentum", "sensor": "sensor_0p3",
             "none": "none"}
    return {ours: list(bootstrap_interval(np.array([float(r[theirs]) for r in rows]), 0.5))
            for theirs, ours in names.items()}


def verdicts(short: dict, full: dict) -> list[dict]:
    """Pairwise order of the medians, short against full (module docstring).

    Parameters
    ----------
    short, full : dict
        Source -> ``[median, low, high]``.

    Returns
    -------
    list of dict
        One entry per pair.
    """
    out = []
    for a, b in itertools.combinations(sorted(set(short) & set(full)), 2):
        s_order = short[a][0] < short[b][0]
        f_order = full[a][0] < full[b][0]
        overlap = (max(short[a][1], short[b][1]) <= min(short[a][2], short[b][2])
                   or max(full[a][1], full[b][1]) <= min(full[a][2], full[b][2]))
        verdict = "agrees" if s_order == f_order else ("tied" if overlap else "disagrees")
        out.append({"pair": [a, b], "short": [short[a], short[b]],
                    "full": [full[a], full[b]], "verdict": verdict})
    return out


def import_cpu() -> float:
    """CPU seconds of a fresh process importing what a batch imports (pydrake, the
    simulation): the per-batch overhead."""
    import resource
    import subprocess
    import sys

    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-c", "import drake_coop.studies.engines, "
                    "drake_coop.experiment.simulate, drake_coop.results.metrics"], check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def cost(folders: list[Path], draws: int = 20, batch: int = 5) -> dict:
    """CPU seconds per case (the finished cases of ``folders``) and the full table's CPU and
    two-core wall time at ``draws`` draws, batches of ``batch`` cases.

    The table's cases are counted as the command runs them: every row under every default
    column, a case two cells share (the residual without torque limits, a column with
    nothing random for a row, the F/T rows' open-loop cells) once. A case's CPU is the
    measured mean of its row (the online row costs several times the others), else the
    mean of all."""
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.studies.reference_table import expand_table

    per: dict = {}
    peaks = None
    for out in folders:
        if (out / "calibration.json").exists():
            peaks = json.loads((out / "calibration.json").read_text())["peaks"]
        for path in sorted((out / "cases").glob("*.json")):
            r = json.loads(path.read_text())
            if r.get("cpu_time_s") is not None and r["status"] == "ok":
                per.setdefault((r["params"]["row"], r["params"]["column"]), []).append(
                    float(r["cpu_time_s"]))
    values = [v for vs in per.values() for v in vs]
    mean = float(np.mean(values))
    by_row: dict = {}
    for (row, _), vs in per.items():
        by_row.setdefault(row, []).extend(vs)
    overhead = import_cpu()
    cases = expand_table(load_scenario(), [r.name for r in ROWS], list(COLUMNS), draws,
                         peaks=peaks or {})
    unique = {c.hash: c.params["row"] for c in cases}
    total = sum(float(np.mean(by_row[row])) if row in by_row else mean
                for row in unique.values()) + len(unique) * overhead / batch
    return {"per_case_mean_cpu_s": mean, "cases_measured": len(values),
            "per_row_mean_cpu_s": {r: float(np.mean(v)) for r, v in by_row.items()},
            "import_cpu_s_per_batch": overhead, "batch": batch, "draws": draws,
            "table_cells": len(ROWS) * len(COLUMNS), "table_cases": len(cases),
            "table_unique_cases": len(unique),
            "table_cpu_min": total / 60.0, "table_wall_min_2_cores": total / 120.0}


def rerun(folder: Path, count: int) -> dict:
    """Run ``count`` finished cases of ``folder`` again (one per row and variant, spread over
    them; none of the slowest) in this process and compare their numbers with the stored
    ones."""
    from drake_coop.studies.reference_engine import run_batch
    from drake_coop.studies.reference_table import per_draw

    chosen, seen = [], set()
    for path in sorted((folder / "cases").glob("*.json")):
        r = json.loads(path.read_text())
        cell = (r["params"]["row"], r["values"].get("variant"))    # rows and variants apart
        if r["status"] == "ok" and cell not in seen and (r.get("cpu_time_s") or 99) < 6:
            seen.add(cell)
            chosen.append(r)
    chosen = chosen[::max(1, len(chosen) // count)][:count]
    out = []
    for stored in chosen:
        (_, record), = run_batch([(stored["hash"], stored["scenario_yaml"],
                                   stored["values"].get("variant"))], stored["t_end"])
        a, b = per_draw(stored), per_draw(record)
        out.append({**stored["params"], "hash": stored["hash"], "stored": a, "rerun": b,
                    "same": a == b})
        print(json.dumps(out[-1]), flush=True)
    return {"cases": out, "all_same": all(c["same"] for c in out)}


def compare_stores(a: Path, b: Path) -> dict:
    """The cases two table folders both finished, matched by row, column and draw (the cases
    each folder's ``cases.csv`` lists, when it has one): whether the table's numbers of each (:func:`~drake_coop.studies.reference_table.per_draw`, NaN equal to
    NaN) are the same to the bit, and whether its hash is (an identified column's model files
    lie in each folder, so its cases' hashes differ between folders).

    Returns
    -------
    dict
        ``compared``, ``same`` (numbers), ``same_hash``, ``differ`` (the first ten that
        differ: params and both numbers), ``only_a``/``only_b`` (finished in one folder only),
        ``cpu_cases_s_a``/``cpu_cases_s_b`` (the finished cases' own CPU in each).
    """
    from drake_coop.studies.reference_table import per_draw
    from drake_coop.studies.store import ResultStore

    def cases(folder: Path) -> dict:
        # The cases of the folder's table (its cases.csv): a folder may also hold records of
        # an earlier version of a case (another scenario for the same row, column and draw).
        listed = None
        if (folder / "cases.csv").is_file():
            with open(folder / "cases.csv") as f:
                listed = {r["hash"] for r in csv.DictReader(f)}
        out = {}
        for h, r in ResultStore(folder).load().items():
            p = r["params"]
            if listed is None or h in listed:
                out[(p["row"], p["column"], p["draw"])] = r
        return out

    def same(x: dict, y: dict) -> bool:
        return x.keys() == y.keys() and all(
            x[k] == y[k] or (math.isnan(x[k]) and math.isnan(y[k])) for k in x)

    ca, cb = cases(a), cases(b)
    both = sorted(ca.keys() & cb.keys())
    differ = []
    for key in both:
        x, y = per_draw(ca[key]), per_draw(cb[key])
        if not same(x, y):
            differ.append({"case": list(key), "a": x, "b": y})
    return {"compared": len(both), "same": len(both) - len(differ),
            "same_hash": sum(ca[k]["hash"] == cb[k]["hash"] for k in both),
            "differ": differ[:10], "only_a": len(ca.keys() - cb.keys()),
            "only_b": len(cb.keys() - ca.keys()),
            "cpu_cases_s_a": sum(r.get("cpu_time_s") or 0.0 for r in ca.values()),
            "cpu_cases_s_b": sum(r.get("cpu_time_s") or 0.0 for r in cb.values())}


def page_tables(source: str, table: dict, key: str) -> str:
    """The table of ``key`` (``squeeze``, ``estimate``) as Markdown whose numbers are
    ``{result}`` roles on ``source`` (the page's name of the table's JSON): median [95 %]
    and n per cell, ``pending`` where no case finished."""
    from drake_coop.studies.reference_table import columns

    labels = {r.name: r.label for r in ROWS}
    col_labels = {c.name: c.label for c in columns({}, {})}
    cols = table["columns"]
    lines = ["| force source | " + " | ".join(col_labels[c] for c in cols) + " |",
             "|" + " --- |" * (len(cols) + 1)]
    for row in table["rows"]:
        cells = []
        for col in cols:
            cell = table["cells"].get(row, {}).get(col)
            if cell is None:
                cells.append("pending")
                continue
            base = f"{source}:cells.{row}.{col}.{key}.median"
            v, lo, hi = (f"{{result}}`{base}.{i} as .3f`" for i in range(3))
            n = f"{{result}}`{source}:cells.{row}.{col}.n as .0f`"
            diverged = (f", {{result}}`{source}:cells.{row}.{col}.diverged as .0f` diverged"
                        if cell["diverged"] else "")
            cells.append(f"{v} [{lo}, {hi}] (n = {n}{diverged})")
        lines.append(f"| {labels[row]} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def time_log(path: Path) -> dict:
    """The process CPU (user + system, waited-for children included) and wall time a
    ``/usr/bin/time -v`` log reports, with the run's last progress line."""
    text = Path(path).read_text()
    found = {}
    for line in text.splitlines():
        key, _, value = line.strip().partition(": ")
        if key in ("User time (seconds)", "System time (seconds)"):
            found[key.split()[0].lower()] = float(value)
        elif key.startswith("Elapsed (wall clock) time"):
            parts = [float(p) for p in value.split(":")]
            found["wall_s"] = sum(p * 60 ** i for i, p in enumerate(reversed(parts)))
        elif line.startswith("reference table:"):
            found["last_progress"] = line.strip()
    if "user" in found:
        found["cpu_s"] = found["user"] + found["system"]
    return {"log": Path(path).name, **found}


def snapshot(folder: Path, draws: int, rows: list[str] | None = None,
             cols: list[str] | None = None) -> dict:
    """The table of ``rows`` × ``cols`` (default: every default row and column) at ``draws``
    draws from the cases finished in ``folder`` (nothing runs; ``folder``'s ``table.json``
    and ``table.md`` rewritten), with the draws asked for. An identified column reads its
    models from ``folder/identified/<column>/<draw>/models.json``."""
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.studies.reference_engine import write_table
    from drake_coop.studies.reference_table import expand_table
    from drake_coop.studies.store import ResultStore

    peaks = json.loads((folder / "calibration.json").read_text())["peaks"]
    rows, cols = rows or [r.name for r in ROWS], cols or list(COLUMNS)
    models = {(c, d): json.loads((folder / "identified" / c / str(d) / "models.json")
                                 .read_text())
              for c in cols if c.startswith("id_") for d in range(draws)}
    cases = expand_table(load_scenario(), rows, cols, draws, peaks=peaks, models=models)
    records = ResultStore(folder).load()
    table = write_table(folder, cases, records, rows, cols)
    table["draws"] = draws
    table["distinct_cases"] = len({c.hash for c in cases})
    table["distinct_finished"] = len({c.hash for c in cases if c.hash in records})
    return table


def paired_identified(folder: Path, draws: int, rows: list[str], cols: list[str]) -> dict:
    """Each identified column against the MAP-SDP column of the same budget, row by row,
    paired by draw (the same prior, the same excitation's noise): ``n`` draws finished in
    both, ``worse`` (squeeze error above the SDP's), ``median_ratio`` and ``max_ratio`` of the
    two squeeze errors. Columns whose SDP column is not in ``cols`` are left out."""
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.studies.reference_table import expand_table, per_draw
    from drake_coop.studies.store import ResultStore

    records = ResultStore(folder).load()
    models = {(c, d): json.loads((folder / "identified" / c / str(d) / "models.json")
                                 .read_text())
              for c in cols if c.startswith("id_") for d in range(draws)}

    def squeeze(row: str, col: str) -> dict[int, float]:
        out = {}
        for draw, case in enumerate(expand_table(load_scenario(), [row], [col], draws,
                                                 models=models)):
            record = records.get(case.hash)
            if record is not None and record["status"] == "ok":
                out[draw] = per_draw(record)["squeeze"]
        return out

    paired: dict = {}
    for col in cols:
        if not col.startswith("id_") or col.startswith("id_map_sdp_"):
            continue
        sdp = "id_map_sdp_" + col.rsplit("_", 1)[1]
        if sdp not in cols:
            continue
        for row in rows:
            a, b = squeeze(row, col), squeeze(row, sdp)
            common = sorted(set(a) & set(b))
            if not common:
                continue
            ratio = np.array([a[d] / b[d] for d in common])
            paired.setdefault(row, {})[col] = {
                "against": sdp, "n": len(common), "worse": int(np.sum(ratio > 1.0)),
                "median_ratio": float(np.median(ratio)), "max_ratio": float(ratio.max())}
    return paired


def per_robot(folder: Path, draws: int, column: str = "clock") -> dict:
    """Each robot's own circle RMS of ``λ − λ_d`` and ``λ̂ − λ`` per row, median and range
    over the draws, under ``column`` and under the exact model, and ``max_change``: the
    largest change of a draw's squeeze error from the same draw's exact-model case (the
    same noise seeds). The table's cells take the worst robot, which hides a change on the
    other one (the clock column skews robot 2)."""
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.studies.reference_table import expand_table
    from drake_coop.studies.store import ResultStore

    records = ResultStore(folder).load()
    out: dict = {"column": column, "draws": draws, "rows": {}}
    for row in [r.name for r in ROWS]:
        cells, per_draw_ = {}, {}
        for col in ("exact", column):
            found: dict = {}
            for case in expand_table(load_scenario(), [row], [col], draws):
                r = records.get(case.hash)
                if r is None or r["status"] != "ok":
                    continue
                for robot, m in r["metrics"].items():
                    for key, error in (("squeeze", "force_error"), ("estimate", "estimate_error")):
                        found.setdefault(robot, {}).setdefault(key, []).append(
                            m["circle"][error]["rms"])
            per_draw_[col] = found
            cells[col] = {robot: {key: {"median": float(np.median(v)), "min": float(min(v)),
                                        "max": float(max(v)), "n": len(v)}
                                  for key, v in keys.items()} for robot, keys in found.items()}
        for robot, keys in cells.get(column, {}).items():
            a = per_draw_[column][robot]["squeeze"]
            b = per_draw_["exact"].get(robot, {}).get("squeeze", [])
            if len(a) == len(b) == draws:  # the largest change of a draw from the same draw's
                keys["squeeze"]["max_change"] = float(max(abs(x - y) for x, y in zip(a, b)))
        out["rows"][row] = cells
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", required=True)
    parser.add_argument("--draws", type=int, default=6)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--cost", nargs="+", default=None, metavar="DIR",
                        help="extrapolate the full table's cost from these tables' cases")
    parser.add_argument("--rerun", default=None, metavar="DIR",
                        help="run some finished cases of DIR again; compare the numbers")
    parser.add_argument("--count", type=int, default=4, help="--rerun: how many cases")
    parser.add_argument("--page", default=None, metavar="JSON",
                        help="print the tables of this table.json as Markdown with roles "
                             "(its name on the page: --out)")
    parser.add_argument("--table", default=None, metavar="DIR",
                        help="write the table of DIR's finished cases at --draws to --out")
    parser.add_argument("--rows", default=None, help="--table: comma-separated rows")
    parser.add_argument("--per-robot", default=None, metavar="DIR",
                        help="write each robot's own numbers under the clock column and the "
                             "exact model, from DIR's finished cases, to --out")
    parser.add_argument("--columns", default=None, help="--table: comma-separated columns")
    parser.add_argument("--time-logs", nargs="+", default=None, metavar="LOG",
                        help="--table: /usr/bin/time -v logs of the runs that filled DIR "
                             "(their process CPU recorded)")
    args = parser.parse_args()
    out = Path(args.out)
    if args.table:
        table = snapshot(Path(args.table), args.draws,
                         args.rows.split(",") if args.rows else None,
                         args.columns.split(",") if args.columns else None)
        if args.time_logs:
            table["runs"] = [time_log(Path(p)) for p in args.time_logs]
        paired = paired_identified(Path(args.table), args.draws, table["rows"],
                                   table["columns"])
        if paired:
            table["paired_with_map_sdp"] = paired
        out.write_text(json.dumps(table, indent=1) + "\n")
        print(f"{table['finished']} of {table['cases']} cases finished")
        return
    if args.per_robot:
        out.write_text(json.dumps(per_robot(Path(args.per_robot), args.draws), indent=1) + "\n")
        return
    if args.page:
        table = json.loads(Path(args.page).read_text())
        for key in ("squeeze", "estimate"):
            print(page_tables(args.out, table, key))
        return
    if args.rerun:
        result = rerun(Path(args.rerun), args.count)
        out.write_text(json.dumps(result, indent=1) + "\n")
        return
    if args.cost:
        result = cost([Path(d) for d in args.cost])
        out.write_text(json.dumps(result, indent=1) + "\n")
        print(json.dumps(result, indent=1))
        return
    table = run_table(out, rows=["observer", "momentum", "sensor_0p3", "sensor_3", "none"],
                      cols=["exact", "model_30"], draws=args.draws, workers=args.workers)
    result = {}
    for col, full in (("exact", full_exact()), ("model_30", full_model_30())):
        short = {row: cells[col]["squeeze"]["median"] for row, cells in table["cells"].items()
                 if col in cells}
        result[col] = verdicts(short, full)
        for v in result[col]:
            print(f"{col}: {v['pair'][0]} vs {v['pair'][1]}: short "
                  f"{v['short'][0][0]:.3f} / {v['short'][1][0]:.3f}, full "
                  f"{v['full'][0][0]:.3f} / {v['full'][1][0]:.3f}: {v['verdict']}")
    (out / "agreement.json").write_text(json.dumps(result, indent=1) + "\n")


if __name__ == "__main__":
    main()
