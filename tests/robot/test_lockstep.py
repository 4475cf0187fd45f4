"""Lockstep over the wire (:mod:`drake_coop.robot.lockstep`): ``serve --lockstep`` and
``sim-driver --lockstep`` as two processes joined by the project's tcpq hub on 127.0.0.1
give the one-process loopback run (:func:`~drake_coop.robot.loopback.run_loopback`) on any
machine, however loaded: the arms' positions, the commands the driver held and the squeeze,
tick by tick."""

import subprocess
import sys

import numpy as np
import pytest

from drake_coop.robot.lockstep import status_time
from drake_coop.robot.loopback import run_loopback, squeeze_error
from drake_coop.robot.tcpq_hub import TcpqHub
from drake_coop.scenario.cell import CellSettings
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.resources import find_scenario

CLI = [sys.executable, "-m", "drake_coop"]


def two_processes(tmp_path, scenario_path, t_end, extra=()):
    """The hub (a thread here), the simulated driver and serve (processes), in lockstep.
    ``serve``'s start ramp is turned off (``cell.start_ramp: 0``): the one-process loopback
    run it is compared with commands the controller's torque from tick 0."""
    s = load_scenario(scenario_path)
    s.cell = CellSettings(start_ramp=0.0)
    scenario_path = tmp_path / "lockstep.yaml"
    scenario_path.write_text(dump_scenario(s))
    hub = TcpqHub(0).start()
    truth = tmp_path / "truth.npz"
    common = ["--lcm-url", hub.url, "--lockstep", "--t-end", str(t_end), "--quiet"]
    try:
        driver = subprocess.Popen(CLI + ["sim-driver", str(scenario_path), *common,
                                         "--log", str(truth), "--command-wait", "60", *extra],
                                  stderr=subprocess.PIPE, text=True)
        serve = subprocess.Popen(CLI + ["serve", str(scenario_path), *common, "--out",
                                        str(tmp_path / "run"), "--delay-margin", "0.002",
                                        "--status-wait", "60"],
                                 stderr=subprocess.PIPE, text=True)
        serve_err = serve.communicate(timeout=1800)[1]
        driver_err = driver.communicate(timeout=120)[1]
    finally:
        for proc in ("driver", "serve"):
            p = locals().get(proc)
            if p is not None and p.poll() is None:
                p.kill()
        hub.stop()
    assert serve.returncode == 0, serve_err
    assert driver.returncode == 0, driver_err
    return dict(np.load(truth))


def assert_same_run(logs, truth, rel=1e-6):
    for i, (name, log) in enumerate(logs.items()):
        n = len(log["t"])
        for key, theirs in (("q", truth[f"arm{i}_state"][:n, :log["q"].shape[1]]),
                            ("tau_commanded", truth[f"arm{i}_tau_commanded"][:n]),
                            ("lambda_meas", truth["lambda"][:n, i].reshape(
                                np.shape(log["lambda_meas"])))):
            ours = np.asarray(log[key], dtype=float)
            scale = max(np.max(np.abs(ours)), 1e-12)
            assert theirs.shape == ours.shape, (name, key, theirs.shape, ours.shape)
            assert np.max(np.abs(theirs - ours)) <= rel * scale, (name, key)


def compressed(name, path, scenario=None):
    s = load_scenario(find_scenario(name)) if scenario is None else scenario
    t = s.task
    t.t_pregrasp, t.t_grasp, t.t_circle_start = 1.0, 1.5, 2.0
    t.t_circle_end, t.t_release, t.t_end = 4.0, 4.5, 6.0
    t.force_omega = 3 * np.pi / 2.0
    path.write_text(dump_scenario(load_scenario(data=dump_scenario(s))))
    return load_scenario(path)


def test_each_tick_reads_the_status_of_its_own_driver_cycle():
    from drake_coop.robot.driver_spec import DriverSpec

    spec = DriverSpec("r", "panda", "S", "C", 3, 1e-3, None, 0.05, 0.1, "hold")
    assert status_time(spec, 0.0) == 0.0
    assert status_time(spec, 0.009) == pytest.approx(0.009, abs=1e-12)
    late = DriverSpec("r", "panda", "S", "C", 3, 1e-3, None, 0.05, 0.1, "hold",
                      clock_phase=4e-4)
    assert status_time(late, 0.0) is None
    assert status_time(late, 0.009) == pytest.approx(0.0084, abs=1e-12)


def test_two_processes_in_lockstep_give_the_loopback_run(tmp_path):
    """The paper's scenario, 0.3 s: the two processes' run equals the one-process run."""
    s = load_scenario()
    path = tmp_path / "paper.yaml"
    path.write_text(dump_scenario(s))
    truth = two_processes(tmp_path, path, 0.3)
    run = run_loopback(s, 0.3)
    assert run.status == "ok", run.message
    assert_same_run(run.logs, truth)
    moved = max(np.max(np.abs(log["q"] - log["q"][0])) for log in run.logs.values())
    assert moved > 1e-6                        # the arms moved: a comparison that can fail


def test_a_plant_step_of_three_driver_cycles_in_lockstep(tmp_path):
    """The paper's scenario with the plant stepped every 3 ms, 0.1 s: the times of one
    instant round apart (the tick ``2*0.009`` is an ulp short of the driver's cycle
    ``18*0.001``, where the plant's update ``6*0.003`` falls), yet the two processes' run
    equals the one-process run to the last bit. (With the status published at the cycle
    itself, it held the state after that plant update in both runs; ``serve --lockstep`` fed
    tick 2 that cycle's status, the one-process tick, an ulp earlier, the cycle before: the
    runs parted there.)"""
    s = load_scenario()
    s.plant.time_step = 0.003
    assert 2 * 0.009 < 18 * 0.001 and 18 * 0.001 == 6 * 0.003      # the premise
    path = tmp_path / "paper3.yaml"
    path.write_text(dump_scenario(s))
    truth = two_processes(tmp_path, path, 0.1)
    run = run_loopback(s, 0.1)
    assert run.status == "ok", run.message
    assert_same_run(run.logs, truth, rel=0.0)
    moved = max(np.max(np.abs(log["q"] - log["q"][0])) for log in run.logs.values())
    assert moved > 1e-9                        # the arms moved: a comparison that can fail


def _circle(tmp_path, name, t_end=2.6, emulate=None, low_pass_hz=None, scenario=None):
    s = compressed(name, tmp_path / f"{name}.yaml", scenario)
    extra = [] if emulate is None else ["--emulate", emulate]
    extra += [] if low_pass_hz is None else ["--low-pass-freq", str(low_pass_hz)]
    truth = two_processes(tmp_path, tmp_path / f"{name}.yaml", t_end, extra)
    run = run_loopback(s, t_end, emulate=emulate, low_pass_hz=low_pass_hz)
    assert run.status == "ok", run.message
    assert_same_run(run.logs, truth)
    theirs = {n: dict(log, lambda_meas=truth["lambda"][:len(log["t"]), i].reshape(
        np.shape(log["lambda_meas"]))) for i, (n, log) in enumerate(run.logs.items())}
    ours, other = squeeze_error(run.logs, s), squeeze_error(theirs, s)
    for robot in ours:
        assert np.isfinite(ours[robot]) and ours[robot] > 0
        assert abs(other[robot] - ours[robot]) <= 1e-6 * ours[robot], (robot, ours, other)


@pytest.mark.slow
def test_the_paper_circle_in_lockstep(tmp_path):
    _circle(tmp_path, "paper")


def _have_robots() -> bool:
    from drake_coop.control.arm_plant import description_packages

    return "example-robot-data" in description_packages()


ROBOTS = pytest.mark.skipif(not _have_robots(), reason="example-robot-data is not installed "
                                                       '(pip install -e ".[robots]")')


@pytest.mark.slow
@ROBOTS
def test_two_pandas_carrying_the_box_in_lockstep(tmp_path):
    _circle(tmp_path, "two_pandas")


@pytest.mark.slow
@ROBOTS
def test_two_pandas_behind_the_emulated_franka_driver_in_lockstep(tmp_path):
    """drake-franka-driver emulated (its filter off: with it the loop is unstable, see
    bench/franka_emulation.py), as two processes and in one."""
    _circle(tmp_path, "two_pandas", emulate="drake-franka-driver", low_pass_hz=1000.0)


@pytest.mark.slow
@ROBOTS
def test_a_lab_arm_pair_in_lockstep(tmp_path):
    _circle(tmp_path, "two_ur5")


def lab_pair(row):
    """A lab pair nothing here ships, set up as the lab-arms guide says: the every-arm
    benchmark's row ``row`` as it is (each arm's entry from ``drake-coop arms --yaml``, placed
    facing the box, the gains ``drake-coop gains`` derived), carrying the box: ``contact``
    mode, the row's own plant step (3 ms, a third of the tick: ``j Δt`` and ``k h`` round
    differently on some ticks) and its object model (the mass estimated)."""
    from bench.delay_margins import every_arm_cases

    s = every_arm_cases()[f"every_arm/{row}"]()
    assert s.plant.object_mode == "contact" and s.plant.time_step == pytest.approx(0.003)
    assert s.object_model.mode == "estimated"
    return s


@pytest.mark.slow
@ROBOTS
def test_a_lab_pair_nothing_ships_in_lockstep(tmp_path):
    """A UR5 and a Unitree Z1 on one box (``drake-coop arms --yaml ur5``, ``--yaml z1``):
    the two processes' run equals the one-process run with the same delay."""
    s = lab_pair("mixed")
    assert [r.name for r in s.robots] == ["ur5_1", "z1_2"]
    assert not any(find_scenario(n).read_text().count("z1_description")
                   for n in ("paper", "two_ur5", "two_pandas", "contact"))
    _circle(tmp_path, "mixed", scenario=s)
