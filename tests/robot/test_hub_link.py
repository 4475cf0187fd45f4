"""The hub's death is caught, not an abort (:mod:`drake_coop.robot.hub_link`): LCM's C tcpq
client closes its socket when the hub goes and its next wait would abort the process
(``FD_SET(-1)``); :class:`WatchedLcm` raises :class:`HubLost` first, on both ways LCM
notices (a read of the hub's end, a failed send), and :func:`hub_monitor` fails a Simulator's
step first. The hub here is a forked child process, killed (SIGKILL): were the watch wrong,
this test process itself would abort (exit 134) — a failure no test can miss. (Not a thread:
LCM's client holds Python's lock while it waits for the hub's greeting.)"""

import multiprocessing
import os
import socket

import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.lcm import LcmInterfaceSystem

from drake_coop.robot.hub_link import (
    HUB_LOST_MARK,
    HubLink,
    HubLost,
    WatchedLcm,
    hub_monitor,
    is_hub_failure,
    tcpq_port,
)
from drake_coop.robot.tcpq_hub import TcpqHub


class Hub:
    """The project's hub in a forked child process (its listener bound here first)."""

    def __init__(self):
        hub = TcpqHub(0)
        self.url, self.port = hub.url, hub.port
        self.proc = multiprocessing.get_context("fork").Process(target=hub.serve_forever,
                                                                daemon=True)
        self.proc.start()
        hub._listener.close()               # the child's copy listens

    def kill(self):
        self.proc.kill()
        self.proc.join(30)


def connected():
    hub = Hub()
    lcm = WatchedLcm(hub.url)
    got = []
    lcm.Subscribe("X", got.append)
    lcm.Publish("X", b"abc")
    for _ in range(500):
        if lcm.HandleSubscriptions(10) or got:
            break
    assert got == [b"abc"]                  # a working connection first
    return hub, lcm


def test_the_watched_socket_is_the_one_lcm_opened_to_the_hub():
    hub, lcm = connected()
    try:
        probe = socket.socket(fileno=os.dup(lcm.link.fd))
        assert probe.getpeername()[1] == hub.port
        probe.close()
        assert not lcm.link.lost()
    finally:
        hub.kill()


def test_the_hubs_end_read_raises_hub_lost_instead_of_the_abort():
    """Subscribing only (a waiting serve, a lockstep driver): the wait that reads the hub's
    end returns, the next would abort; ``HubLost`` comes at the first."""
    hub, lcm = connected()
    hub.kill()
    with pytest.raises(HubLost, match="hub connection lost"):
        for _ in range(500):
            lcm.HandleSubscriptions(10)
    with pytest.raises(HubLost):            # and stays lost
        lcm.HandleSubscriptions(0)


def test_a_failed_send_raises_hub_lost_at_the_next_wait():
    """Publishing into the dead hub closes LCM's socket (and tries to reconnect); the next
    ``HandleSubscriptions`` would put -1 into an ``fd_set``: it raises before LCM's wait."""
    hub, lcm = connected()
    hub.kill()
    with pytest.raises(HubLost):
        for _ in range(500):
            lcm.Publish("X", b"x" * 100000)
            lcm.HandleSubscriptions(0)


def test_no_hub_listening_is_refused_at_the_start():
    hub = Hub()
    hub.kill()                              # the port is free again: nobody listens there
    with pytest.raises(ValueError, match="no hub listens at tcpq://127.0.0.1"):
        WatchedLcm(hub.url)


def test_a_simulator_pumping_lcm_fails_the_step_after_the_hubs_death():
    """The paced driver's ``LcmInterfaceSystem`` pumps LCM inside ``AdvanceTo``: the monitor
    fails the step after the death, before the next step's pump would abort."""
    hub, lcm = connected()
    builder = DiagramBuilder()
    builder.AddSystem(LcmInterfaceSystem(lcm))
    sim = Simulator(builder.Build())
    sim.set_monitor(hub_monitor(lcm, sim.get_system()))
    sim.AdvanceTo(0.01)
    hub.kill()
    with pytest.raises(RuntimeError) as caught:
        for k in range(1, 2000):
            sim.AdvanceTo(0.01 * k)
            lcm.Publish("X", b"y")
    assert is_hub_failure(caught.value) and HUB_LOST_MARK in str(caught.value)
    assert not is_hub_failure(RuntimeError("another failure"))


def test_other_providers_are_not_watched():
    lcm = WatchedLcm("memq://")
    got = []
    lcm.Subscribe("X", got.append)
    lcm.Publish("X", b"abc")
    lcm.HandleSubscriptions(0)
    assert got == [b"abc"] and not lcm.link.watched and not lcm.link.lost()


@pytest.mark.parametrize("url, port", [("tcpq://127.0.0.1:7701", 7701), ("tcpq://", 7700),
                                       ("tcpq://127.0.0.1", 7700), ("memq://", None),
                                       ("tcpq://h:x", None), (None, None)])
def test_the_hubs_port_from_the_url(url, port):
    assert tcpq_port(url) == port


def test_a_link_made_without_a_new_socket_is_not_found():
    link = HubLink(1)
    link.before()
    assert link.after() is False and link.lost() is False


def test_a_serve_waiting_when_the_hub_dies_stops_in_one_line(tmp_path, capsys, monkeypatch):
    """``serve`` waiting for its first status (no driver) when the hub is killed, half a
    second after it connected: exit 1, one line naming the lost hub, nothing written — not
    an abort, not a traceback."""
    import threading

    from drake_coop.cli import main
    from drake_coop.robot import cli

    hub = Hub()
    make = cli._make_lcm

    def connect(url):
        lcm = make(url)
        threading.Timer(0.5, hub.kill).start()
        return lcm

    monkeypatch.setattr(cli, "_make_lcm", connect)
    code = main(["serve", "paper", "--lcm-url", hub.url, "--out", str(tmp_path / "run"),
                 "--quiet", "--t-end", "1", "--delay-margin", "0.002", "--status-wait", "60"])
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if x.startswith("drake-coop:")]
    assert code == 1, err
    assert len(lines) == 1 and "hub connection lost" in lines[0], err
    assert "nothing written" in lines[0] and not (tmp_path / "run").exists()


# ------------------------------------------------------------------ processes, slow


@pytest.mark.slow
def test_the_hubs_death_mid_run_in_lockstep_costs_no_record(tmp_path):
    """The hub (its own process), the lockstep driver with ``--log`` and a serve per arm;
    the hub killed (SIGKILL) once both serve: each serve and the driver exit 1 with one
    line naming the lost hub (no abort), and their records are there up to the death — each
    serve's ``run.json`` (stopped, the reason) and ticks, the driver's ground truth. In
    lockstep, so the same on any load."""
    import json
    import signal
    import subprocess
    import sys
    import threading
    import time

    import numpy as np

    cmd = [sys.executable, "-m", "drake_coop"]
    hub = subprocess.Popen(cmd + ["tcpq-hub", "--port", "0"], stderr=subprocess.PIPE,
                           text=True)
    procs = {"hub": hub}
    err: dict[str, list[str]] = {}
    readers: dict = {}
    truth = tmp_path / "truth.npz"

    def drain(name):             # every pipe read to its end: no process blocks on stderr
        err[name] = []
        readers[name] = threading.Thread(target=lambda: err[name].extend(procs[name].stderr),
                                         daemon=True)
        readers[name].start()

    try:
        url = hub.stderr.readline().split("--lcm-url ")[1].rstrip(")\n")
        drain("hub")
        common = ["--lcm-url", url, "--lockstep", "--t-end", "60"]
        procs["driver"] = subprocess.Popen(
            cmd + ["sim-driver", "paper", *common, "--quiet", "--log", str(truth),
                   "--command-wait", "60"], stderr=subprocess.PIPE, text=True)
        drain("driver")
        for robot in ("robot1", "robot2"):
            procs[robot] = subprocess.Popen(
                cmd + ["serve", "paper", *common, "--out", str(tmp_path / robot), "--robot",
                       robot, "--delay-margin", "0.002", "--status-wait", "120"],
                stderr=subprocess.PIPE, text=True)
            drain(robot)
        deadline = time.monotonic() + 240            # until each says it is serving
        while not all(any("drake-coop: serving" in x for x in err[r])
                      for r in ("robot1", "robot2")):
            assert time.monotonic() < deadline, err
            time.sleep(0.05)
        time.sleep(1.0)
        hub.send_signal(signal.SIGKILL)
        hub.wait(30)
        ends = {}
        for name in ("robot1", "robot2", "driver"):
            code = procs[name].wait(120)
            readers[name].join(30)                   # its pipe read to the end
            ends[name] = (code, [x.rstrip("\n") for x in err[name]
                                 if x.startswith("drake-coop:")])
    finally:
        for proc in procs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait(30)
    for name, (code, lines) in ends.items():
        assert code == 1, "\n".join([name, *lines])
        lost = [x for x in lines if "hub connection lost" in x]
        assert len(lost) == 1 and "stopped at t = " in lost[0], "\n".join([name, *lines])
    for robot in ("robot1", "robot2"):
        meta = json.loads((tmp_path / robot / "run.json").read_text())
        assert meta["status"] == "stopped" and "hub connection lost" in meta["message"]
        rows = (tmp_path / robot / "pacing.csv").read_text().splitlines()
        assert len(rows) > 2                              # the ticks up to the death
    log = np.load(truth)
    assert len(log["t"]) > 2 and log["t"][-1] > 0          # the ground truth up to the death
    assert np.all(np.isfinite(log["arm0_state"]))
