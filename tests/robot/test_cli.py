"""``drake-coop serve`` / ``sim-driver``: bad input exits 2 naming the field; Ctrl-C, SIGTERM
and a watchdog trip end with the safe command sent (in-process, ``memq://`` only: the test
plays the driver inside the serve loop's LCM pump)."""

import json
import os
import signal

import numpy as np
import pytest
from pydrake.lcm import DrakeLcm

from drake import lcmt_panda_command, lcmt_panda_status
from drake_coop.cli import main
from drake_coop.scenario.resources import default_scenario_path

PAPER = default_scenario_path().read_text()


def with_driver(robot: int, text: str) -> str:
    """The paper's scenario with ``driver: text`` on one robot."""
    marker = "  gains:"
    parts = PAPER.split(marker)
    assert len(parts) == 3
    parts[robot] = parts[robot] + f"  driver: {text}\n"
    return marker.join(parts)


@pytest.mark.parametrize("text, robot, field", [
    ("{kind: iiwa}", 0, "robots[0].driver.kind"),
    ("{status_channel: PANDA_COMMAND_robot1}", 0, "robots[0].driver.status_channel"),
    ("{command_channel: PANDA_STATUS_robot1}", 1, "robots[1].driver.command_channel"),
    ("{num_joints: 7}", 1, "robots[1].driver.num_joints"),
])
@pytest.mark.parametrize("command", ["serve", "sim-driver"])
def test_bad_driver_exits_2_naming_the_field(tmp_path, capsys, text, robot, field, command):
    check_exit_2(tmp_path, capsys, text, robot, field, command)


@pytest.mark.parametrize("text, robot, field", [
    ("{safe_command: brake}", 0, "robots[0].driver.safe_command"),
    ("{rate_hz: 300}", 0, "robots[0].driver.rate_hz"),
    ("{max_status_age: 0}", 1, "robots[1].driver.max_status_age"),
])
def test_bad_driver_settings_exit_2_naming_the_field(tmp_path, capsys, text, robot, field):
    check_exit_2(tmp_path, capsys, text, robot, field, "serve")


def check_exit_2(tmp_path, capsys, text, robot, field, command):
    path = tmp_path / "s.yaml"
    path.write_text(with_driver(robot, text))
    extra = ["--out", str(tmp_path / "out")] if command == "serve" else []
    assert main([command, str(path), "--lcm-url", "memq://", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and field in err[0], err
    assert not (tmp_path / "out").exists()


def test_a_velocity_source_the_driver_cannot_serve_exits_2(tmp_path, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(PAPER.replace("  gains:", "  velocity_source: measured\n  gains:", 1))
    assert main(["sim-driver", str(path), "--lcm-url", "memq://"]) == 2
    assert "robots[0].velocity_source" in capsys.readouterr().err


def test_a_bad_lcm_url_exits_2(tmp_path, capsys):
    assert main(["sim-driver", "paper", "--lcm-url", "nonsense"]) == 2
    assert "--lcm-url" in capsys.readouterr().err


def played_driver(monkeypatch, lcm, stop_status_after=None, signal_after=None, joints=3):
    """Make serve use ``lcm`` and play the driver in its pump: a status per arm at rest
    (fresh stamps) at every pump, until ``stop_status_after`` pumps; ``signal_after`` pumps
    then send that signal to this process."""
    import time

    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.simulate import rest_posture
    from drake_coop.robot import cli, pacing
    from drake_coop.scenario.loading import load_scenario

    scenario = load_scenario()
    q0, _ = rest_posture(scenario, list(plan_run(scenario).arms))
    calls = {"n": 0}

    def pump(lcm_, deadline):
        calls["n"] += 1
        if stop_status_after is None or calls["n"] <= stop_status_after:
            for name, q in zip(("robot1", "robot2"), q0):
                msg = lcmt_panda_status()
                msg.utime = calls["n"]
                msg.num_joints = joints
                msg.joint_position = list(np.resize(q, joints))
                for f in ("joint_velocity", "joint_torque", "joint_torque_external",
                          "joint_position_desired", "joint_velocity_desired",
                          "joint_acceleration_desired", "joint_torque_desired"):
                    setattr(msg, f, [0.0] * joints)
                lcm.Publish(f"PANDA_STATUS_{name}", msg.encode())
        if signal_after is not None and calls["n"] == signal_after[0]:
            os.kill(os.getpid(), signal_after[1])
        lcm.HandleSubscriptions(0)
        remaining = deadline - time.perf_counter()
        if remaining > 0:
            time.sleep(remaining)

    monkeypatch.setattr(cli, "_make_lcm", lambda url: lcm)
    monkeypatch.setattr(pacing, "pump_until", pump)
    commands = {"robot1": [], "robot2": []}
    for name in commands:
        lcm.Subscribe(f"PANDA_COMMAND_{name}",
                      lambda data, name=name: commands[name].append(
                          lcmt_panda_command.decode(data)))
    return commands


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_ctrl_c_and_sigterm_end_with_the_safe_command_sent(tmp_path, monkeypatch, capsys,
                                                           sig, code):
    lcm = DrakeLcm("memq://")
    commands = played_driver(monkeypatch, lcm, signal_after=(25, sig))
    out = tmp_path / "run"
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out),
                 "--delay-margin", "0.002", "--quiet"]) == code
    lcm.HandleSubscriptions(0)
    for msgs in commands.values():
        assert len(msgs) >= 10
        assert any(np.any(np.array(m.joint_torque) != 0.0) for m in msgs[:-1])
        assert list(msgs[-1].joint_torque) == [0.0, 0.0, 0.0]       # the last one: safe
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "interrupted"
    assert (out / "pacing.csv").is_file() and (out / "pacing.png").is_file()


def test_a_stale_status_stops_serve_with_one_line_and_zero_torque(tmp_path, monkeypatch, capsys):
    lcm = DrakeLcm("memq://")
    commands = played_driver(monkeypatch, lcm, stop_status_after=12)
    out = tmp_path / "run"
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out),
                 "--delay-margin", "0.002", "--quiet", "--t-end", "2"]) == 1
    lcm.HandleSubscriptions(0)
    err = capsys.readouterr().err
    assert "robot1: status older than max_status_age" in err.splitlines()[0]
    for msgs in commands.values():
        assert list(msgs[-1].joint_torque) == [0.0, 0.0, 0.0]
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "stopped" and meta["pacing"]["ticks"] < 2 / 0.009


def test_a_driver_reporting_another_joint_count_exits_2_naming_the_driver(tmp_path, monkeypatch,
                                                                          capsys):
    lcm = DrakeLcm("memq://")
    commands = played_driver(monkeypatch, lcm, joints=7)      # a 7-joint Panda's status
    out = tmp_path / "run"
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out),
                 "--delay-margin", "0.002", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert "robots[0].driver" in err[0] and "7 joints" in err[0]
    lcm.HandleSubscriptions(0)
    assert all(list(m[-1].joint_torque) == [0.0] * 3 for m in commands.values())
    assert not out.exists()


@pytest.mark.parametrize("command, option, value, named", [
    ("serve", "--status-wait", "0", "--status-wait"),
    ("serve", "--status-wait", "inf", "--status-wait"),
    ("sim-driver", "--command-wait", "-1", "--command-wait"),
    ("serve", "--lcm-url", "localhost", "--lcm-url"),
    ("sim-driver", "--lcm-url", "localhost", "--lcm-url"),
    ("serve", "--delay-margin", "1.5", "--delay-margin"),
])
def test_bad_option_exits_2_in_one_line_before_anything_starts(tmp_path, capsys, command,
                                                               option, value, named):
    out = tmp_path / "run"
    args = [command, "paper", option, value, "--quiet"]
    if command == "serve":
        args += ["--out", str(out)]
    if option != "--lcm-url":
        args += ["--lcm-url", "memq://"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and named in err[0], err
    assert not out.exists()
