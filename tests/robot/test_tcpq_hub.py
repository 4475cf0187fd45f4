"""The tcpq hub (:mod:`drake_coop.robot.tcpq_hub`, 127.0.0.1 only), run as its own process
(``drake-coop tcpq-hub``; ``DrakeLcm``'s connection blocks holding the GIL, so the hub cannot
be a thread of the process that connects): Drake's own LCM client
(``DrakeLcm("tcpq://127.0.0.1:PORT")``, LCM's C provider) publishes and receives through it;
a split run as two processes over it (slow)."""

import json
import os
import subprocess
import sys
import time

import pytest
from pydrake.lcm import DrakeLcm

from drake_coop.robot.tcpq_hub import TcpqHub

CLI = [sys.executable, "-m", "drake_coop"]


@pytest.fixture
def hub_url():
    proc = subprocess.Popen(CLI + ["tcpq-hub", "--port", "0"], stderr=subprocess.PIPE,
                            text=True)
    try:
        line = proc.stderr.readline()
        url = line.split("--lcm-url ")[1].rstrip(")\n")
        assert url.startswith("tcpq://127.0.0.1:"), line
        yield url
    finally:
        proc.terminate()
        proc.wait(10)


def pump(lcms, until, timeout=5.0):
    end = time.perf_counter() + timeout
    while not until() and time.perf_counter() < end:
        for lcm in lcms:
            lcm.HandleSubscriptions(10)


def test_messages_go_through_the_hub_to_every_subscriber_the_sender_too(hub_url):
    a, b = DrakeLcm(hub_url), DrakeLcm(hub_url)
    got = {"a": [], "b": [], "b_other": []}
    a.Subscribe("STATUS", lambda d: got["a"].append(bytes(d)))
    b.Subscribe("STATUS", lambda d: got["b"].append(bytes(d)))
    b.Subscribe("OTHER", lambda d: got["b_other"].append(bytes(d)))
    time.sleep(0.2)                        # the subscriptions reach the hub
    payloads = [bytes([k]) * (1 + 97 * k) for k in range(20)]   # 1 B to 1.8 kB
    for p in payloads:
        a.Publish("STATUS", p)
    pump([a, b], lambda: len(got["a"]) == len(got["b"]) == len(payloads))
    assert got["b"] == payloads and got["a"] == payloads      # in order, whole
    assert got["b_other"] == []


def test_a_client_that_breaks_the_protocol_is_dropped_and_the_hub_goes_on(hub_url):
    import socket

    bad = socket.create_connection(("127.0.0.1", int(hub_url.rsplit(":", 1)[1])))
    bad.sendall(b"GET / HTTP/1.0\r\n\r\n")
    bad.settimeout(2)
    assert bad.recv(16) == b""                 # closed by the hub
    a, b = DrakeLcm(hub_url), DrakeLcm(hub_url)
    got = []
    b.Subscribe("S", lambda d: got.append(bytes(d)))
    time.sleep(0.2)
    a.Publish("S", b"ok")
    pump([a, b], lambda: got)
    assert got == [b"ok"]


def _fifo_allowed() -> bool:
    import shutil

    if shutil.which("chrt") is None:
        return False
    return subprocess.run(["chrt", "-f", "50", "true"], capture_output=True).returncode == 0


def test_the_hub_refuses_a_bad_port_naming_it():
    with pytest.raises(ValueError, match="port"):
        TcpqHub(70000)


@pytest.mark.slow
def test_a_paced_split_run_as_two_processes_over_the_hub(tmp_path, hub_url):
    """sim-driver and serve, two processes on 127.0.0.1 through the hub (under SCHED_FIFO
    where granted): the statuses and commands go through it and serve's loop runs, paced,
    with its record kept. Whether the loop stays stable is the machine's matter (a diverging
    run is a result: exit 1 with the watchdog's one line), measured in real_robot.md."""
    env = dict(os.environ)
    rt = ["chrt", "-f", "50"] if _fifo_allowed() else []
    cmd = rt + CLI
    driver = subprocess.Popen(cmd + ["sim-driver", "paper", "--lcm-url", hub_url,
                                     "--t-end", "3", "--quiet"], env=env,
                              stderr=subprocess.PIPE, text=True)
    out = tmp_path / "serve"
    serve = subprocess.run(cmd + ["serve", "paper", "--lcm-url", hub_url, "--out", str(out),
                                  "--t-end", "2", "--delay-margin", "0.002",
                                  "--status-wait", "60", "--quiet"],
                           env=env, stderr=subprocess.PIPE, text=True, timeout=600)
    driver.wait(timeout=120)
    lines = [x for x in serve.stderr.splitlines() if x.startswith("drake-coop:")]
    assert serve.returncode in (0, 1) and len(lines) == 1, serve.stderr
    meta = json.loads((out / "run.json").read_text())
    assert meta["lcm_url"].startswith("tcpq://127.0.0.1:")
    if serve.returncode == 0:
        assert meta["status"] == "ok" and meta["pacing"]["ticks"] == int(round(2 / 0.009)) + 1
    else:
        assert meta["status"] == "stopped" and "watchdog" in lines[0], lines
    assert meta["pacing"]["ticks"] > 50                  # it ticked on the hub's statuses
    assert meta["pacing"]["status_age_p99_s"] < 0.05     # fresh ones (max_status_age)
