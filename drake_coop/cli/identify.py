"""``drake-coop identify``: identify the scenario's robots and write the identified models."""

from __future__ import annotations

import argparse
import sys

from drake_coop.console import error as _error
from drake_coop.scenario.resources import find_scenario


def cmd_identify(args: argparse.Namespace) -> int:
    """Identify the scenario's robots and write DIR (exit 2 on bad input, one line).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (:func:`build_parser`).

    Returns
    -------
    int
        The exit code: 0 done, 1 an identification failed, 2 bad input.
    """
    import math

    from drake_coop.identification.report import (
        IdentifyInputError,
        parse_robots,
        run_identify,
    )
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.schema import ScenarioError

    if not math.isfinite(args.duration):
        return _error(f"--duration must be a finite number of seconds, got {args.duration}")
    try:
        scenario = load_scenario(find_scenario(args.scenario))
        robots = parse_robots(args.robots, len(scenario.robots))
        report = run_identify(scenario, args.out, robots, args.duration, seed=args.seed,
                              estimator=args.estimator,
                              log=(lambda *a: None) if args.quiet else
                              (lambda m: print(m, flush=True)))
    except (ScenarioError, IdentifyInputError) as exc:
        return _error(str(exc))
    except OSError as exc:                 # a full disk while writing: nothing was replaced
        _error(f"--out {args.out}: writing the outputs failed ({exc.strerror or exc}); "
               "nothing was replaced")
        return 1
    for name, r in report["robots"].items():
        if r.get("estimator_stopped"):        # e.g. DIDIM's loop diverged: said, in one line
            print(f"drake-coop: warning: {name}: the {r['estimator']} iterations stopped: "
                  f"{' '.join(str(r['estimator_stopped']).split())[:300]}; the estimate is "
                  "the last one reached", file=sys.stderr)
    if not args.quiet:
        for name, r in report["robots"].items():
            v = r["validation"]
            share = v['torque_error_rms_identified'] / max(v['torque_rms'], 1e-300)
            print(f"{name}: model torque error {v['torque_error_rms_identified']:.3g} N·m RMS "
                  f"({100 * share:.2g} % of the torque RMS on fresh data; nominal model "
                  f"{v['torque_error_rms_nominal']:.3g}), base parameters "
                  f"{r['identifiable_combinations']}, residual "
                  f"{max(r['residual_torque_rms']):.3g} N·m, condition number "
                  f"{r['regressor_condition_number']:.3g}")
        print(f"wrote {args.out}")
    return 0
