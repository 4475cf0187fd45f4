"""The per-arm cell started skewed, paced at real time: the hub, ``sim-driver`` (with
``--log``) and one ``serve`` per arm, each its own process, the second ``serve`` started
``--skew`` seconds after the first, in both orders; a stop sent on the serves' stop channel
``--stop-after`` seconds after both serve (what every trip sends); the driver runs on to its
``--t-end`` without commands. One results JSON::

    python -m bench.cell_start [--skew 2] [--sched fifo] [--out runs/cell_start] \\
        [--results docs/results/cell_start.json]

``--sched fifo`` runs the processes as ``bench/paced_split.py`` does (``chrt -f``: hub 70,
serves 60, driver 50); ``default`` at the default priority. From the driver's ground truth
(``--log``), per arm:

- ``moved_before_command_rad`` / ``speed_before_command_rad_s``: the largest joint offset
  from the first row and the largest joint speed over the rows before the arm's first
  non-zero command (the ramp's tick 1: tick 0 carries the wire's hold torque, 0 where the
  robot adds its own gravity) — the driver's hold before its ``serve`` commands it;
- ``ramp_bound_use``: over the ramp's rows and the joints, the largest ``|τ − τ_hold,wire|
  / ((k/N)(|τ_hold| + τ_lim))`` (≤ 1: the bound holds; ``k`` counted from the row of the
  arm's first non-zero command, an upper bound of the tick it carries), the largest
  command over those rows (``ramp_max_command_Nm``, on the wire) and the bound itself;
- ``speed_end_rad_s`` / ``drift_after_stop_rad``: the largest joint speed at the driver's end
  and the largest joint motion between the stop and the end — the arms at rest, not fallen.

Wall-clock behaviour, so a benchmark, not a test: which process stops first and when
depends on the machine's load (recorded: ``/proc/loadavg``). Exit 0 once every case ran.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

CLI = [sys.executable, "-m", "drake_coop"]
PRIORITY = {"hub": 70, "serve": 60, "driver": 50}


def run_case(out: Path, first: str, second: str, skew: float, stop_after: float,
             t_end: float, sched: str) -> dict:
    """One skewed start (see the module).

    Parameters
    ----------
    out : Path
        The case's folder (the serves' run folders, the driver's ``truth.npz``).
    first, second : str
        The arms in start order.
    skew : float
        Seconds between the two ``serve`` starts.
    stop_after : float
        Seconds after both serve before the stop.
    t_end : float
        The driver's end, s of simulated time.
    sched : str
        ``fifo`` or ``default``.

    Returns
    -------
    dict
        Exit codes, ``drake-coop:`` lines, the serves' stop reasons and the per-arm numbers.
    """
    from drake_coop.robot.hub_link import WatchedLcm
    from drake_coop.robot.serve_loop import StopListener

    out.mkdir(parents=True, exist_ok=True)

    def prefix(role):
        return ["chrt", "-f", str(PRIORITY[role])] if sched == "fifo" else []

    hub = subprocess.Popen(prefix("hub") + CLI + ["tcpq-hub", "--port", "0"],
                           stderr=subprocess.PIPE, text=True)
    procs = {"hub": hub}
    truth = out / "truth.npz"
    lines: dict[str, list[str]] = {}
    load: dict[str, float] = {}
    try:
        url = hub.stderr.readline().split("--lcm-url ")[1].rstrip(")\n")
        common = ["--lcm-url", url]
        procs["driver"] = subprocess.Popen(
            prefix("driver") + CLI + ["sim-driver", "paper", *common, "--t-end", f"{t_end:g}",
                                      "--quiet", "--log", str(truth), "--command-wait", "120"],
            stderr=subprocess.PIPE, text=True)
        for robot in (first, second):
            procs[robot] = subprocess.Popen(
                prefix("serve") + CLI + ["serve", "paper", *common, "--t-end", "60", "--out",
                                         str(out / robot), "--robot", robot,
                                         "--status-wait", "120"],
                stderr=subprocess.PIPE, text=True)
            if robot == first:
                time.sleep(skew)
        for robot in (first, second):
            lines[robot] = []
            for line in procs[robot].stderr:
                lines[robot].append(line.rstrip())
                if "drake-coop: serving" in line or "drake-coop: stopped" in line:
                    break
        time.sleep(stop_after)
        load["at_stop"] = float(open("/proc/loadavg").read().split()[0])
        operator = WatchedLcm(url)
        StopListener.publish(operator, "operator", "a stop sent by the benchmark",
                             session="be4c0001")
        codes = {}
        for name in (first, second, "driver"):
            codes[name] = procs[name].wait(t_end + 300)
            lines.setdefault(name, []).extend(procs[name].stderr.read().splitlines())
        load["at_end"] = float(open("/proc/loadavg").read().split()[0])
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait(30)
    meta = {}
    for r in (first, second):
        path = out / r / "run.json"
        meta[r] = json.loads(path.read_text()) if path.exists() else None
    return {"order": [first, second], "skew_s": skew, "sched": sched, "codes": codes,
            "lines": {n: [x for x in v if x.startswith("drake-coop:")] for n, v in lines.items()},
            "stops": {r: (m or {}).get("message") for r, m in meta.items()},
            "loadavg": load, "arms": arm_numbers(dict(np.load(truth)), t_end)}


def arm_numbers(truth: dict, t_end: float) -> dict:
    """The per-arm numbers of the module's list from the driver's ground truth.

    Parameters
    ----------
    truth : dict
        ``sim-driver --log``'s arrays.
    t_end : float
        The driver's end, s.

    Returns
    -------
    dict
        Per arm (``robot1``, ``robot2``): the numbers, floats.
    """
    from pydrake.lcm import DrakeLcm

    from drake_coop.experiment.plan import plan_run
    from drake_coop.robot.driver_spec import driver_specs
    from drake_coop.robot.serve_loop import ServeLoop
    from drake_coop.scenario.cell import CellSettings
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.model_check import check_models

    scenario = load_scenario()
    plan = plan_run(scenario, t_end)
    loop = ServeLoop(plan, DrakeLcm("memq://"), driver_specs(scenario, check_models(scenario)))
    n_ramp = math.ceil(CellSettings().start_ramp / plan.h - 1e-9)
    t = truth["t"]
    out = {}
    for i, spec in enumerate(loop.specs):
        x, tau = truth[f"arm{i}_state"], truth[f"arm{i}_tau_commanded"]
        n = spec.n
        nonzero = np.flatnonzero(np.any(tau != 0.0, axis=1))
        r0 = int(nonzero[0]) if nonzero.size else len(t)
        before = x[:max(r0 - 1, 1)]
        hold = np.asarray(loop.side.arms[i].hold_torque(x[0, :n]))
        wire_hold = hold - (hold if spec.gravity == "robot_adds" else 0.0)
        bound = np.abs(hold) + np.asarray(spec.torque_limits)
        use = [float(np.max(np.abs(tau[r] - wire_hold)
                            / (min(r - r0 + 1, n_ramp) / n_ramp * bound)))
               for r in range(r0, min(r0 + n_ramp, len(t)))]
        last_cmd = int(nonzero[-1]) if nonzero.size else 0
        out[spec.robot] = {
            "first_command_t_s": float(t[r0]) if r0 < len(t) else None,
            "moved_before_command_rad": float(np.max(np.abs(before[:, :n] - x[0, :n]))),
            "speed_before_command_rad_s": float(np.max(np.abs(before[:, n:]))),
            "ramp_bound_use": max(use) if use else None,
            "ramp_max_command_Nm": float(np.max(np.abs(tau[r0:r0 + n_ramp]))) if use else None,
            "bound_min_Nm": float(np.min(bound)),
            "last_command_t_s": float(t[last_cmd]),
            "speed_end_rad_s": float(np.max(np.abs(x[-1, n:]))),
            "drift_after_stop_rad": float(np.max(np.abs(x[-1, :n] - x[last_cmd, :n]))),
            "t_end_s": float(t[-1])}
    return out


def main(argv=None) -> int:
    """Run both start orders and write the JSON.

    Parameters
    ----------
    argv : list of str or None
        The command line (None: ``sys.argv``).

    Returns
    -------
    int
        0.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skew", type=float, default=2.0)
    parser.add_argument("--stop-after", type=float, default=1.0)
    parser.add_argument("--t-end", type=float, default=6.0)
    parser.add_argument("--sched", choices=("fifo", "default"), default="fifo")
    parser.add_argument("--out", default="runs/cell_start")
    parser.add_argument("--results", default=None)
    args = parser.parse_args(argv)
    cases = {}
    for first, second in (("robot1", "robot2"), ("robot2", "robot1")):
        key = f"{first}_first"
        cases[key] = run_case(Path(args.out) / key, first, second, args.skew,
                              args.stop_after, args.t_end, args.sched)
    result = {"about": ("The per-arm cell of the paper's scenario, paced at real time on a "
                        "shared 2-core machine: the second serve started skew_s after the "
                        "first, in both orders; a stop sent once both serve; the driver's "
                        "ground truth (bench/cell_start.py)."),
              "cpus": len(os.sched_getaffinity(0)), "cases": cases}
    text = json.dumps(result, indent=1, default=float)
    print(text)
    if args.results:
        Path(args.results).write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
