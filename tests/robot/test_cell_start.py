"""The per-arm cell started skewed, as a user starts it: the hub, the lockstep driver and one
``serve`` per arm, each its own process, the second ``serve`` started 2 s after the first,
in both orders; then a stop on the serves' stop channel (what every trip sends). In
lockstep (simulated time on both sides), so the same on any load:

- no arm moves before its own ``serve`` commands it: the driver holds each arm and the run
  begins at the start posture, at rest;
- the first commands are bounded: tick ``k`` of the ``N`` ramp ticks carries at most
  ``(k/N) (|τ_hold| + τ_lim)`` on each joint beyond the wire's hold torque (``τ_hold`` the
  controller model's gravity torque at the first reading, ``τ_lim`` the joint's torque
  limit: the ramp blends the hold into the controller's command, itself within
  ``τ_lim``); tick 0 carries the hold torque exactly (0 on the wire of a robot that adds
  its own gravity);
- a trip leaves every arm at rest: the serves stop (exit 1, naming the stop), the driver
  runs on without commands (the last one expires; gravity compensation and damping) and the
  arms come to rest where they were, not at their joint stops.

The paced cell (wall clock, load-dependent) is measured in ``bench/cell_start.py``."""

import json
import math
import subprocess
import sys
import time

import numpy as np
import pytest

from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.simulate import rest_posture
from drake_coop.robot.driver_spec import driver_specs
from drake_coop.robot.lockstep import HOLD_AFTER_STOP
from drake_coop.robot.serve_loop import STOP_CHANNEL, ServeLoop, StopListener
from drake_coop.scenario.cell import CellSettings
from drake_coop.scenario.loading import load_scenario
from drake_coop.scenario.model_check import check_models

CLI = [sys.executable, "-m", "drake_coop"]
SKEW = 2.0


def skewed_cell(tmp_path, first: str, second: str) -> dict:
    """Run the cell (see the module); returns the exit codes, the ``drake-coop:`` lines, the
    serves' ``run.json`` and the driver's ground truth."""
    from drake_coop.robot.hub_link import WatchedLcm

    hub = subprocess.Popen(CLI + ["tcpq-hub", "--port", "0"], stderr=subprocess.PIPE,
                           text=True)
    procs = {"hub": hub}
    truth = tmp_path / "truth.npz"
    try:
        url = hub.stderr.readline().split("--lcm-url ")[1].rstrip(")\n")
        common = ["--lcm-url", url, "--lockstep", "--t-end", "30"]
        procs["driver"] = subprocess.Popen(
            CLI + ["sim-driver", "paper", *common, "--quiet", "--log", str(truth),
                   "--command-wait", "120"], stderr=subprocess.PIPE, text=True)
        for robot in (first, second):
            procs[robot] = subprocess.Popen(
                CLI + ["serve", "paper", *common, "--out", str(tmp_path / robot), "--robot",
                       robot, "--delay-margin", "0.002", "--status-wait", "120"],
                stderr=subprocess.PIPE, text=True)
            if robot == first:
                time.sleep(SKEW)
        lines = {}
        for robot in (first, second):          # until each says it is serving
            lines[robot] = []
            for line in procs[robot].stderr:
                lines[robot].append(line.rstrip())
                if "drake-coop: serving" in line:
                    break
        time.sleep(0.5)
        operator = WatchedLcm(url)             # a stop, as a tripped serve sends it
        StopListener.publish(operator, "operator", "a test's stop", session="5e55101d")
        codes = {}
        for name in (first, second, "driver"):
            codes[name] = procs[name].wait(300)
            lines.setdefault(name, []).extend(procs[name].stderr.read().splitlines())
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait(30)
    meta = {r: json.loads((tmp_path / r / "run.json").read_text()) for r in (first, second)}
    return {"codes": codes, "lines": {n: [x for x in v if x.startswith("drake-coop:")]
                                      for n, v in lines.items()},
            "meta": meta, "truth": dict(np.load(truth))}


@pytest.mark.slow
@pytest.mark.parametrize("first, second", [("robot1", "robot2"), ("robot2", "robot1")])
def test_a_skewed_per_arm_cell_holds_ramps_and_comes_to_rest(tmp_path, first, second):
    run = skewed_cell(tmp_path, first, second)
    for robot in (first, second):
        assert run["codes"][robot] == 1, run["lines"][robot]
        assert run["meta"][robot]["watchdog"]["channel"] == STOP_CHANNEL, (
            run["meta"][robot]["message"], run["lines"])
    assert run["codes"]["driver"] == 1, run["lines"]["driver"]
    assert any(f"stop on {STOP_CHANNEL}" in x for x in run["lines"]["driver"])
    truth = run["truth"]
    scenario = load_scenario()
    plan = plan_run(scenario, 30)
    rest, _ = rest_posture(plan)
    specs = driver_specs(scenario, check_models(scenario))
    from pydrake.lcm import DrakeLcm

    loop = ServeLoop(plan, DrakeLcm("memq://"), specs)
    n_ramp = math.ceil(CellSettings().start_ramp / plan.h - 1e-9)
    assert n_ramp >= 2
    t = truth["t"]
    assert t[-1] >= HOLD_AFTER_STOP                     # the hold after the stop ran
    for i, spec in enumerate(loop.specs):
        x, tau = truth[f"arm{i}_state"], truth[f"arm{i}_tau_commanded"]
        n = spec.n
        # the start: at the start posture, at rest (nothing moved before the commands)
        np.testing.assert_allclose(x[0, :n], rest[i], atol=1e-9)
        np.testing.assert_array_equal(x[0, n:], 0.0)
        # the ramp's bound, tick by tick (row r holds a command of tick <= r)
        hold = np.asarray(loop.side.arms[i].hold_torque(np.asarray(rest[i], float)))
        wire_hold = hold - (hold if spec.gravity == "robot_adds" else 0.0)
        bound = np.abs(hold) + np.asarray(spec.torque_limits)
        assert np.linalg.norm(hold) > 1.0                 # gravity: a bound that can fail
        for r in range(n_ramp + 1):
            assert np.all(np.abs(tau[r] - wire_hold) <= r / n_ramp * bound + 1e-9), (i, r)
        np.testing.assert_allclose(tau[1], wire_hold, atol=1e-9)   # tick 0: the hold
        # after the stop: at rest, near where the arm was, not at its stops
        assert np.max(np.abs(x[-1, n:])) < 1e-2, (i, x[-1, n:])
        stopped = np.searchsorted(t, t[-1] - HOLD_AFTER_STOP)
        assert np.max(np.abs(x[-1, :n] - x[stopped, :n])) < 0.2, (i, x[-1, :n])
