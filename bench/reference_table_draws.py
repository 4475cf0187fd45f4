"""The reference table at more draws against the committed 20-draw table.

``python -m bench.reference_table_draws STORE [--write docs/results/reference_table_5x.json]``
reads a table folder that ``drake-coop reference-table --draws N`` filled (``STORE/table.json``)
and compares each of its cells with the same cell of ``docs/results/reference_table_run.json``
(the committed 20-draw table; the first 20 draws of a cell are the same runs in both, since a
draw's random numbers are ``numpy.random.default_rng([seed, column, draw])``):

* the median squeeze error at N draws, and whether it lies inside the 20-draw median's 95 %
  interval (the short table's intervals are honest if it does);
* the other way round, whether the 20-draw median lies inside the N-draw median's 95 %
  interval (narrower: a 20-draw median outside it is a cell whose short-table value moved);
* how much narrower the interval got (its width at N draws over its width at 20);
* the diverged draws, as counts and fractions.

A cell with fewer draws than the store's most (a run not finished) is compared at the draws
it has and listed in ``incomplete``. Prints one line per cell; ``--write`` stores the
comparison as JSON with the store's case count, CPU time and the command that fills it, and
with ``--runs LOG ...`` what each run of it said (:func:`run_log`).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

from drake_coop.studies.reference_table import COLUMNS, ROWS

COMMITTED = Path("docs/results/reference_table_run.json")
#: An interval narrower than this fraction of its median is a point (nothing compared): the
#: draws differ at the scale the same case's numbers differ between Drake versions.
POINT = 1e-6


def compare(many: dict, twenty: dict) -> dict:
    """Each cell of ``many`` that ``twenty`` also has, compared (module docstring).

    Parameters
    ----------
    many, twenty : dict
        Two ``table.json`` documents of ``drake-coop reference-table``.

    Returns
    -------
    dict
        ``{"cells": {row: {column: {...}}}, "inside": k, "compared": n, "outside": [...],
        "inside_100": k, "compared_100": n, "outside_100": [...], "draws": N,
        "incomplete": [...]}``: ``inside`` counts the cells whose N-draw median lies in the
        20-draw interval (``outside`` names the others, as ``"row/column"``), ``inside_100``
        those whose 20-draw median lies in the N-draw interval; a cell's ``inside_20_interval``
        (``median_20_inside_interval``) is None where the 20-draw (N-draw) interval is a point
        (narrower than :data:`POINT` of its median: a column with nothing random, or whose
        draws move the run only at the rounding's scale). ``draws`` is the most draws of a cell; ``incomplete``
        names the cells with fewer.
    """
    def is_point(lo: float, hi: float, m: float) -> bool:
        # Narrower than POINT of its median: a column whose draws change the run only at
        # the rounding's scale (the clock skew with an estimate that ignores it).
        return hi - lo <= max(POINT * abs(m), 1e-12)

    cells, inside, compared = {}, 0, 0
    inside_100, compared_100, outside, outside_100 = 0, 0, [], []
    for row, columns in many["cells"].items():
        for col, cell in columns.items():
            other = twenty["cells"].get(row, {}).get(col)
            if other is None:
                continue
            m, lo, hi = cell["squeeze"]["median"]
            m20, lo20, hi20 = other["squeeze"]["median"]
            point = is_point(lo20, hi20, m20)
            hit = None if point else bool(lo20 <= m <= hi20)
            if hit is not None:
                compared += 1
                inside += hit
                if not hit:
                    outside.append(f"{row}/{col}")
            point_n = is_point(lo, hi, m)
            back = None if point_n else bool(lo <= m20 <= hi)
            if back is not None:
                compared_100 += 1
                inside_100 += back
                if not back:
                    outside_100.append(f"{row}/{col}")
            cells.setdefault(row, {})[col] = {
                "draws": cell["n"], "diverged": cell["diverged"],
                "diverged_fraction": cell["diverged"] / cell["n"],
                "median": m, "interval": [lo, hi],
                "median_20": m20, "interval_20": [lo20, hi20],
                "diverged_20": other["diverged"], "diverged_fraction_20": other["diverged"] / other["n"],
                "inside_20_interval": hit, "median_20_inside_interval": back,
                "width_ratio": None if point else (hi - lo) / (hi20 - lo20),
            }
    most = max((c["draws"] for r in cells.values() for c in r.values()), default=0)
    incomplete = [f"{r}/{k}" for r, cols in cells.items() for k, c in cols.items()
                  if c["draws"] < most]
    return {"cells": cells, "inside": inside, "compared": compared, "outside": outside,
            "inside_100": inside_100, "compared_100": compared_100, "outside_100": outside_100,
            "draws": most, "incomplete": incomplete}


def command(many: dict, draws: int) -> str:
    """The command that fills a table folder like ``many`` on a cluster.

    Parameters
    ----------
    many : dict
        A ``table.json`` document of ``drake-coop reference-table``.
    draws : int
        Its draws per cell.

    Returns
    -------
    str
        ``drake-coop reference-table --out STORE --draws N [--rows ...] [--columns ...] --ray
        127.0.0.1:PORT``; rows and columns named only where they are not all the rows and the
        default columns.
    """
    parts = ["drake-coop reference-table --out STORE", f"--draws {draws}"]
    if list(many["rows"]) != [r.name for r in ROWS]:
        parts.append(f"--rows {','.join(many['rows'])}")
    if list(many["columns"]) != list(COLUMNS):
        parts.append(f"--columns {','.join(many['columns'])}")
    return " ".join(parts + ["--ray 127.0.0.1:PORT"])


_PROGRESS = re.compile(r"reference table: (\d+) of \d+$")
_PLANNED = re.compile(r"reference table: (\d+) cases, (\d+) already finished, running (\d+)")


def run_log(path: Path) -> dict:
    """What one run of the table's command said, from its ``/usr/bin/time -v`` log.

    Parameters
    ----------
    path : Path
        The log: the command's progress lines and ``/usr/bin/time -v``'s report.

    Returns
    -------
    dict
        ``log`` (the file's name), ``cases``, ``already_finished``, ``running`` (its first
        line's plan), ``last_progress`` (its last progress line) and ``progress`` (the finished
        cases it counts), ``exit`` (the command's
        exit status; 130 interrupted), ``cpu_s`` (the driver's own process CPU: the Ray
        workers' is not in it) and ``wall_s``.
    """
    found = {"log": Path(path).name}
    for line in Path(path).read_text().splitlines():
        line = line.strip()
        plan = _PLANNED.match(line)
        if plan:
            found.update(zip(("cases", "already_finished", "running"), map(int, plan.groups())))
        elif line.startswith("reference table:"):
            found["last_progress"] = line
            done = _PROGRESS.match(line)
            if done:
                found["progress"] = int(done.group(1))
        elif line.startswith("Exit status:"):
            found["exit"] = int(line.partition(": ")[2])
        elif line.startswith(("User time (seconds):", "System time (seconds):")):
            found["cpu_s"] = found.get("cpu_s", 0.0) + float(line.partition(": ")[2])
        elif line.startswith("Elapsed (wall clock) time"):
            parts = [float(v) for v in line.rpartition(": ")[2].split(":")]
            found["wall_s"] = sum(v * 60 ** i for i, v in enumerate(reversed(parts)))
    return found


def main(argv: list[str] | None = None) -> int:
    """Compare a table folder with the committed 20-draw table (module docstring).

    Parameters
    ----------
    argv : list of str or None
        The command line (None: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 written or printed; 2 a missing file.
    """
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("store", help="the table folder (its table.json)")
    parser.add_argument("--write", help="the JSON to write")
    parser.add_argument("--runs", nargs="+", default=[], metavar="LOG",
                        help="--write: the runs' /usr/bin/time -v logs, in order (recorded)")
    args = parser.parse_args(argv)
    try:
        many = json.loads((Path(args.store) / "table.json").read_text())
        twenty = json.loads(COMMITTED.read_text())
        runs = [run_log(Path(p)) for p in args.runs]
    except OSError as exc:
        print(f"reference_table_draws: {exc.strerror}: {exc.filename}", file=sys.stderr)
        return 2
    result = compare(many, twenty)
    for row, columns in result["cells"].items():
        for col, c in columns.items():
            print(f"{row:12s} {col:11s} {c['median']:.4g} [{c['interval'][0]:.4g}, "
                  f"{c['interval'][1]:.4g}] at {c['draws']}; 20 draws {c['median_20']:.4g} "
                  f"[{c['interval_20'][0]:.4g}, {c['interval_20'][1]:.4g}]; diverged "
                  f"{c['diverged']}/{c['draws']} vs {c['diverged_20']}/20")
    print(f"inside the 20-draw interval: {result['inside']} of {result['compared']} cells; "
          f"20-draw median inside the {result['draws']}-draw interval: "
          f"{result['inside_100']} of {result['compared_100']}")
    if result["incomplete"]:
        print(f"fewer than {result['draws']} draws: {', '.join(result['incomplete'])}")
    if args.write:
        result.update(rows=many["rows"], columns=many["columns"], cases=many["cases"],
                      finished=many["finished"], cpu_time_s=many.get("cpu_time_s"),
                      command=command(many, result["draws"]))
        if runs:
            result["runs"] = runs
        Path(args.write).write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
