"""``drake-coop stability SCENARIO --out DIR [--grid PATH=v1,v2,... ...] [--point free|held|both]``.

Computes ρ(Φ) of the one-period map at each grid point and operating point
(:mod:`drake_coop.stability.grid`) and writes ``DIR/stability.csv`` and the maps
(:mod:`drake_coop.stability.output`); ``--overlay RESULTS.csv`` marks a study's simulated
outcomes on them. ``--out`` is checked before the grid runs and written whole at the end (staged
in a hidden sibling, :func:`drake_coop.results.io.staged_folder`). Exit codes: 0 done (unstable
points are results), 1 a point's ρ depends on the finite-difference step (the reason is printed;
the rows are written with status ``step_dependent``) or writing the outputs failed (the previous
outputs are kept), 2 bad input (one line naming the field), 130 Ctrl-C, 143 SIGTERM.
"""

from __future__ import annotations

import sys
from pathlib import Path

__all__ = ["add_stability_parser", "cmd_stability", "parse_grid"]


class InputError(ValueError):
    """Bad command-line input (one line, exit 2)."""


def _value(text: str):
    from pydrake.common.yaml import yaml_load

    try:
        return yaml_load(data=f"v: {text}")["v"]
    except Exception:
        return text


def parse_grid(items: list[str]) -> dict[str, list]:
    """``["control_period=0.009,0.02", …]`` -> ``{"control_period": [0.009, 0.02], …}``.

    Parameters
    ----------
    items : list of str
        ``path=v1,v2,…`` items of the command line.

    Returns
    -------
    dict of str to list
        Each path's values (numbers where they parse, else text).
    """
    grid: dict[str, list] = {}
    for item in items:
        path, sep, values = item.partition("=")
        if not sep or not path or not values:
            raise InputError(f"--grid: expected PATH=v1,v2,..., got {item!r}")
        if path in grid:
            raise InputError(f"--grid: {path} given twice")
        grid[path] = [_value(v) for v in values.split(",")]
    return grid


def add_stability_parser(sub) -> None:
    """Register ``stability`` on the ``drake-coop`` subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``drake-coop`` subparsers.
    """
    p = sub.add_parser("stability", help="spectral radius of the one-period map over a grid")
    p.add_argument("scenario", help="scenario YAML or shipped scenario name")
    p.add_argument("--out", required=True, help="output folder (new, or one of ours)")
    p.add_argument("--grid", action="append", default=[], metavar="PATH=v1,v2,...",
                   help="a dotted scenario path and its values (repeatable)")
    p.add_argument("--point", default="free", choices=["free", "held", "both"],
                   help="operating point of the map: free (arms before the grasp, t = 0), "
                        "held (object held, at the circle's start) or both (default free)")
    p.add_argument("--overlay", default=None, metavar="RESULTS.csv",
                   help="a study's results.csv to mark its simulated outcomes on the maps")
    p.add_argument("--workers", type=int, default=2,
                   help="parallel processes, one grid point each (default 2)")
    p.add_argument("--ray", nargs="?", const="", default=None, metavar="ADDRESS",
                   help="run on Ray: a local instance, or the cluster at ADDRESS")
    p.add_argument("--epsilon", type=float, default=1e-3,
                   help="central-difference step, 1e-6 to 1e-3 (default 1e-3, on the held "
                        "loop's plateau too; ρ is computed again with a second step and must "
                        "agree)")
    p.add_argument("--quiet", action="store_true", help="no progress messages")
    p.set_defaults(func=cmd_stability)


def _check_out(out: Path) -> None:
    from drake_coop.results.io import check_output_folder
    from drake_coop.stability.output import OUTPUT_NAMES

    check_output_folder(out)
    if out.is_dir():
        foreign = [p.name for p in out.iterdir()     # ours, or our interrupted temp files
                   if not any(p.name.lstrip(".").startswith(n) for n in OUTPUT_NAMES)]
        if foreign:
            raise InputError(f"--out: {out} holds files that are not a stability map's "
                             f"({', '.join(sorted(foreign)[:3])}); choose a new folder")


def cmd_stability(args) -> int:
    """Run ``drake-coop stability``: ρ of the one-period map over the grid, written to ``--out``.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit code: 0 done, 1 the outputs could not be written or a point has no
        step-independent ρ, 2 bad input.
    """
    from drake_coop.console import error as _error
    from drake_coop.results.io import staged_folder
    from drake_coop.scenario.resources import find_scenario
    from drake_coop.scenario.schema import ScenarioError
    from drake_coop.stability.grid import STEP_DEPENDENT, grid_cases, run_grid
    from drake_coop.stability.period_map import EPSILON_RANGE
    from drake_coop.stability.output import outcome_key, plot_maps, read_outcomes, write_csv
    from drake_coop.studies.spec import StudyError

    try:
        lo, hi = EPSILON_RANGE
        if not lo <= args.epsilon <= hi:
            raise InputError(f"--epsilon must be in [{lo:g}, {hi:g}] (where the map's ρ does "
                             f"not depend on the step), got {args.epsilon}")
        if args.workers < 1:
            raise InputError(f"--workers must be >= 1, got {args.workers}")
        out = Path(args.out)
        _check_out(out)
        path = find_scenario(args.scenario)
        text = path.read_text(encoding="utf-8")
        if not text.strip():
            raise InputError(f"scenario {path}: the file is empty (give a scenario, or the "
                             "shipped 'paper')")
        grid = parse_grid(args.grid)
        cases = grid_cases(text, grid)
        swept = list(grid)
        outcomes = read_outcomes(args.overlay, swept) if args.overlay else None
        if outcomes is not None:
            keys = {outcome_key(case.params, swept) for case in cases}
            if not keys & set(outcomes):
                raise InputError(f"--overlay: {args.overlay} has no case at this grid's points "
                                 f"(its columns {', '.join(swept)} never take the grid's "
                                 "values)")
    except (InputError, ScenarioError, StudyError, OSError, ValueError) as exc:
        return _error(str(exc))
    points = ["free", "held"] if args.point == "both" else [args.point]
    rows_by_case: dict[int, list[dict]] = {}

    def on_result(case, rows) -> None:
        rows_by_case[case.index] = [{**{k: case.params[k] for k in swept}, **r} for r in rows]
        if not args.quiet:
            text = ", ".join(f"{r['point']}: rho={r.get('rho', float('nan')):.4g} "
                             f"{r['status']}" for r in rows)
            print(f"{len(rows_by_case)}/{len(cases)} "
                  f"{', '.join(f'{k}={v}' for k, v in case.params.items())}: {text}",
                  file=sys.stderr, flush=True)

    run_grid(cases, points, on_result, workers=args.workers,
             engine="ray" if args.ray is not None else "local",
             address=args.ray or None, epsilon=args.epsilon)
    rows = [r for i in sorted(rows_by_case) for r in rows_by_case[i]]
    try:
        with staged_folder(out) as staging:
            write_csv(staging / "stability.csv", swept, rows)
            figures = plot_maps(staging, swept, rows, outcomes)
    except OSError as exc:               # a full disk while writing: nothing was replaced
        _error(f"--out {out}: writing the outputs failed ({exc.strerror or exc}); nothing "
               "was replaced")
        return 1
    if not args.quiet:
        print(f"wrote {out / 'stability.csv'} and {len(figures)} figure(s)", file=sys.stderr)
    dependent = [r for r in rows if r["status"] == STEP_DEPENDENT]
    if dependent:
        _error(f"{len(dependent)} point(s) have no step-independent ρ (status "
               f"{STEP_DEPENDENT} in stability.csv); first: {dependent[0]['message']}")
        return 1
    return 0
