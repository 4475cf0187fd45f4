"""The reference table at more draws against the committed 20-draw table.

``python -m bench.reference_table_draws STORE [--write docs/results/reference_table_5x.json]``
reads a table folder that ``drake-coop reference-table --draws N`` filled (``STORE/table.json``)
and compares each of its cells with the same cell of ``docs/results/reference_table_run.json``
(the committed 20-draw table; the first 20 draws of a cell are the same runs in both, since a
draw's random numbers are ``numpy.random.default_rng([seed, column, draw])``):

* the median squeeze error at N draws, and whether it lies inside the 20-draw median's 95 %
  interval (the short table's intervals are honest if it does);
* how much narrower the interval got (its width at N draws over its width at 20);
* the diverged draws, as counts and fractions.

Prints one line per cell; ``--write`` stores the comparison as JSON with the store's case
count and CPU time.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

COMMITTED = Path("docs/results/reference_table_run.json")


def compare(many: dict, twenty: dict) -> dict:
    """Each cell of ``many`` that ``twenty`` also has, compared (module docstring).

    Parameters
    ----------
    many, twenty : dict
        Two ``table.json`` documents of ``drake-coop reference-table``.

    Returns
    -------
    dict
        ``{"cells": {row: {column: {...}}}, "inside": k, "compared": n}``; a cell's ``inside``
        is None where the 20-draw interval is a point (a column with nothing random).
    """
    cells, inside, compared = {}, 0, 0
    for row, columns in many["cells"].items():
        for col, cell in columns.items():
            other = twenty["cells"].get(row, {}).get(col)
            if other is None:
                continue
            m, lo, hi = cell["squeeze"]["median"]
            m20, lo20, hi20 = other["squeeze"]["median"]
            point = hi20 - lo20 <= 1e-12 * max(1.0, abs(m20))
            hit = None if point else bool(lo20 <= m <= hi20)
            if hit is not None:
                compared += 1
                inside += hit
            cells.setdefault(row, {})[col] = {
                "draws": cell["n"], "diverged": cell["diverged"],
                "diverged_fraction": cell["diverged"] / cell["n"],
                "median": m, "interval": [lo, hi],
                "median_20": m20, "interval_20": [lo20, hi20],
                "diverged_20": other["diverged"], "diverged_fraction_20": other["diverged"] / other["n"],
                "inside_20_interval": hit,
                "width_ratio": None if point else (hi - lo) / (hi20 - lo20),
            }
    return {"cells": cells, "inside": inside, "compared": compared}


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
    args = parser.parse_args(argv)
    try:
        many = json.loads((Path(args.store) / "table.json").read_text())
        twenty = json.loads(COMMITTED.read_text())
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
    print(f"inside the 20-draw interval: {result['inside']} of {result['compared']} cells")
    if args.write:
        result.update(rows=many["rows"], columns=many["columns"], cases=many["cases"],
                      finished=many["finished"], cpu_time_s=many.get("cpu_time_s"),
                      command=f"drake-coop reference-table --out STORE --draws "
                              f"{max(c['draws'] for r in result['cells'].values() for c in r.values())}"
                              f" --rows {','.join(many['rows'])} --ray 127.0.0.1:PORT")
        Path(args.write).write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
