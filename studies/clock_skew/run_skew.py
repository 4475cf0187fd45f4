"""The arms' clocks: the squeeze error of the split run (controller side and
simulated drivers joined by LCM, ``drake_coop.robot.loopback``) against the skew between the two
drivers' 1 kHz clocks, without and with delay compensation.

Compressed task (circle 2-4 s, as ``tests/robot/test_loopback.py``), plant step 0.25 ms so that a
driver's phase acts (to within one plant step); robot1's driver at phase 0.125 ms, robot2's at
0.125 ms + skew (events between plant steps: the same rounding for every row); one row with
robot2's clock drifting 2.5e-4 (its phase walks through a whole cycle in 4 s). In ``planes``
mode (the paper's model) each arm is on its own plane and a skew changes only the skewed arm's
own loop; ``rigid`` (the second argument) couples the arms through the object.

    .venv/bin/python studies/clock_skew/run_skew.py OUT.csv [planes|rigid]
"""

import csv
import sys
import time

import numpy as np

from drake_coop.robot.loopback import run_loopback, squeeze_error
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.driver import Driver

T_END = 4.0
BASE_PHASE = 1.25e-4
CASES = [(skew, 0.0) for skew in (0.0, 2.5e-4, 5e-4, 7.5e-4)] + [(0.0, 2.5e-4)]


def scenario(skew: float, drift: float, horizon, mode: str = "planes"):
    s = load_scenario()
    s.plant.object_mode = mode
    t = s.task
    t.t_pregrasp, t.t_grasp, t.t_circle_start = 1.0, 1.5, 2.0
    t.t_circle_end, t.t_release, t.t_end = 4.0, 4.5, 6.0
    t.force_omega = 3 * np.pi / 2.0
    s.plant.time_step = 2.5e-4
    for i, robot in enumerate(s.robots):
        robot.driver = Driver(clock_phase=BASE_PHASE + (skew if i == 1 else 0.0),
                              clock_drift=drift if i == 1 else 0.0)
        robot.timing.prediction_horizon = horizon
    return load_scenario(data=dump_scenario(s))


def main(out: str, mode: str = "planes", horizons=(None, 0.003), cases=CASES) -> None:
    rows = []
    for horizon in horizons:
        for skew, drift in cases:
            s = scenario(skew, drift, horizon, mode)
            start = time.perf_counter()
            r = run_loopback(s, T_END)
            e = squeeze_error(r.logs, s)
            row = {"object_mode": mode, "prediction_horizon": horizon if horizon is not None else "", "skew_s": skew,
                   "drift": drift, "status": r.status,
                   **{f"squeeze_rms_{k}": v for k, v in e.items()},
                   "squeeze_rms_worst": max(e.values()),
                   "wall_time_s": round(time.perf_counter() - start, 1)}
            print(row, flush=True)
            rows.append(row)
    with open(out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


if __name__ == "__main__":
    mode = sys.argv[2] if len(sys.argv) > 2 else "planes"
    main(sys.argv[1], mode, cases=CASES if mode == "planes" else [(0.0, 0.0), (5e-4, 0.0)])
