"""``drake-coop identify``: identify the scenario's robots and write the identified models.

The data come from the simulated experiment (default), from the arms themselves over the
wire (``--wire URL``: each arm's excitation through its driver's LCM messages, checked before
the first command, :mod:`~drake_coop.robot.wire_identify`; ``--wire lockstep``: the
in-process simulated driver, stepped tick by tick), or from a recording of the wire
(``--recording FILE``, :mod:`~drake_coop.identification.recording`). Exit codes: 0 done, 1 an
identification failed or the wire experiment was refused or stopped (one line), 2 bad input.
"""

from __future__ import annotations

import argparse
import sys

from drake_coop.console import error as _error
from drake_coop.scenario.resources import find_scenario


def cmd_identify(args: argparse.Namespace) -> int:
    """The exit code of ``drake-coop identify`` (0 done, 1 an identification failed, 2 bad
    input, one line): the scenario's robots identified, DIR written.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (:func:`build_parser`).
    """
    import math

    from drake_coop.identification.report import parse_robots, run_identify
    from drake_coop.identification.setup import IdentifyInputError
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.schema import ScenarioError

    if not math.isfinite(args.duration):
        return _error(f"--duration must be a finite number of seconds, got {args.duration}")
    wire, recording = getattr(args, "wire", None), getattr(args, "recording", None)
    if wire is not None and recording is not None:
        return _error("--wire and --recording: give one (drive the arms now, or identify "
                      "from a recording)")
    log = (lambda *a: None) if args.quiet else (lambda m: print(m, flush=True))
    try:
        scenario = load_scenario(find_scenario(args.scenario))
        robots = parse_robots(args.robots, len(scenario.robots))
        recordings, source = None, "simulation"
        if recording is not None:
            recordings, source = _read(recording, scenario, robots), f"recording {recording}"
        elif wire is not None:
            recordings = _drive(wire, scenario, robots, args, log)
            if isinstance(recordings, int):
                return recordings
            source = "wire"
        report = run_identify(scenario, args.out, robots, args.duration, seed=args.seed,
                              estimator=args.estimator, log=log, recordings=recordings,
                              source=source)
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


def _read(path: str, scenario, robots: list[int]) -> dict:
    """The recording's arms by scenario index (``IdentifyInputError``: one line)."""
    from drake_coop.identification.recording import read_recording
    from drake_coop.identification.setup import IdentifyInputError

    try:
        found = read_recording(path)
    except ValueError as exc:
        raise IdentifyInputError(str(exc)) from None
    by_index = {r.index: r for r in found.values()}
    missing = [scenario.robots[i].name for i in robots if i not in by_index]
    if missing:
        raise IdentifyInputError(f"--recording {path}: no rows of {', '.join(missing)} "
                                 f"(it holds {', '.join(found) or 'none'}); choose --robots")
    return by_index


def _drive(url: str, scenario, robots: list[int], args, log):
    """Drive the excitation over the wire; the recordings by index, or an exit code."""
    import sys

    from drake_coop.robot.wire_identify import Lockstep, WallClock, WireRefusal, drive
    from drake_coop.robot.cli import check_lcm_url
    from drake_coop.robot.driver_spec import driver_specs
    from drake_coop.scenario.model_check import check_models
    from pydrake.lcm import DrakeLcm

    specs = driver_specs(scenario, check_models(scenario))
    if url == "lockstep":
        lcm = DrakeLcm("memq://")
        clock = Lockstep(scenario, lcm, specs)
    else:
        try:
            check_lcm_url(url)
        except ValueError as exc:
            return _error(str(exc).replace("--lcm-url", "--wire"))
        if url.startswith("memq://"):
            return _error("--wire memq:// is in-process only: no driver in another process can "
                          "reach it; use tcpq:// or udpm://, or --wire lockstep")
        try:
            lcm = DrakeLcm(url)
        except Exception as exc:
            return _error(f"--wire {url!r}: {' '.join(str(exc).split())[:200]}")
        clock = WallClock(lcm)
    log(f"drake-coop: driving {args.duration:g} s of excitation over the wire ({url}) on "
        + ", ".join(scenario.robots[i].name for i in robots))
    try:
        recordings = drive(scenario, robots, lcm, clock, duration=args.duration,
                           seed=args.seed, specs=specs)
    except WireRefusal as exc:
        print(f"drake-coop: identify --wire: {exc}", file=sys.stderr)
        return 1
    return {r.index: r for r in recordings}
