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
the CPU seconds per case of the finished cases in ``DIR`` (``cases.csv``) and the extrapolated
CPU and 2-core wall time of the full 20-draw table.
"""

from __future__ import annotations

import argparse
import csv
import itertools
import json
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
    two-core wall time at ``draws`` draws, batches of ``batch`` cases."""
    per: dict = {}
    for out in folders:
        for path in sorted((out / "cases").glob("*.json")):
            r = json.loads(path.read_text())
            if r.get("cpu_time_s") is not None and r["status"] == "ok":
                per.setdefault(r["params"]["column"], []).append(float(r["cpu_time_s"]))
    values = [v for vs in per.values() for v in vs]
    mean = float(np.mean(values))
    overhead = import_cpu()
    cases = len(ROWS) * len(COLUMNS) * draws
    total = cases * (mean + overhead / batch)
    return {"per_case_mean_cpu_s": mean, "cases_measured": len(values),
            "per_column_mean_cpu_s": {c: float(np.mean(v)) for c, v in per.items()},
            "import_cpu_s_per_batch": overhead, "batch": batch, "table_cases": cases,
            "table_cpu_min": total / 60.0, "table_wall_min_2_cores": total / 120.0}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", required=True)
    parser.add_argument("--draws", type=int, default=6)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--cost", nargs="+", default=None, metavar="DIR",
                        help="extrapolate the full table's cost from these tables' cases")
    args = parser.parse_args()
    out = Path(args.out)
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
