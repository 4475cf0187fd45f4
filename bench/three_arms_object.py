"""Three arms carry a prism by friction: squeeze, path, slips, drops and mass estimate.

Runs ``scenarios/three_arms_contact.yaml`` (three CRS A255 arms 120° apart, a triangular prism
held only by friction at hydroelastic pads, 3 ms plant step) with ``object_model: {mode:
estimated}`` to the circle's end (+1 s): the shipped object (``shipped``) and ``--draws``
paired draws of mass (uniform in 0.2–1.5 kg) and friction (uniform in 0.5–1.0) from
``--seed`` (``--time-step``: at another plant step; ``--squeeze``: another
``object_model.squeeze``); writes, per case, the circle phase's metrics, the lift's and
circle's slips and drops, the lift's largest slip and cone use, and the mass estimate at the
lift's end to a JSON file::

    python -m bench.three_arms_object --draws 4 --out docs/results/three_arms_object.json

Each case is written as soon as it ends, with its command, the drake version and the CPU (the
file keeps the cases of other calls).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from bench.lab_arms_object import _cpu_name, contact_scenario

#: The draws' ranges: object mass (kg) and friction coefficient.
MASS_RANGE, MU_RANGE = (0.2, 1.5), (0.5, 1.0)


def draws(n: int, seed: int) -> list[tuple[float, float]]:
    """``n`` draws ``(mass, μ)``, uniform in :data:`MASS_RANGE` × :data:`MU_RANGE`."""
    rng = np.random.default_rng(seed)
    return [(round(float(rng.uniform(*MASS_RANGE)), 3), round(float(rng.uniform(*MU_RANGE)), 3))
            for _ in range(n)]


def measure_case(mass: float | None, mu: float | None, mode: str = "estimated",
                 time_step: float | None = None, squeeze: str | None = None) -> dict:
    """One run of the three-arm scenario with ``mass`` and ``μ`` (None: the shipped ones),
    at the plant step ``time_step`` (None: the shipped one), with ``object_model.squeeze``
    ``squeeze`` (None: the default, the task's profile (29))."""
    import time

    from drake_coop.experiment.simulate import simulate
    from drake_coop.results.metrics import compute_metrics
    from drake_coop.scenario import validate

    scenario = contact_scenario("three_arms_contact")
    scenario.object_model.mode = mode
    if mass is not None:
        scenario.plant.object_mass = mass
    if mu is not None:
        scenario.plant.friction = mu
    if time_step is not None:
        scenario.plant.time_step = time_step
    if squeeze is not None:
        scenario.object_model.squeeze = squeeze
    validate(scenario)
    task = scenario.task
    start = time.process_time()
    result = simulate(scenario, t_end=task.t_circle_end + 1.0)
    cpu = time.process_time() - start
    metrics = compute_metrics(result.logs, result.meta)
    out: dict = {"status": result.meta["status"], "cpu_seconds": round(cpu, 1),
                 "object_mass_kg": float(scenario.plant.object_mass),
                 "friction": float(scenario.plant.friction), "mode": mode,
                 "plant_time_step": float(scenario.plant.time_step),
                 "squeeze": scenario.object_model.squeeze, "robots": {}}
    for robot in result.logs:
        circle = metrics[robot]["circle"]
        entry = {"squeeze_error_rms_N": circle["force_error"]["rms"]}
        for key in ("object_position_error", "object_turn", "object_tilt", "friction_use",
                    "slip"):
            if key in circle:
                entry[f"{key}_rms"] = circle[key]["rms"]
                entry[f"{key}_max"] = circle[key]["max"]
        lift = metrics[robot]["lift"]
        for key in ("slip", "friction_use"):
            if key in lift:
                entry[f"lift_{key}_max"] = lift[key]["max"]
        entry["slips"] = sum(metrics[robot][p].get("slips", {}).get("count", 0)
                             for p in ("lift", "circle"))
        entry["drops"] = sum(metrics[robot][p].get("drops", {}).get("count", 0)
                             for p in ("lift", "circle"))
        out["robots"][robot] = entry
    t = np.asarray(next(iter(result.logs.values()))["t"])
    k = int(np.searchsorted(t, task.t_circle_start - 1e-9)) - 1
    shares = [np.asarray(log["mass_share"])[k] for log in result.logs.values()
              if "mass_share" in log]
    if shares:
        out["mass_at_lift_end_kg"] = float(np.sum(shares))
        out["mass_error_at_lift_end"] = float(np.sum(shares) / out["object_mass_kg"] - 1.0)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True)
    parser.add_argument("--draws", type=int, default=4)
    parser.add_argument("--seed", type=int, default=33)
    parser.add_argument("--only", default=None, help="run only this case (shipped, draw1, …)")
    parser.add_argument("--mode", default="estimated", choices=("none", "known", "estimated"))
    parser.add_argument("--time-step", type=float, default=None,
                        help="the plant step (s); default the scenario's")
    parser.add_argument("--squeeze", default=None, choices=("profile", "friction"),
                        help="object_model.squeeze; default the scenario's")
    args = parser.parse_args(argv)
    out = Path(args.out)
    from importlib.metadata import version

    cases = [("shipped", None, None)] + [(f"draw{i + 1}", m, mu)
                                         for i, (m, mu) in enumerate(draws(args.draws,
                                                                           args.seed))]
    for name, mass, mu in cases:
        if args.only is not None and name != args.only:
            continue
        case = measure_case(mass, mu, args.mode, args.time_step, args.squeeze)
        case["command"] = ("python -m bench.three_arms_object " + " ".join(sys.argv[1:])
                           if argv is None else "")
        case["drake"] = version("drake")
        case["cpu"] = _cpu_name()
        key = name if args.mode == "estimated" else f"{name}_{args.mode}"
        if args.time_step is not None:
            key += f"_dt{args.time_step * 1e3:g}ms"
        if args.squeeze is not None:
            key += f"_{args.squeeze}"
        # Read again just before writing: another call may have added its cases meanwhile.
        data = json.loads(out.read_text()) if out.exists() else {"cases": {}}
        data["cases"][key] = case
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(f".{key}.tmp")
        tmp.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
        tmp.replace(out)
        print(key, json.dumps(case), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
