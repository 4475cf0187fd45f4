"""MAP SDP and DIDIM on robot 1 of ``realistic.yaml`` with and without encoder noise.

``python bench/didim_noise.py --out docs/results/didim_noise.json [--duration 2]
[--noise 0 0.001]`` identifies robot 1 of ``scenarios/realistic.yaml`` (its 31 µrad encoders,
35 N·m torque limits, a controller model 10 % heavy) from ``--duration`` s of excitation with
each estimator (``map_sdp``, ``didim``) at each encoder noise level (rad, 1-sigma), and writes
per case: the model torque error on the validation trajectory (identified and nominal, N·m),
the forearm composite's first-moment error (%) and the share of the excitation's ticks on
which the commanded torque reached a joint's limit. ``docs/identification.md`` reads its
numbers from the JSON this writes.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def one_case(estimator: str, noise: float, duration: float) -> dict:
    """One identification of robot 1 and its numbers."""
    from drake_coop.identification.report import identify_robot
    from drake_coop.scenario.loading import load_scenario

    scenario = load_scenario(ROOT / "scenarios" / "realistic.yaml")
    scenario.robots[0].encoders.noise_std = noise
    start = time.process_time()
    ident = identify_robot(scenario, 0, duration, estimator=estimator)
    s, th, tr = ident.structure, ident.estimate.theta, ident.theta_true
    k = 10 * (len(s.links) - 1) + 3                   # the forearm composite's h_z
    tau = np.asarray(ident.data.tau)
    limits = np.asarray(scenario.robots[0].actuators.torque_limits, float)
    at_limit = np.any(np.abs(tau) >= limits - 1e-9, axis=1)
    return {"estimator": estimator, "noise_std": noise, "duration": duration,
            "first_moment_error_pct": float(100.0 * (th[k] / tr[k] - 1.0)),
            **ident.validation,
            "ticks_at_torque_limit": float(np.mean(at_limit)),
            "cpu_time_s": time.process_time() - start}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", required=True)
    parser.add_argument("--duration", type=float, default=2.0)
    parser.add_argument("--noise", type=float, nargs="+", default=[0.0, 1e-3])
    args = parser.parse_args()
    cases = {}
    for noise in args.noise:
        for estimator in ("map_sdp", "didim"):
            case = one_case(estimator, noise, args.duration)
            cases[f"{estimator}_noise_{1e3 * noise:g}mrad"] = case
            print(json.dumps(case))
    Path(args.out).write_text(json.dumps(cases, indent=1) + "\n")


if __name__ == "__main__":
    main()
