"""A watcher that ends the helper processes of a local Ray instance when its driver dies.

``ray.init()`` on one machine starts helpers (GCS server, raylet, dashboard, agents,
workers). Those Ray starts itself die with the driver, but the raylet's agents and idle
workers do not: after a ``kill -9`` of the driver they were seen running on (Ray 2.60). The
driver therefore starts this watcher first (:func:`start`), as a separate process in its own
session that holds the reading end of a pipe from the driver:

* every 0.25 s it records every descendant of the driver (pid and start time, from
  ``/proc``), so it still knows the agents after their raylet died and they were re-parented;
* when the pipe closes *without* the word ``done`` — the driver died, however (``kill -9``
  included: the kernel closes its end) — it sends SIGKILL to every recorded process that
  still runs with the same start time (a reused pid is never touched), then, three times
  0.1 s apart, to every process whose command line names the driver's Ray session
  (``session_<date>_<time>_<µs>_<driver pid>``): a worker the raylet started in the last
  0.25 s and that was re-parented when the raylet died is caught that way; then it exits;
* when the driver writes ``done`` (after ``ray.shutdown()``) it exits without killing.

Linux only (it reads ``/proc``); elsewhere :func:`start` returns None and nothing watches.
This file runs as a script (``python reaper.py PID``) so that it imports nothing of
``drake_coop``.
"""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

__all__ = ["Reaper", "start"]


def _start_time(pid: int) -> str | None:
    """Field 22 of ``/proc/PID/stat`` (start time in clock ticks), or None if gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text[text.rindex(")") + 2:].split()[19]


def _children() -> dict[int, list[int]]:
    """Parent pid -> child pids, of every process."""
    tree: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            text = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        ppid = int(text[text.rindex(")") + 2:].split()[1])
        tree.setdefault(ppid, []).append(int(entry))
    return tree


def _descendants(roots: set[int]) -> set[int]:
    tree = _children()
    found, stack = set(), list(roots)
    while stack:
        for child in tree.get(stack.pop(), []):
            if child not in found:
                found.add(child)
                stack.append(child)
    return found


def watch(driver: int, pipe) -> int:
    """The watcher's loop (see the module's docstring); returns its exit code.

    Parameters
    ----------
    driver : int
        The driver's pid.
    pipe : file
        The reading end of the driver's pipe (``done`` written on a clean shutdown).
    """
    me = os.getpid()
    seen: dict[int, str] = {}
    data = b""
    while True:
        ready, _, _ = select.select([pipe], [], [], 0.25)
        roots = {driver} | set(seen)
        for pid in _descendants(roots) - {me}:
            if pid not in seen:
                start = _start_time(pid)
                if start is not None:
                    seen[pid] = start
        if ready:
            chunk = os.read(pipe.fileno(), 64)
            data += chunk
            if not chunk:
                break
    if b"done" in data:
        return 0
    for pid in _descendants(set(seen)) - {me}:       # children started since the last look
        seen.setdefault(pid, _start_time(pid) or "")
    for pid, start in seen.items():
        if start and _start_time(pid) == start:
            _kill(pid)
    session = re.compile(rb"session_\d{4}-\d\d-\d\d_\d\d-\d\d-\d\d_\d+_%d(?!\d)" % driver)
    for _ in range(3):
        for pid in _session_members(session) - {me}:
            _kill(pid)
        time.sleep(0.1)
    return 0


def _kill(pid: int) -> None:
    try:
        os.kill(pid, signal.SIGKILL)
    except OSError:
        pass


def _session_members(session: re.Pattern) -> set[int]:
    """Processes whose command line names the driver's Ray session."""
    found = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                cmdline = Path(f"/proc/{entry}/cmdline").read_bytes()
            except OSError:
                continue
            if session.search(cmdline):
                found.add(int(entry))
    return found


class Reaper:
    """The driver's handle on its watcher: :meth:`done` after a clean ``ray.shutdown()``.

    Parameters
    ----------
    process : subprocess.Popen
        The watcher's process.
    """

    def __init__(self, process: subprocess.Popen):
        self.process = process

    def done(self) -> None:
        """Tell the watcher that the driver shut Ray down itself, and let it exit."""
        try:
            self.process.stdin.write(b"done\n")
            self.process.stdin.close()
        except OSError:
            pass
        try:
            self.process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()


def start() -> Reaper | None:
    """Start the watcher of this process (None where ``/proc`` is missing).

    Returns
    -------
    Reaper or None
        The handle.
    """
    if not sys.platform.startswith("linux") or not os.path.isdir("/proc"):
        return None
    process = subprocess.Popen(
        [sys.executable, "-I", "-S", os.path.abspath(__file__), str(os.getpid())],
        stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        start_new_session=True, close_fds=True)
    return Reaper(process)


if __name__ == "__main__":
    signal.signal(signal.SIGINT, signal.SIG_IGN)      # Ctrl-C is for the driver
    sys.exit(watch(int(sys.argv[1]), sys.stdin.buffer))
