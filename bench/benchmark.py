"""Benchmark of drake_coop: ``python bench/benchmark.py [--t-end 90] [--out bench.json]``.

Reports the paper experiment's wall and CPU time against the plant alone (ratios, spread over
``--repeats`` alternated pairs), the ground-truth force log's share, a per-system breakdown per
tick, the scaling with the plant step and per robot, and optionally another scenario's
realtime factor (``--scenario scenarios/contact.yaml``), and the object-aware blocks' cost on
lab arms (``--object-arms two_pandas``: each run against its plant replay); see
:mod:`bench.harness`.
"""

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # the checkout: bench.harness

from bench.harness import run_benchmark  # noqa: E402

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--t-end", type=float, default=90.0)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument("--out", default=None, help="write the numbers as JSON")
    parser.add_argument("--t-scaling", type=float, default=20.0,
                        help="simulated seconds of each plant-step scaling run (0 skips them)")
    parser.add_argument("--scenario", default=None,
                        help="also measure this scenario's realtime factor "
                             "(e.g. scenarios/contact.yaml)")
    parser.add_argument("--t-scenario", type=float, default=None,
                        help="simulated seconds of that run (default: its whole task)")
    parser.add_argument("--t-attribution", type=float, default=10.0,
                        help="simulated seconds of each run of the ground truth's attribution "
                             "(0 skips it)")
    parser.add_argument("--attribution-repeats", type=int, default=5)
    parser.add_argument("--t-callbacks", type=float, default=16.2,
                        help="simulated seconds of the run whose Python callbacks are counted "
                             "(0 skips it)")
    parser.add_argument("--object-repeats", type=int, default=0,
                        help="with a contact --scenario: alternated repeats of the run with "
                             "object_model none / known / estimated, each followed by the plant "
                             "alone replaying its torques (0 skips them)")
    parser.add_argument("--object-arms", nargs="+", default=None, metavar="NAME",
                        help="shipped scenarios (e.g. two_pandas; contact = the paper's arms) "
                             "run with contact.yaml's plant and object_model estimated: the "
                             "whole run against its plant replay and the object blocks' own "
                             "cost (bar: <= 20 %%)")
    parser.add_argument("--t-object-arms", type=float, default=30.0,
                        help="simulated seconds of those runs (30: the grasp at 15 s, the "
                             "lift, 5 s of the circle)")
    parser.add_argument("--object-arms-repeats", type=int, default=3,
                        help="alternated (none, estimated) pairs per scenario, each run "
                             "followed by its plant replay")
    args = parser.parse_args()
    for flag, value in (("--t-object-arms", args.t_object_arms),
                        ("--object-arms-repeats", args.object_arms_repeats)):
        if not value > 0:
            parser.error(f"{flag}: a number > 0 is required, got {value}")
    run_benchmark(args.t_end, args.repeats, args.out, t_scaling=args.t_scaling,
                  extra_scenario=args.scenario, t_extra=args.t_scenario,
                  t_attribution=args.t_attribution,
                  attribution_repeats=args.attribution_repeats, t_callbacks=args.t_callbacks,
                  object_repeats=args.object_repeats, lab_object=args.object_arms,
                  t_lab=args.t_object_arms, lab_repeats=args.object_arms_repeats)
