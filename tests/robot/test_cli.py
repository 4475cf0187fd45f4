"""``drake-coop serve`` / ``sim-driver``: bad input exits 2 naming the field; Ctrl-C, SIGTERM
and a watchdog trip end with the safe command sent (in-process, ``memq://`` only: the test
plays the driver inside the serve loop's LCM pump)."""

import json
import math
import os
import signal

import numpy as np
import pytest
from pydrake.lcm import DrakeLcm

from drake import lcmt_panda_command, lcmt_panda_status
from drake_coop.cli import main
from drake_coop.robot.cell import MIN_ANNOUNCEMENTS
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
    ("{max_status_age: 1e-9}", 1, "robots[1].driver.max_status_age"),   # < one tick (9 ms)
    ("{max_status_age: 0.005}", 0, "robots[0].driver.max_status_age"),
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


@pytest.mark.parametrize("url", ["bogus://x", "file:///tmp/x.lcmlog", "udp://1.2.3.4"])
@pytest.mark.parametrize("command", ["serve", "sim-driver"])
def test_an_unknown_lcm_provider_exits_2_before_anything_starts(tmp_path, monkeypatch, capsys,
                                                                url, command):
    from drake_coop.robot import cli

    def never(url_):
        raise AssertionError("an LCM connection was made")

    monkeypatch.setattr(cli, "_make_lcm", never)
    out = tmp_path / "run"
    extra = ["--out", str(out)] if command == "serve" else []
    assert main([command, "paper", "--lcm-url", url, "--quiet", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--lcm-url" in err[0] and "provider" in err[0], err
    assert not out.exists()


def test_serve_on_memq_with_no_driver_says_memq_is_in_process_only(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out), "--quiet",
                 "--delay-margin", "0.002", "--status-wait", "0.2"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "memq:// is in-process only" in err[0], err
    assert not out.exists()


def test_sigterm_while_waiting_for_the_first_status_keeps_the_previous_run(tmp_path,
                                                                          monkeypatch, capsys):
    """``--force`` into a completed run's folder, no driver, SIGTERM during the wait: the
    completed run is still there, byte for byte."""
    lcm = DrakeLcm("memq://")
    played_driver(monkeypatch, lcm)
    out = tmp_path / "run"
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out), "--quiet",
                 "--delay-margin", "0.002", "--t-end", "0.05"]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert json.loads(before["run.json"])["status"] == "ok"
    played_driver(monkeypatch, lcm, stop_status_after=0, signal_after=(3, signal.SIGTERM))
    capsys.readouterr()
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out), "--quiet",
                 "--delay-margin", "0.002", "--force"]) == 143
    err = capsys.readouterr().err.strip().splitlines()
    assert "nothing written" in err[0], err         # (then the command line's "interrupted")
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir()] == ["run"]      # no staging folder left


def status_message(q, utime, joints=3):
    """An ``lcmt_panda_status`` at ``q`` (resized to ``joints``), its other fields zero."""
    msg = lcmt_panda_status()
    msg.utime = utime
    msg.num_joints = joints
    msg.joint_position = list(np.resize(np.asarray(q, dtype=float), joints))
    for f in ("joint_velocity", "joint_torque", "joint_torque_external",
              "joint_position_desired", "joint_velocity_desired",
              "joint_acceleration_desired", "joint_torque_desired"):
        setattr(msg, f, [0.0] * joints)
    return msg


def played_driver(monkeypatch, lcm, stop_status_after=None, signal_after=None, joints=3,
                  hostile=None):
    """Make serve use ``lcm`` and play the driver in its pump: a status per arm at rest
    (fresh stamps) at every pump, until ``stop_status_after`` pumps; ``signal_after`` pumps
    then send that signal to this process; ``hostile = (pump, make[, then_good])``: at that
    pump robot1's status is replaced by the bytes ``make(q, utime)`` (followed within the same
    pump by a good one if ``then_good``), then the good ones go on."""
    import time

    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.simulate import rest_posture
    from drake_coop.robot import cli, pacing
    from drake_coop.scenario.loading import load_scenario

    scenario = load_scenario()
    q0, _ = rest_posture(plan_run(scenario))
    calls = {"n": 0}

    def pump(lcm_, deadline):
        calls["n"] += 1
        if stop_status_after is None or calls["n"] <= stop_status_after:
            for name, q in zip(("robot1", "robot2"), q0):
                data = status_message(q, calls["n"], joints).encode()
                if hostile is not None and name == "robot1" and calls["n"] == hostile[0]:
                    lcm.Publish(f"PANDA_STATUS_{name}", hostile[1](q, calls["n"]))
                    if len(hostile) < 3 or not hostile[2]:
                        continue
                    data = status_message(q, calls["n"] * 10 + 1).encode()  # a good one after
                lcm.Publish(f"PANDA_STATUS_{name}", data)
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
    assert commands == {"robot1": [], "robot2": []}     # no command before a valid status
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


def _shifted(q, utime, dq):
    return status_message(np.asarray(q) + np.asarray(dq), utime).encode()


def _command_bytes(q, utime):
    msg = lcmt_panda_command()
    msg.utime = utime
    msg.num_joint_torque = 3
    msg.joint_torque = [1.0, 2.0, 3.0]
    return msg.encode()


#: What a hostile or broken driver may put on the status channel, and a word of the one line.
HOSTILE = {
    "no joints": (lambda q, u: status_message(q, u, joints=0).encode(), "0 joints"),
    "seven joints": (lambda q, u: status_message(q, u, joints=7).encode(), "7 joints"),
    "truncated": (lambda q, u: status_message(q, u).encode()[:100], "truncated"),
    "random bytes": (lambda q, u: np.random.default_rng(5).bytes(230), "another message type"),
    "fingerprint then random": (
        lambda q, u: status_message(q, u).encode()[:20]
        + np.random.default_rng(6).bytes(210), "robot1"),
    "trailing bytes": (lambda q, u: status_message(q, u).encode() + b"\0", "wrong size"),
    "command message": (_command_bytes, "another message type"),
    "nan": (lambda q, u: _shifted(q, u, [0.0, math.nan, 0.0]), "non-finite"),
    "+inf": (lambda q, u: _shifted(q, u, [math.inf, 0.0, 0.0]), "non-finite"),
    "-inf": (lambda q, u: _shifted(q, u, [0.0, 0.0, -math.inf]), "non-finite"),
    "0.5 rad jump": (lambda q, u: _shifted(q, u, [0.0, 0.5, 0.0]), "jumped"),
}
#: The URDF's effort limits of the paper's arms (urdf/crs_a465_3dof.urdf, effort="2000").
URDF_EFFORT = 2000.0


@pytest.mark.parametrize("case, pump", [           # pump 1: the first status; 30: mid-run
    (case, pump) for case in sorted(HOSTILE) for pump in (1, 30)
    if not (pump == 1 and case == "0.5 rad jump")])   # (a jump needs a reading before it)
def test_a_hostile_status_trips_at_its_tick_with_one_line_and_the_run_kept(
        tmp_path, monkeypatch, capsys, case, pump):
    make, word = HOSTILE[case]
    lcm = DrakeLcm("memq://")
    commands = played_driver(monkeypatch, lcm, hostile=(pump, make))
    out = tmp_path / "run"
    code = main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out),
                 "--delay-margin", "0.002", "--quiet", "--t-end", "2"])
    lcm.HandleSubscriptions(0)
    err = capsys.readouterr().err.strip().splitlines()
    if pump == 1 and case in ("no joints", "seven joints"):
        # a first status of another joint count: the driver of another arm, a setup error
        assert code == 2 and len(err) == 1 and "robots[0].driver" in err[0], err
        assert commands == {"robot1": [], "robot2": []} and not out.exists()
        return
    if pump == 1 and case == "fingerprint then random":
        # a first status that reads (finite, far from the start posture), then good ones:
        # the arm is not where it starts, or moving: serve refuses to begin, nothing sent
        assert code == 1 and len(err) == 1 and "robot1" in err[0], err
        assert "not started" in err[0], err
        assert commands == {"robot1": [], "robot2": []} and not out.exists()
        return
    assert code == 1
    assert len(err) == 1, err
    assert "robot1" in err[0] and "PANDA_STATUS_robot1" in err[0] and word in err[0], err
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "stopped" and meta["watchdog"]["robot"] == "robot1"
    assert meta["watchdog"]["channel"] == "PANDA_STATUS_robot1"
    # the tick that read it is the last: pump p precedes tick p - 4 (pumps 1-3: the wait,
    # three heartbeats announced)
    k_trip = max(pump - 1 - MIN_ANNOUNCEMENTS, 0)
    assert meta["pacing"]["ticks"] == k_trip + 1
    assert (out / "pacing.csv").read_text().count("\n") == k_trip + 2   # header + ticks
    for name, msgs in commands.items():
        tau = np.array([m.joint_torque for m in msgs])
        assert tau.shape == (k_trip + 2, 3)           # one per tick, and the safe one last
        assert np.all(np.isfinite(tau)) and np.all(np.abs(tau) <= URDF_EFFORT)
    tau = np.array([m.joint_torque for m in commands["robot1"]])
    np.testing.assert_array_equal(tau[k_trip:], 0.0)   # the tick's command and the last
    if k_trip > 0:
        assert np.any(tau[k_trip - 1] != 0.0)          # the controller ran until then


def test_without_configured_limits_the_urdfs_effort_limits_bound_the_command(
        tmp_path, monkeypatch, capsys):
    """The paper's scenario sets no torque limit: serve takes the URDF's (read here from the
    file's XML, independently of Drake)."""
    import xml.etree.ElementTree as ET

    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.resources import model_urdf_path

    s = load_scenario()
    assert all(r.driver is None or r.driver.torque_limits is None for r in s.robots)
    assert all(r.actuators.torque_limits is None for r in s.robots)
    effort = {}
    for robot in s.robots:
        root = ET.parse(model_urdf_path(robot)).getroot()
        effort[robot.name] = [float(j.find("limit").get("effort")) for j in root.iter("joint")
                              if j.get("type") == "revolute"]
    assert effort == {"robot1": [URDF_EFFORT] * 3, "robot2": [URDF_EFFORT] * 3}
    lcm = DrakeLcm("memq://")
    played_driver(monkeypatch, lcm)
    out = tmp_path / "run"
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out),
                 "--delay-margin", "0.002", "--quiet", "--t-end", "0.05"]) == 0
    meta = json.loads((out / "run.json").read_text())
    assert meta["torque_limits"] == effort


def test_run_json_records_the_realtime_settings_read_back(tmp_path, monkeypatch, capsys):
    lcm = DrakeLcm("memq://")
    played_driver(monkeypatch, lcm)
    out = tmp_path / "run"
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out), "--quiet",
                 "--delay-margin", "0.002", "--t-end", "0.05"]) == 0
    rt = json.loads((out / "run.json").read_text())["realtime"]
    policy = os.sched_getscheduler(0)
    assert getattr(os, rt["policy"]) == policy
    assert rt["priority"] == os.sched_getparam(0).sched_priority
    assert rt["cpu_affinity"] == sorted(os.sched_getaffinity(0))
    assert rt["mlockall"] == "not requested"


def test_require_rt_refuses_to_start_naming_what_is_missing(tmp_path, capsys):
    assert os.sched_getscheduler(0) == os.SCHED_OTHER      # the test process is not real-time
    out = tmp_path / "run"
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out), "--quiet",
                 "--delay-margin", "0.002", "--require-rt"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--require-rt" in err[0] and "SCHED_OTHER" in err[0], err
    assert "locked memory (not attempted" in err[0]
    assert not out.exists()


def test_require_rt_refuses_when_mlockall_fails(tmp_path, monkeypatch, capsys):
    import errno
    from types import SimpleNamespace

    from drake_coop.robot import realtime

    monkeypatch.setattr(os, "sched_getscheduler", lambda pid: os.SCHED_FIFO)
    monkeypatch.setattr(os, "sched_getparam", lambda pid: SimpleNamespace(sched_priority=80))
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {1})
    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    monkeypatch.setattr(realtime, "_mlockall", lambda: errno.EPERM)
    monkeypatch.setattr(realtime, "_locked_kib", lambda: 0)
    out = tmp_path / "run"
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out), "--quiet",
                 "--delay-margin", "0.002", "--require-rt"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "locked memory (mlockall failed: EPERM" in err[0], err
    assert "scheduling" not in err[0] and "affinity" not in err[0]
    assert not out.exists()


def test_a_bad_status_followed_by_a_good_one_before_the_tick_still_trips(tmp_path, monkeypatch,
                                                                        capsys):
    """At 1 kHz a tick of 9 ms reads one status of nine: every message's bytes are checked as
    it arrives, and the next tick reads the faulty one."""
    lcm = DrakeLcm("memq://")
    commands = played_driver(monkeypatch, lcm, hostile=(30, HOSTILE["truncated"][0], True))
    out = tmp_path / "run"
    assert main(["serve", "paper", "--lcm-url", "memq://", "--out", str(out),
                 "--delay-margin", "0.002", "--quiet", "--t-end", "2"]) == 1
    lcm.HandleSubscriptions(0)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "truncated" in err[0] and "PANDA_STATUS_robot1" in err[0], err
    k_trip = 30 - 1 - MIN_ANNOUNCEMENTS        # pump p precedes tick p - 4
    assert json.loads((out / "run.json").read_text())["pacing"]["ticks"] == k_trip + 1
    tau = np.array([m.joint_torque for m in commands["robot1"]])
    np.testing.assert_array_equal(tau[k_trip:], 0.0)
    assert np.any(tau[k_trip - 1] != 0.0)
