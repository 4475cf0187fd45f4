"""Cost per control tick against the number of robots: ``python bench/robots.py
[--robots 2 3 4 6] [--t-end 10] [--repeats 3] [--out robots.json]`` (see :mod:`bench.robots_scaling`)."""

import argparse
import sys
from pathlib import Path
import json

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # the checkout: bench.*

from bench.robots_scaling import robots_scaling  # noqa: E402

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--robots", type=int, nargs="+", default=[2, 3, 4, 6])
    parser.add_argument("--t-end", type=float, default=10.0)
    parser.add_argument("--repeats", type=int, default=1,
                        help="alternated (experiment, plant alone) pairs per l; medians")
    parser.add_argument("--out", default=None, help="write the numbers as JSON")
    args = parser.parse_args()
    rows = robots_scaling(tuple(args.robots), args.t_end, args.repeats)
    if args.out:
        from drake_coop.results.io import atomic_write_text

        atomic_write_text(args.out, json.dumps(rows, indent=2))
