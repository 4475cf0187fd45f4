"""Benchmark of drake_coop: ``python bench/benchmark.py [--t-end 90] [--out bench.json]``.

Reports the realtime factor of the paper's experiment, the plant-alone floor and the cost
per controller tick (see :mod:`drake_coop.bench`).
"""

import argparse

from drake_coop.bench import run_benchmark

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--t-end", type=float, default=90.0)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--out", default=None, help="write the numbers as JSON")
    args = parser.parse_args()
    run_benchmark(args.t_end, args.repeats, args.out)
