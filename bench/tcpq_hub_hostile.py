"""The tcpq hub's relay latency between two well-behaved clients, quiet and while hostile
clients do their worst (500 nested groups, a catastrophic-backtracking pattern, a reader that
never reads, a client flooding its own channel, garbage, 50 idle connections); one JSON::

    python -m bench.tcpq_hub_hostile [--messages 2000] [--sched fifo] [--out hub.json]

The hub runs as its own process (``drake-coop tcpq-hub --port 0``); the two measuring
clients are plain sockets speaking LCM's tcpq protocol in this process, the hostile clients
in a child process of their own. A round trip is a 200-byte publish by one client and its
arrival at the other (both subscribed), timed with ``perf_counter``; p50/p99/max of each
phase. ``--sched fifo`` runs them as the cell runs them (``bench/paced_split.py``): the hub
under ``chrt -f`` at the highest priority (70), the measuring clients (a serve's place) at
60, the hostile clients at the default priority (a local process is given no real-time
priority); ``default``: every process at the default priority.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

from drake_coop.robot.tcpq_hub import MAGIC_CLIENT, PUBLISH, SUBSCRIBE, VERSION


def _client(port: int, greet: bool = True) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    if greet:
        sock.sendall(struct.pack(">II", MAGIC_CLIENT, VERSION))
        _exactly(sock, 8)
    return sock


def _exactly(sock: socket.socket, n: int) -> bytes:
    out = b""
    while len(out) < n:
        chunk = sock.recv(n - len(out))
        if not chunk:
            raise ConnectionError("closed")
        out += chunk
    return out


def _frame(kind: int, channel: str, data: bytes | None = None) -> bytes:
    c = channel.encode()
    head = struct.pack(">II", kind, len(c)) + c
    return head if data is None else head + struct.pack(">I", len(data)) + data


def _receive(sock: socket.socket) -> bytes:
    _, size = struct.unpack(">II", _exactly(sock, 8))
    _exactly(sock, size)
    (length,) = struct.unpack(">I", _exactly(sock, 4))
    return _exactly(sock, length)


def _relay(port: int, messages: int) -> list[float]:
    a, b = _client(port), _client(port)
    b.sendall(_frame(SUBSCRIBE, "BENCH"))
    time.sleep(0.2)
    payload = b"x" * 200
    out = []
    for _ in range(messages):
        start = time.perf_counter()
        a.sendall(_frame(PUBLISH, "BENCH", payload))
        _receive(b)
        out.append(time.perf_counter() - start)
    a.close()
    b.close()
    return out


def _hostile(port: int, stop: threading.Event) -> None:
    held = [_client(port, greet=k % 2 == 0) for k in range(50)]
    bad = _client(port)
    bad.sendall(_frame(SUBSCRIBE, "(" * 100 + ")" * 100) + _frame(SUBSCRIBE, "(a|a)*b"))
    lazy = _client(port)
    lazy.sendall(_frame(SUBSCRIBE, "FLOOD"))
    flood = _client(port)
    flood.sendall(_frame(SUBSCRIBE, "SELF"))
    flood.setblocking(False)
    big = _frame(PUBLISH, "FLOOD", b"z" * 60000)
    own = _frame(PUBLISH, "SELF", b"f" * 8000)
    long_name = _frame(PUBLISH, "a" * 1000, b"y")
    while not stop.is_set():
        for sock, data in ((flood, own), (flood, big), (flood, long_name)):
            try:
                sock.send(data)
            except OSError:
                pass
        try:
            junk = _client(port, greet=False)
            junk.sendall(bytes(range(256)))
            junk.close()
        except OSError:
            pass
        time.sleep(0.001)
    for sock in held + [bad, lazy, flood]:
        sock.close()


def _hostile_process(port: int, stop) -> None:
    """:func:`_hostile` in a child process at the default priority, until ``stop`` is set."""
    if hasattr(os, "sched_setscheduler"):
        try:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        except OSError:
            pass
    _hostile(port, stop)


def _port(lines, hub) -> int:
    """The hub's port, from its first line (``… --lcm-url tcpq://127.0.0.1:PORT)``)."""
    deadline = time.perf_counter() + 60
    while time.perf_counter() < deadline and hub.poll() is None:
        lines.seek(0)
        first = lines.readline()
        if first.endswith("\n"):
            return int(first.rsplit(":", 1)[1].rstrip(")\n"))
        time.sleep(0.05)
    raise RuntimeError("the hub did not start")


def _stats(values: list[float]) -> dict:
    v = np.asarray(values) * 1e3
    return {"n": int(v.size), "p50_ms": float(np.percentile(v, 50)),
            "p99_ms": float(np.percentile(v, 99)), "max_ms": float(v.max())}


def main(argv=None) -> int:
    """Run both phases and write the JSON.

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
    parser.add_argument("--messages", type=int, default=2000)
    parser.add_argument("--sched", choices=("fifo", "default"), default="default")
    parser.add_argument("--hub-priority", type=int, default=70)
    parser.add_argument("--client-priority", type=int, default=60)
    parser.add_argument("--out", default=None)
    args = parser.parse_args(argv)
    fifo = args.sched == "fifo"
    prefix = ["chrt", "-f", str(args.hub_priority)] if fifo else []
    # the hub's lines go to a file, not to a reading thread here: a thread that is not
    # real-time holding Python's lock would delay the measuring one (priority inversion)
    lines = tempfile.TemporaryFile("w+")
    hub = subprocess.Popen(prefix + [sys.executable, "-m", "drake_coop", "tcpq-hub", "--port",
                                     "0"], stderr=lines, text=True)
    try:
        port = _port(lines, hub)
        stop = multiprocessing.get_context("fork").Event()
        attacker = multiprocessing.get_context("fork").Process(
            target=_hostile_process, args=(port, stop), daemon=True)
        if fifo:                    # the measuring clients: a serve's priority
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(args.client_priority))
        quiet = _relay(port, args.messages)
        attacker.start()
        time.sleep(1.0)
        hostile = _relay(port, args.messages)
        stop.set()
        attacker.join(10)
        if fifo:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        lines.seek(0)
        result = {"quiet": _stats(quiet), "hostile": _stats(hostile),
                  "hub_alive": hub.poll() is None, "hub_lines": len(lines.readlines()) - 1,
                  "sched": args.sched,
                  "priority": {"hub": args.hub_priority, "clients": args.client_priority,
                               "hostile": "default"} if fifo else None,
                  "cpus": len(os.sched_getaffinity(0)),
                  "loadavg": open("/proc/loadavg").read().split()[:3]}
    finally:
        hub.terminate()
        hub.wait(10)
    text = json.dumps(result, indent=1)
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
