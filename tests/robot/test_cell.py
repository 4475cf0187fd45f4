"""A cell of arms fails safe as a whole (:mod:`drake_coop.robot.cell`): a ``serve`` whose
partner falls silent stops within ``cell.partner_silence_ticks`` of its own ticks naming the
silent arm; a second ``serve`` for an arm already served is refused; the stop names the arm
that tripped; nothing from another process reaches a terminal or ``run.json`` with a control
byte. In process, on ``memq://``: the other processes are played in the LCM pump, message by
message (deterministic); the multi-process run over the hub is the slow test at the end."""

import json
import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from pydrake.lcm import DrakeLcm

from drake import lcmt_panda_command
from drake_coop.cli import main
from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.simulate import rest_posture
from drake_coop.robot import cli, pacing
from drake_coop.robot.cell import (
    CELL_CHANNEL,
    MIN_ANNOUNCEMENTS,
    CellWatch,
    Heartbeat,
    parse_heartbeat,
    printable,
)
from drake_coop.robot.serve_loop import STOP_CHANNEL, StopListener
from drake_coop.scenario.loading import load_scenario
from tests.robot.test_cli import status_message

OTHER = "ab" * 8                         # another process's session


# ------------------------------------------------------------------ printable text


@pytest.mark.parametrize("byte", range(256))
def test_every_byte_value_becomes_printable_text(byte):
    for data in (bytes([byte]), b"robot1: " + bytes([byte]) * 3 + b" reason",
                 bytes([byte]).decode("latin-1")):        # as bytes, and as a character
        text = printable(data)
        assert text.isprintable() and "\x1b" not in text and "\n" not in text, (byte, text)
        if 0x21 <= byte <= 0x7E:                          # visible ASCII: kept as it is
            assert chr(byte) in text


def test_control_sequences_are_shown_not_sent():
    text = printable(b"robot1: \x1b[2J\x1b]0;owned\x07 \xe2\x80\xae gnp.exe \xff")
    assert text.isprintable()
    assert "\\x1b[2J" in text and "\\x07" in text and "\\u202e" in text and "\\xff" in text
    assert printable(bytes(range(256)) * 10, limit=50).endswith("…")
    assert len(printable(bytes(range(256)) * 10, limit=50)) == 50


# ------------------------------------------------------------------ heartbeats


@pytest.mark.parametrize("data", [
    b"", b"not json", b"[" * 100000, b"{" * 3000, b'"a string"', b"{}",
    b'{"session": "XYZ", "pid": 1, "start_ns": 1, "state": "serving", "robots": ["r"]}',
    b'{"session": "ab", "pid": true, "start_ns": 1, "state": "serving", "robots": ["r"]}',
    b'{"session": "ab", "pid": 1, "start_ns": 1, "state": "dancing", "robots": ["r"]}',
    b'{"session": "ab", "pid": 1, "start_ns": 1, "state": "serving", "robots": []}',
    b'{"session": "ab", "pid": 1, "start_ns": 1, "state": "serving", "robots": [1]}',
    b'{"session": "ab", "pid": 1, "start_ns": 1, "state": "serving", "robots": ["r"], "x": "'
    + b"y" * 5000 + b'"}',
    bytes(range(256)),
])
def test_a_malformed_heartbeat_is_not_one_and_never_raises(data):
    assert parse_heartbeat(data) is None


def test_a_heartbeat_reads_back():
    beat = Heartbeat(OTHER, 12, 34, "waiting", ["robot1", "robot2"])
    assert parse_heartbeat(beat.encode()) == beat


def watch(lcm, robots, cell=("robot1", "robot2"), **kw):
    return CellWatch(lcm, list(robots), list(cell), **kw)


def announce_all(lcm, *watches, times=MIN_ANNOUNCEMENTS):
    for _ in range(times):
        for w in watches:
            w.announce()
        lcm.HandleSubscriptions(0)


def test_a_partner_silent_for_three_ticks_stops_this_serve_naming_it():
    lcm = DrakeLcm("memq://")
    one, two = watch(lcm, ["robot1"]), watch(lcm, ["robot2"])
    assert two.missing() == ["robot1"] and not two.ready()
    announce_all(lcm, one, two)
    assert one.ready() and two.ready()
    one.begin(), two.begin()
    for _ in range(20):                  # both alive: no stop
        assert one.tick() is None and two.tick() is None
        lcm.HandleSubscriptions(0)
    ticks = 0
    while two.tick() is None:            # robot1's serve killed: it ticks no more
        ticks += 1
        lcm.HandleSubscriptions(0)
        assert ticks < 10
    assert ticks + 1 == 3 == two.silence_ticks           # stopped at its third silent tick
    assert two.arm == "robot1" and two.reason.startswith("robot1: its serve silent for 3")
    assert not two.refused


def test_a_partner_still_starting_has_a_grace_then_its_silence_stops_this_serve():
    """A partner heard only waiting (its start is slower than a tick) is given
    ``grace_ticks``; not serving by then, it stops this serve naming it."""
    lcm = DrakeLcm("memq://")
    one, two = watch(lcm, ["robot1"]), watch(lcm, ["robot2"], grace_ticks=40)
    announce_all(lcm, one, two)          # robot1's serve waiting, then nothing more
    two.begin()
    ticks = 1
    while two.tick() is None:
        ticks += 1
        assert ticks <= 40
    assert ticks == 40 and two.reason == "robot1: its serve did not begin within 40 ticks of " \
        "this one"
    # a partner that begins within the grace: then the silence rule
    lcm = DrakeLcm("memq://")
    one, two = watch(lcm, ["robot1"]), watch(lcm, ["robot2"], grace_ticks=40)
    announce_all(lcm, one, two)
    two.begin()
    for _ in range(30):                  # robot1 still starting: no stop
        assert two.tick() is None
    one.begin()
    one.tick()
    lcm.HandleSubscriptions(0)
    assert [two.tick() for _ in range(3)][-1].startswith("robot1: its serve silent for 3")


def test_a_partner_that_is_done_is_not_a_death():
    lcm = DrakeLcm("memq://")
    one, two = watch(lcm, ["robot1"]), watch(lcm, ["robot2"])
    announce_all(lcm, one, two)
    one.begin(), two.begin()
    one.announce("done")
    lcm.HandleSubscriptions(0)
    assert all(two.tick() is None for _ in range(10))


def test_a_second_serve_for_an_arm_already_served_is_refused_and_the_first_goes_on():
    lcm = DrakeLcm("memq://")
    first = watch(lcm, ["robot1", "robot2"], clock_ns=lambda: 100)
    announce_all(lcm, first)
    first.begin()
    second = watch(lcm, ["robot2"], clock_ns=lambda: 50)   # started earlier, still waiting
    for _ in range(MIN_ANNOUNCEMENTS):
        first.tick()
        second.announce()
        lcm.HandleSubscriptions(0)
    assert not second.ready() and second.refused and second.arm == "robot2"
    assert "robot2 is already served by another serve" in second.reason
    assert str(os.getpid()) in second.reason
    assert first.tick() is None and first.reason is None


@pytest.mark.parametrize("starts, refused", [((1, 2), [False, True]), ((2, 1), [True, False]),
                                             ((5, 5), [True, True])])
def test_two_waiting_serves_for_one_arm_the_later_is_refused_both_when_it_cannot_be_told(
        starts, refused):
    lcm = DrakeLcm("memq://")
    a = watch(lcm, ["robot1"], cell=["robot1"], clock_ns=lambda: starts[0])
    b = watch(lcm, ["robot1"], cell=["robot1"], clock_ns=lambda: starts[1])
    announce_all(lcm, a, b)
    assert [not a.ready() and a.refused, not b.ready() and b.refused] == refused


def test_two_serves_already_commanding_one_arm_both_stop():
    lcm = DrakeLcm("memq://")
    a = watch(lcm, ["robot1"], cell=["robot1"])
    b = watch(lcm, ["robot1"], cell=["robot1"])
    a.begin(), b.begin()                 # both began before hearing each other
    a.tick(), b.tick()
    lcm.HandleSubscriptions(0)
    assert a.tick() is not None and b.tick() is not None
    assert "both stop" in a.reason and "both stop" in b.reason and not a.refused


def test_a_serve_that_announced_serving_then_done_is_not_a_duplicate():
    lcm = DrakeLcm("memq://")
    old = watch(lcm, ["robot1"], cell=["robot1"], clock_ns=lambda: 1)
    old.begin()
    old.tick()
    old.announce("done")                 # both still queued when the new one pumps
    new = watch(lcm, ["robot1"], cell=["robot1"], clock_ns=lambda: 2)
    announce_all(lcm, new)
    assert new.ready() and new.reason is None


def test_garbage_on_the_heartbeat_channel_is_counted_and_ignored():
    lcm = DrakeLcm("memq://")
    w = watch(lcm, ["robot1"], cell=["robot1"])
    for data in (b"\x00" * 10, b"[" * 50000, bytes(range(256))):
        lcm.Publish(CELL_CHANNEL, data)
    announce_all(lcm, w)
    assert w.ready() and w.ignored == 3


# ------------------------------------------------------------------ the stop message


def test_a_duplicate_serves_stop_is_heard_its_own_is_not_and_control_bytes_are_shown():
    lcm = DrakeLcm("memq://")
    mine = StopListener(lcm, ["robot1"], session="cd" * 8)
    StopListener.publish(lcm, "robot1", "own", session="cd" * 8)
    lcm.HandleSubscriptions(0)
    assert mine.reason is None
    # another process serving the same arm: its stop names robot1, and is heard
    StopListener.publish(lcm, "robot1", "tripped\x1b[2J\x07 \xff", session=OTHER)
    lcm.HandleSubscriptions(0)
    assert mine.reason is not None and mine.reason.startswith("robot1: tripped")
    assert mine.reason.isprintable() and "\x1b" not in mine.reason


@pytest.mark.parametrize("byte", range(256))
def test_every_byte_of_a_stop_message_reaches_the_reason_printable(byte):
    lcm = DrakeLcm("memq://")
    listener = StopListener(lcm, ["robot2"], session="cd" * 8)
    lcm.Publish(STOP_CHANNEL, b"robot1: " + bytes([byte]) * 4 + b" end\nsession " + OTHER.encode())
    lcm.HandleSubscriptions(0)
    assert listener.reason.isprintable() and listener.reason.endswith("end")


# ------------------------------------------------------------------ serve, in process

SCENARIO = load_scenario()
Q0 = [np.asarray(q, dtype=float) for q in rest_posture(plan_run(SCENARIO))[0]]


def played_cell(monkeypatch, lcm, partner=None, partner_until=None, shift=None, velocity=None,
                nan_robot2_at=None, extra=None):
    """serve on ``lcm``, its pump playing the driver (both arms' statuses at rest, fresh
    stamps), another serve's heartbeat for ``partner`` (until ``partner_until`` pumps: then it
    is killed), ``shift`` (robot, joint, rad) and ``velocity`` (robot, joint, rad/s) on the
    statuses, a NaN on robot2's status from ``nan_robot2_at``, and ``extra(n)`` messages."""
    calls = {"n": 0}

    def pump(lcm_, deadline):
        calls["n"] += 1
        n = calls["n"]
        if partner is not None and (partner_until is None or n <= partner_until):
            lcm.Publish(CELL_CHANNEL, Heartbeat(OTHER, 999999, 0, "serving", partner).encode())
        for i, name in enumerate(("robot1", "robot2")):
            msg = status_message(Q0[i], n)
            q = np.array(msg.joint_position)
            if shift is not None and shift[0] == name:
                q[shift[1]] += shift[2]
            if nan_robot2_at is not None and name == "robot2" and n >= nan_robot2_at:
                q[0] = math.nan
            msg.joint_position = list(q)
            if velocity is not None and velocity[0] == name:
                v = [0.0] * 3
                v[velocity[1]] = velocity[2]
                msg.joint_velocity = v
            lcm.Publish(f"PANDA_STATUS_{name}", msg.encode())
        if extra is not None:
            extra(n)
        lcm.HandleSubscriptions(0)
        remaining = deadline - time.perf_counter()
        if remaining > 0:
            time.sleep(remaining)

    monkeypatch.setattr(cli, "_make_lcm", lambda url: lcm)
    monkeypatch.setattr(pacing, "pump_until", pump)
    got = {"robot1": [], "robot2": [], "stop": [], "cell": []}
    for name in ("robot1", "robot2"):
        lcm.Subscribe(f"PANDA_COMMAND_{name}", lambda d, name=name: got[name].append(
            np.array(lcmt_panda_command.decode(d).joint_torque)))
    lcm.Subscribe(STOP_CHANNEL, lambda d: got["stop"].append(bytes(d)))
    lcm.Subscribe(CELL_CHANNEL, lambda d: got["cell"].append(parse_heartbeat(bytes(d))))
    return got


def serve(tmp_path, *extra, scenario="paper", t_end="1"):
    out = tmp_path / "run"
    code = main(["serve", scenario, "--lcm-url", "memq://", "--out", str(out),
                 "--delay-margin", "0.002", "--quiet", "--t-end", t_end, *extra])
    return code, out


class PlayedLockstepDriver(DrakeLcm):
    """``memq://`` whose pump plays the lockstep driver and robot1's serve for robot2's
    ``serve --lockstep``: both arms' statuses of every driver cycle (``period``) up to tick
    ``k``'s time (``k h``) once tick ``k - 1``'s command of robot2 came (cycle 0 until the
    first), and robot1's ``serving`` heartbeat; :attr:`sent` records what robot2's serve
    published, in order: ``command``, or its heartbeat's state."""

    def __init__(self, period: float, h: float):
        super().__init__("memq://")
        self.period, self.h, self.cycle, self.commands, self.sent = period, h, -1, 0, []
        self.Subscribe("PANDA_COMMAND_robot2", self._command)
        self.Subscribe(CELL_CHANNEL, self._beat)

    def _command(self, data) -> None:
        self.sent.append("command")
        self.commands += 1

    def _beat(self, data) -> None:
        beat = parse_heartbeat(bytes(data))
        if beat is not None and beat.session != OTHER:
            self.sent.append(beat.state)

    def HandleSubscriptions(self, timeout_millis: int) -> int:  # noqa: N802 (Drake's name)
        self.Publish(CELL_CHANNEL, Heartbeat(OTHER, 999999, 0, "serving", ["robot1"]).encode())
        while (self.cycle + 1) * self.period <= self.commands * self.h + 1e-9:
            self.cycle += 1
            utime = 10**6 + round(self.cycle * self.period * 1e6)
            for i, name in enumerate(("robot1", "robot2")):
                self.Publish(f"PANDA_STATUS_{name}", status_message(Q0[i], utime).encode())
        if self.cycle == 0:                         # before tick 0: the first status again
            for i, name in enumerate(("robot1", "robot2")):
                self.Publish(f"PANDA_STATUS_{name}", status_message(Q0[i], 10**6).encode())
        return super().HandleSubscriptions(0)


def test_in_lockstep_each_ticks_heartbeat_goes_out_before_its_command(tmp_path, monkeypatch):
    """``serve --lockstep``: every tick's heartbeat is on the wire before the tick's command.
    The driver advances only on every arm's command, so a partner cannot tick past a command
    whose heartbeat it has not had: its count of this serve's silence stays below 3 however
    the processes are scheduled (sent after the command, a heartbeat can trail it while the
    lockstep runs on, and 3 ticks were seen under load)."""
    from drake_coop.robot.driver_spec import driver_specs
    from drake_coop.scenario.model_check import check_models

    period = driver_specs(SCENARIO, check_models(SCENARIO))[1].period
    h = plan_run(SCENARIO).h
    lcm = PlayedLockstepDriver(period, h)
    monkeypatch.setattr(cli, "_make_lcm", lambda url: lcm)
    code, out = serve(tmp_path, "--robot", "robot2", "--lockstep", "--status-wait", "5",
                      t_end="0.03")
    assert code == 0, json.loads((out / "run.json").read_text())["message"]
    lcm.HandleSubscriptions(0)
    assert lcm.sent[-2:] == ["command", "done"]          # the safe command, then done
    ticks = [i for i, x in enumerate(lcm.sent[:-2]) if x == "command"]
    assert len(ticks) == math.floor(0.03 / h + 1e-9) + 1 >= 3
    for i in ticks:                       # each command right after its tick's heartbeat
        assert lcm.sent[i - 1] == "serving", lcm.sent[max(i - 3, 0):i + 1]
    assert lcm.sent.count("serving") == len(ticks)


def test_killed_partner_serve_stops_this_one_within_three_ticks_naming_the_dead_arm(
        tmp_path, monkeypatch, capsys):
    """robot2's serve, robot1's serve played by its heartbeats in the pump until it is killed
    (pump 20): robot2's serve stops at its third tick without a heartbeat, exit 1, one line
    naming robot1, its last command the safe one, its stop published naming robot1."""
    lcm = DrakeLcm("memq://")
    kill = 20
    got = played_cell(monkeypatch, lcm, partner=["robot1"], partner_until=kill)
    code, out = serve(tmp_path, "--robot", "robot2")
    lcm.HandleSubscriptions(0)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1, err
    assert "robot1: its serve silent for 3 ticks" in err[0], err
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "stopped" and meta["watchdog"]["robot"] == "robot1"
    assert meta["watchdog"]["channel"] == CELL_CHANNEL
    # pump p precedes tick p - 1 - MIN_ANNOUNCEMENTS: the last heartbeat came just before
    # tick kill - 1 - MIN_ANNOUNCEMENTS; that tick and two more ran, then the stop
    first_after = kill - 1 - MIN_ANNOUNCEMENTS
    assert meta["pacing"]["ticks"] == first_after + 3
    assert np.all(got["robot2"][-1] == 0.0) and np.any(got["robot2"][-2] != 0.0)
    assert got["robot1"] == []                                  # never another arm's
    assert len(got["stop"]) == 1 and got["stop"][0].startswith(b"robot1: its serve silent")
    assert got["cell"][-1].state == "stopped" and got["cell"][-1].robots == ["robot2"]


def test_with_its_partner_alive_a_serve_per_arm_completes(tmp_path, monkeypatch, capsys):
    lcm = DrakeLcm("memq://")
    got = played_cell(monkeypatch, lcm, partner=["robot1"])
    code, out = serve(tmp_path, "--robot", "robot2", t_end="0.3")
    lcm.HandleSubscriptions(0)
    assert code == 0, capsys.readouterr().err
    assert got["stop"] == [] and got["cell"][-1].state == "done"
    assert json.loads((out / "run.json").read_text())["cell"]["partners"] == ["robot1"]


def test_a_serve_per_arm_without_its_partner_does_not_begin(tmp_path, monkeypatch, capsys):
    lcm = DrakeLcm("memq://")
    got = played_cell(monkeypatch, lcm)
    code, out = serve(tmp_path, "--robot", "robot2", "--status-wait", "0.5")
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and "no serve for robot1" in err[0], err
    assert not out.exists() and got["robot2"] == []


@pytest.mark.parametrize("robot_option", [[], ["--robot", "robot1"]])
def test_a_second_serve_for_an_arm_already_served_is_refused_in_one_line(
        tmp_path, monkeypatch, capsys, robot_option):
    lcm = DrakeLcm("memq://")
    got = played_cell(monkeypatch, lcm, partner=["robot1", "robot2"])
    code, out = serve(tmp_path, *robot_option)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert "robot1 is already served by another serve (pid 999999" in err[0], err
    assert not out.exists() and got["robot1"] == [] and got["robot2"] == []
    assert got["stop"] == []                  # the serve already running goes on


def test_a_duplicate_found_while_serving_stops_both_and_the_cell(tmp_path, monkeypatch, capsys):
    """A serve for robot1 appears mid-run already serving (the two could not tell which was
    first): this one stops, naming robot1, and its stop is published for the others."""
    lcm = DrakeLcm("memq://")
    appear = 15

    def duplicate(n):
        if n >= appear:
            lcm.Publish(CELL_CHANNEL, Heartbeat("ef" * 8, 777, 1, "serving",
                                                ["robot1"]).encode())
    got = played_cell(monkeypatch, lcm, extra=duplicate)
    code, out = serve(tmp_path)
    lcm.HandleSubscriptions(0)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and "robot1: two serve processes" in err[0], err
    assert "both stop" in err[0]
    meta = json.loads((out / "run.json").read_text())
    assert meta["watchdog"]["robot"] == "robot1" and meta["watchdog"]["channel"] == CELL_CHANNEL
    assert meta["pacing"]["ticks"] == appear - 1 - MIN_ANNOUNCEMENTS + 1
    assert np.all(got["robot1"][-1] == 0.0) and np.all(got["robot2"][-1] == 0.0)
    assert len(got["stop"]) == 1 and got["stop"][0].startswith(b"robot1: two serve")


def test_a_two_arm_serve_whose_robot2_trips_names_robot2(tmp_path, monkeypatch, capsys):
    lcm = DrakeLcm("memq://")
    got = played_cell(monkeypatch, lcm, nan_robot2_at=20)
    code, out = serve(tmp_path)
    lcm.HandleSubscriptions(0)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and "robot2" in err[0] and "PANDA_STATUS_robot2" in err[0], err
    assert len(got["stop"]) == 1 and got["stop"][0].startswith(b"robot2: "), got["stop"]


def test_a_stop_with_control_bytes_reaches_the_terminal_and_run_json_printable(
        tmp_path, monkeypatch, capsys):
    lcm = DrakeLcm("memq://")
    hostile = b"robot9: \x1b[2J\x1b]0;pwned\x07\x00\xff\xfe \xe2\x80\xae done\r\n" + bytes(range(32))

    def stop(n):
        if n == 12:
            lcm.Publish(STOP_CHANNEL, hostile)
    played_cell(monkeypatch, lcm, extra=stop)
    code, out = serve(tmp_path)
    err = capsys.readouterr().err
    assert code == 1
    line = err.strip()
    assert "\n" not in line and line.isprintable() and "\\x1b[2J" in line, repr(line)
    text = (out / "run.json").read_text()
    meta = json.loads(text)
    for value in (meta["message"], *meta["watchdog"].values()):
        assert value.isprintable() and "\x1b" not in value, repr(value)
    assert all(32 <= ord(c) or c in "\n" for c in text)


# ------------------------------------------------------------------ safe start


@pytest.mark.parametrize("shift, joint, words", [
    (("robot2", 1, 0.2), 2, "robot2 is 0.2 rad from its start posture at joint 2"),
    (("robot1", 0, -0.06), 1, "robot1 is 0.06 rad from its start posture at joint 1"),
])
def test_serve_refuses_to_begin_away_from_the_start_posture(tmp_path, monkeypatch, capsys,
                                                           shift, joint, words):
    lcm = DrakeLcm("memq://")
    got = played_cell(monkeypatch, lcm, shift=shift)
    code, out = serve(tmp_path)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1 and words in err[0] and "not started" in err[0], err
    assert "cell.start_max_offset = 0.05 rad" in err[0]
    assert not out.exists() and got["robot1"] == [] and got["robot2"] == []


def test_a_small_offset_within_the_bound_starts(tmp_path, monkeypatch, capsys):
    lcm = DrakeLcm("memq://")
    played_cell(monkeypatch, lcm, shift=("robot1", 2, 0.04))
    code, _ = serve(tmp_path, t_end="0.1")
    assert code == 0, capsys.readouterr().err


def test_serve_refuses_to_begin_on_a_moving_arm(tmp_path, monkeypatch, capsys):
    lcm = DrakeLcm("memq://")
    got = played_cell(monkeypatch, lcm, velocity=("robot1", 2, 0.3))
    code, out = serve(tmp_path)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1 and len(err) == 1, err
    assert "robot1 is moving: joint 3 at 0.3 rad/s by its measured velocity" in err[0], err
    assert not out.exists() and got["robot1"] == [] and got["robot2"] == []


def test_an_offset_limit_from_the_scenario_is_used(tmp_path, monkeypatch, capsys):
    path = tmp_path / "s.yaml"
    path.write_text("cell: {start_max_offset: 0.5}\n")
    lcm = DrakeLcm("memq://")
    played_cell(monkeypatch, lcm, shift=("robot2", 1, 0.2))
    code, _ = serve(tmp_path, scenario=str(path), t_end="0.1")
    assert code == 0, capsys.readouterr().err


def test_the_first_commands_are_ramped_in_from_the_hold_torque(tmp_path, monkeypatch):
    """The same statuses (robot1 0.04 rad off its start posture, within the bound) to serve
    without a ramp and with one of N = 5 ticks: tick k's
    command is (1 - k/N) τ_hold(q0) + (k/N) τ(k), τ(k) the unramped run's; from tick N on
    they are equal. τ_hold: the controller model's gravity torque at the first reading (the
    hold torque of the safe command ``hold``). Each ramped command stays within
    |τ_hold| + the torque limit."""
    from drake_coop.robot.driver_spec import driver_specs
    from drake_coop.robot.serve_loop import ServeLoop
    from drake_coop.scenario.model_check import check_models

    runs = {}
    for ramp in ("0", "0.045"):
        path = tmp_path / f"ramp{ramp}.yaml"
        path.write_text(f"cell: {{start_ramp: {ramp}}}\n")
        lcm = DrakeLcm("memq://")
        got = played_cell(monkeypatch, lcm, shift=("robot1", 1, 0.04))   # within the bound
        code, _ = main(["serve", str(path), "--lcm-url", "memq://", "--out",
                        str(tmp_path / f"run{ramp}"), "--delay-margin", "0.002", "--quiet",
                        "--t-end", "0.2"]), None
        assert code == 0
        lcm.HandleSubscriptions(0)
        runs[ramp] = got
    scenario = load_scenario(tmp_path / "ramp0.yaml")
    specs = driver_specs(scenario, check_models(scenario))
    loop = ServeLoop(plan_run(scenario, 0.2), DrakeLcm("memq://"), specs)
    n = 5
    for i, name in enumerate(("robot1", "robot2")):
        plain, ramped = np.array(runs["0"][name]), np.array(runs["0.045"][name])
        assert plain.shape == ramped.shape
        q_first = Q0[i] + (np.array([0.0, 0.04, 0.0]) if name == "robot1" else 0.0)
        hold = np.asarray(loop.side.arms[i].hold_torque(q_first))
        assert np.linalg.norm(hold) > 1.0                       # gravity: not nothing
        limit = loop.specs[i].torque_limits          # resolved: the URDF effort limits
        for k in range(n):
            w = k / n
            # on the wire: the robot adds g(q) itself (``robot_adds``), so the wire carries
            # τ − g(q) and the hold torque is 0 there (the readings do not change)
            g = hold if loop.specs[i].gravity == "robot_adds" else 0.0
            np.testing.assert_allclose(ramped[k], (1 - w) * (hold - g) + w * plain[k],
                                       rtol=1e-12, atol=1e-9)
            assert np.all(np.abs(ramped[k]) <= np.abs(hold) + limit)
        np.testing.assert_array_equal(ramped[n:], plain[n:])   # then the controller's own
    # robot1 off its start: the controller's first torques are not its hold torque, and
    # the ramp changed them
    assert np.max(np.abs(np.array(runs["0"]["robot1"][0]) - runs["0.045"]["robot1"][0])) > 0.1


# ------------------------------------------------------------------ processes, slow


@pytest.mark.slow
def test_sigkill_of_one_serve_stops_the_other_naming_the_dead_arm(tmp_path):
    """The hub, the simulated driver and a serve per arm, each its own process; robot1's
    serve is killed (SIGKILL) once both are serving: robot2's serve stops, exit 1, its one
    line naming robot1 (behaviour, not latency: the timeouts are generous)."""
    cmd = [sys.executable, "-m", "drake_coop"]
    hub = subprocess.Popen(cmd + ["tcpq-hub", "--port", "0"], stderr=subprocess.PIPE,
                           text=True)
    procs = [hub]
    try:
        url = hub.stderr.readline().split("--lcm-url ")[1].rstrip(")\n")
        procs.append(subprocess.Popen(cmd + ["sim-driver", "paper", "--lcm-url", url,
                                             "--t-end", "30", "--quiet"],
                                      stderr=subprocess.DEVNULL))
        serves = {}
        for robot in ("robot1", "robot2"):
            serves[robot] = subprocess.Popen(
                cmd + ["serve", "paper", "--lcm-url", url, "--out", str(tmp_path / robot),
                       "--robot", robot, "--delay-margin", "0.002", "--t-end", "25",
                       "--status-wait", "120"], stderr=subprocess.PIPE, text=True)
            procs.append(serves[robot])
        for robot, proc in serves.items():         # wait until each says it is serving
            for line in proc.stderr:
                if "serving" in line:
                    break
        time.sleep(1.0)
        assert serves["robot2"].poll() is None and serves["robot1"].poll() is None
        serves["robot1"].send_signal(signal.SIGKILL)
        code = serves["robot2"].wait(120)
        rest = serves["robot2"].stderr.read()
        lines = [x for x in rest.splitlines() if x.startswith("drake-coop:")]
        assert code == 1, rest
        assert "robot1: its serve silent" in lines[0], rest
        meta = json.loads((tmp_path / "robot2" / "run.json").read_text())
        assert meta["watchdog"]["robot"] == "robot1"
        assert hub.poll() is None                          # the hub is up
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait(30)
