"""Arms and boxes the project does not ship, set up from the docs alone: the lab-arm goals.

Each name is a scenario file written as the how-to of the lab-arms guide says (a robot entry of
``drake-coop arms --yaml NAME`` per arm, placed and oriented, ``contact.yaml``'s plant with the
box, ``object_model: {mode: estimated}``, **no gains**). The script does what a user does next:
derives the gains as ``drake-coop gains`` does (:func:`drake_coop.stability.gains.derive_and_check`,
the same rules and stability check), then runs the scenario with them to the circle's end
(+1 s) and measures it with :func:`bench.lab_arms_object.measure` (the same code as the shipped
lab arms' numbers; the lift phase's slips and friction use are added from the same metrics),
and checks the bars on the circle phase::

    python -m bench.unseen_arms docs/guide/lab_arms_howto/two_xarm7_box.yaml \\
        --out docs/results/unseen_arms.json

The case's key is the file's stem (``--case`` names it otherwise; ``--squeeze friction`` runs
it with ``object_model.squeeze: friction`` instead, under ``STEM@sqfriction``; ``--lift-timeline
T_END`` runs to ``T_END`` only and stores the grasp's and the lift's forces, rises and slide every
0.25 s, :func:`lift_timeline`, under ``STEM@lift``); each case is written as soon
as it ends, with its command, the derived gains and their ρ, the drake version and the CPU (the
file keeps the cases of other calls). Exit 1 when the derived gains fail their check (the case
is written, without a run).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

#: The bars on the circle phase: squeeze error RMS (N, worst arm), the box's position
#: error RMS (m), its turn about the grasp line RMS (rad), slips, drops, and the mass estimate's
#: relative error at the lift's end.
BARS = {"squeeze_error_rms_N": 0.3, "object_position_error_rms_m": 0.5e-3,
        "object_turn_rms_rad": math.radians(0.3), "slips": 0, "drops": 0,
        "mass_error_at_lift_end": 0.05}


def verdicts(case: dict) -> dict:
    """Each bar of :data:`BARS`: the measured value (worst arm) and whether it passes."""
    robots = case["robots"].values()
    measured = {
        "squeeze_error_rms_N": max(r["squeeze_error_rms_N"] for r in robots),
        "object_position_error_rms_m": max(r["object_position_error_rms"] for r in robots),
        "object_turn_rms_rad": max(abs(r["object_turn_rms"]) for r in robots),
        "slips": sum(r["slips"] or 0 for r in robots),
        "drops": sum(r["drops"] or 0 for r in robots),
        "mass_error_at_lift_end": abs(case.get("mass_error_at_lift_end", math.inf)),
    }
    return {k: {"value": v, "bar": BARS[k], "passes": bool(v <= BARS[k])}
            for k, v in measured.items()}


def measure_with_lift(scenario) -> dict:
    """:func:`bench.lab_arms_object.measure` (the circle phase), and the same run's lift phase
    per robot (``lift``: the squeeze error's RMS, the friction use's max, the pad's slip on
    the box at the lift's end, slips and drops), read from the metrics that ``measure``
    computes (``compute_metrics`` wrapped while it runs: one run, one measuring code)."""
    import drake_coop.results.metrics as metrics_module
    from bench.lab_arms_object import measure

    captured = {}
    compute = metrics_module.compute_metrics

    def capture(logs, meta, *args, **kwargs):
        captured["metrics"] = compute(logs, meta, *args, **kwargs)
        return captured["metrics"]

    metrics_module.compute_metrics = capture
    try:
        case = measure(scenario)
    finally:
        metrics_module.compute_metrics = compute
    for robot, entry in case["robots"].items():
        lift = captured["metrics"][robot].get("lift", {})
        entry["lift"] = {
            "squeeze_error_rms_N": lift.get("force_error", {}).get("rms"),
            "friction_use_max": lift.get("friction_use", {}).get("max"),
            "slip_max": lift.get("slip", {}).get("max"),
            "slips": lift.get("slips", {}).get("count"),
            "drops": lift.get("drops", {}).get("count")}
    return case


def lift_timeline(scenario, t_end: float, step: float = 0.25) -> dict:
    """The grasp and the lift's first seconds, every ``step`` s to ``t_end``, from the plant's
    truth: per robot ``λ_d``, the pad's normal and tangential force on the box (N), the pad's
    rise since the run's start and its slide on the box (mm; :func:`~drake_coop.results.
    object_metrics.object_signals`), and the box's rise (mm). Beside it, the squeeze at which
    friction carries the box, ``m g / (2 μ)`` per pad (two pads), and the first tick where
    both pads' normal force ``f_n`` reaches it."""
    from drake_coop.experiment.simulate import simulate
    from drake_coop.results.object_metrics import object_signals

    result = simulate(scenario, t_end=t_end)
    logs, meta = result.logs, result.meta
    signals = object_signals(logs, meta)
    robots = list(logs)
    t = np.asarray(logs[robots[0]]["t"])
    pose = np.asarray(logs[robots[0]]["object_pose"])
    m, mu = float(scenario.plant.object_mass), float(scenario.plant.friction)
    needed = m * 9.81 / (2.0 * mu)
    rows = []
    for tt in np.arange(scenario.task.t_grasp - 0.5, t_end, step):
        k = int(np.searchsorted(t, tt - 1e-9))
        if k >= len(t):
            break
        row = {"t": float(t[k]), "box_rise_mm": 1e3 * float(pose[k, 6] - pose[0, 6])}
        for r in robots:
            log = logs[r]
            slip = float(signals[r]["slip"][k])
            row[r] = {"lambda_d_N": float(np.ravel(log["lambda_d"][k])[0]),
                      "pad_normal_N": float(log["pad_normal_force"][k]),
                      "pad_tangential_N": float(log["pad_tangential_force"][k]),
                      "pad_rise_mm": 1e3 * float(log["x"][k, 2] - log["x"][0, 2]),
                      "slide_mm": 1e3 * slip if np.isfinite(slip) else None}
        rows.append(row)
    f_n = np.min([np.asarray(logs[r]["pad_normal_force"]) for r in robots], axis=0)
    after = np.flatnonzero((t >= scenario.task.t_grasp) & (f_n >= needed))
    return {"t_end": t_end, "needed_squeeze_per_pad_N": needed,
            "friction_carries_from_s": float(t[after[0]]) if after.size else None,
            "rows": rows}


def derived_scenario(path: Path):
    """The scenario of ``path`` with the gains ``drake-coop gains`` derives for it, and the
    derivation's report (``report.stable`` False: no gains passed the check)."""
    from drake_coop.stability.gains import derive_and_check, gains_for_scenario
    from drake_coop.stability.gains_cli import load_for_gains

    scenario = load_for_gains(str(path))
    report = derive_and_check(scenario)
    return gains_for_scenario(scenario, report.robots), report


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", help="scenario files without gains (.yaml)")
    parser.add_argument("--out", required=True)
    parser.add_argument("--case", help="the case's key in the file (one file only)")
    parser.add_argument("--lift-timeline", type=float, metavar="T_END",
                        help="instead of the measurement: the grasp and the lift to T_END s, "
                             "every 0.25 s (:func:`lift_timeline`), under STEM@lift")
    parser.add_argument("--squeeze", choices=("profile", "friction"),
                        help="the object model's squeeze source (a diagnosis: the key gets "
                             "@sq<squeeze>)")
    args = parser.parse_args(argv)
    if args.case is not None and len(args.files) != 1:
        parser.error("--case: names one case; give one scenario file with it")
    from importlib.metadata import version

    from bench.lab_arms_object import _cpu_name, contact_scenario
    from drake_coop.scenario.loading import dump_scenario

    out = Path(args.out)
    status = 0
    for name in args.files:
        start = time.process_time()
        scenario, report = derived_scenario(Path(name))
        gains = {"rho": report.rho, "stable": report.stable, "attempts": report.attempts,
                 "cpu_seconds": round(time.process_time() - start, 1),
                 "robots": {d.name: {"K_R": [float(k) for k in d.gains.K_R],
                                     "Lambda": d.gains.Lambda, "k_d": d.gains.k_d,
                                     "xi": d.gains.xi} for d in report.robots}}
        case: dict = {"scenario": name, "gains": gains}
        if report.stable:
            tmp = out.parent / f".{Path(name).stem}.derived.yaml"
            out.parent.mkdir(parents=True, exist_ok=True)
            tmp.write_text(dump_scenario(scenario))
            try:                                          # as bench.lab_arms_object sets it up
                scenario = contact_scenario(str(tmp), squeeze=args.squeeze)
            finally:
                tmp.unlink()
            if args.lift_timeline is not None:
                case["lift_timeline"] = lift_timeline(scenario, args.lift_timeline)
            else:
                case.update(measure_with_lift(scenario))
                case["bars"] = verdicts(case)
                case["passes"] = all(v["passes"] for v in case["bars"].values())
        else:
            status = 1
        case["command"] = ("python -m bench.unseen_arms " + " ".join(sys.argv[1:])
                           if argv is None else "")
        case["drake"] = version("drake")
        case["cpu"] = _cpu_name()
        data = json.loads(out.read_text()) if out.exists() else {"cases": {}}
        key = (Path(name).stem + (f"@sq{args.squeeze}" if args.squeeze else "")
               + ("@lift" if args.lift_timeline is not None else ""))
        data["cases"][args.case or key] = case
        out.parent.mkdir(parents=True, exist_ok=True)
        part = out.with_suffix(".tmp")
        part.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
        part.replace(out)
        print(name, json.dumps(case), flush=True)
    return status


if __name__ == "__main__":
    raise SystemExit(main())
