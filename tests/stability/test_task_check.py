"""``drake-coop gains`` checks the task (:mod:`drake_coop.stability.task_check`): each check
fails on a case made to fail it, naming where and what to change, and the shipped paper arms
pass every check with their own gains."""

import copy
import json

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.experiment.plan import plan_run
from drake_coop.plant.arms import arm_model
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.resources import find_scenario
from drake_coop.stability.task_check import _check_torque, check_task, map_points


def _peak_torque(scenario, index):
    """The largest |τ| per joint of the law's feedforward along the reference, computed here
    by Drake's inverse dynamics on the arm's own plant (the independent side)."""
    plan = plan_run(scenario)
    arm = plan.arms[index]
    model = arm_model(arm, arm.urdf_path)
    t, r = plan.robots[index].samples
    n = model.plant.num_velocities()
    q, v, a = r[:, :n], r[:, n:2 * n], r[:, 2 * n:3 * n]
    lam, held = r[:, 3 * n:3 * n + arm.m], r[:, -1:]
    context = model.plant.CreateDefaultContext()
    from pydrake.multibody.tree import MultibodyForces

    peak = np.zeros(n)
    for k in range(0, len(t), 10):
        model.plant.SetPositions(context, q[k])
        model.plant.SetVelocities(context, v[k])
        forces = MultibodyForces(model.plant)
        model.plant.CalcForceElementsContribution(context, forces)
        tau = model.plant.CalcInverseDynamics(context, a[k], forces)
        tau = tau - model.J_phi(q[k]).T @ (lam[k] * held[k])
        peak = np.maximum(peak, np.abs(tau))
    return peak


def test_the_torque_check_refuses_a_limit_below_the_path_and_names_the_joint():
    s = load_scenario(find_scenario("paper"))
    peak = _peak_torque(s, 0)
    j = int(np.argmax(peak))
    limits = [1e3] * len(peak)
    limits[j] = 0.9 * peak[j]
    s.robots[0].actuators.torque_limits = limits
    check = _check_torque(s)
    assert not check.passes
    assert check.message.startswith("torque limits: robots[0] (robot1): at t = ")
    assert f"joint {j + 1} needs" in check.message and "beyond its torque limit" in check.message
    limits[j] = 1.1 * peak[j]                 # just above the path's need: passes
    assert _check_torque(s).passes


def test_the_torque_check_of_a_contact_run_is_the_runs_squeeze_check():
    s = load_scenario(find_scenario("contact"))
    s.robots[1].actuators.torque_limits = [2.0, 2.0, 2.0]
    check = _check_torque(s)
    assert not check.passes and "robots[1] (robot2)" in check.message


def test_the_map_is_sampled_along_the_lift_and_the_circle():
    task = load_scenario().task
    points = map_points(task)
    assert [p[1] for p in points] == ["free"] + ["held"] * 5
    times = [p[2] for p in points[1:]]
    assert task.t_grasp < times[0] < task.t_circle_start
    assert times[1] == task.t_circle_start and max(times) < task.t_circle_end


@pytest.mark.slow
def test_a_stiff_gain_fails_the_map_naming_the_posture():
    s = load_scenario(find_scenario("paper"))
    for robot in s.robots:
        robot.gains.K_R = [4.0 * k for k in robot.gains.K_R]   # h K_R / J beyond 2
    report = check_task(s)
    check = next(c for c in report.checks if c.name == "map")
    assert not check.passes and ">= 1" in check.message and "t = " in check.message
    assert report.refusal == check.message


@pytest.mark.slow
def test_the_paper_arms_pass_every_task_check_with_their_gains():
    for name in ("paper", "contact"):
        s = load_scenario(find_scenario(name))
        before = copy.deepcopy([r.gains for r in s.robots])
        report = check_task(s)
        assert report.passes, report.refusal
        assert {c.name for c in report.checks} == (
            {"torque", "map", "grasp"} if name == "contact" else {"torque", "map"})
        assert [r.gains for r in s.robots] == before         # checked, not changed
        rho = next(c for c in report.checks if c.name == "map").values["rho"]
        assert len(rho) == 6 and max(rho.values()) < 1.0


def test_gains_refuses_a_task_beyond_the_torque_limits_in_one_line(tmp_path, capsys,
                                                                    monkeypatch):
    from drake_coop.stability import gains as rules

    # The map at home and the held start passes (its computation is another test's): with
    # 2 N·m the map's own loop saturates, and the refusal to test is the task's.
    monkeypatch.setattr(rules, "check_gains_map", lambda *a, **k: {"free": 0.5, "held": 0.5})
    s = load_scenario(find_scenario("contact"))
    s.robots[0].actuators.torque_limits = [2.0, 2.0, 2.0]
    path = tmp_path / "weak.yaml"
    path.write_text(dump_scenario(s))
    out = tmp_path / "out"
    assert main(["gains", str(path), "--out", str(out), "--quiet"]) == 1
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("drake-coop: gains: refused: torque limits: robots[0] (robot1)")
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "refused" and meta["refusal"] in last
    # neither the grasp's dynamics nor the map is run once the torque check has failed
    assert [c["name"] for c in meta["task_checks"]] == ["torque"]
