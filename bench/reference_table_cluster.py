"""The reference table on a Ray cluster of two nodes on 127.0.0.1, a worker killed, resumed.

``python bench/reference_table_cluster.py --out DIR [--draws 2] [--port 6391]`` starts a head
node and a worker node with Ray's own command (``ray start --head --port P --num-cpus 1
--block`` and ``ray start --address 127.0.0.1:P --num-cpus 1 --block``, each in its own
process group, ended by its group id when the run is over; both with ``--temp-dir`` a folder
of the run's own, removed after, so that Ray's address file ``ray_current_cluster``, which
``ray start`` writes into its temporary folder, is not left in the shared ``/tmp/ray`` for a
later ``ray.init()`` to look for a dead cluster), then:

1. runs ``drake-coop reference-table --ray 127.0.0.1:P`` (2 rows × 2 columns, ``--draws``
   draws, a 6 s segment, batches of 1 case) and kills one Ray worker process (SIGKILL, the
   first ``ray::run_batch`` process found under this run's nodes) while it runs a case;
2. runs the same command again: the cases finished before are kept, the killed one runs again;
3. runs the same table locally (``--workers 1``) into ``DIR/local`` and compares the
   per-case numbers (``cases.csv``) of the two: the same seeds must give the same numbers.

Prints one line per step and ``same numbers: True/False``; exit 1 when they differ or a case
is missing.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROWS, COLS, T_END = "observer,sensor_3", "exact,model_30", "6"
BIN = Path(sys.executable).parent
#: Ray 2.59 and later turn token authentication on for a head started on this machine; a
#: worker node (and the driver) must then run with it too, or the head refuses them
#: ("InvalidAuthToken"). Older Rays ignore the variable.
ENV = {**os.environ, "RAY_AUTH_MODE": "token"}


def _start(args: list[str], log: Path, temp_dir: Path) -> subprocess.Popen:
    """One Ray node (``ray start ARGS --temp-dir TEMP_DIR --block``) in its own process
    group, its output into ``log``."""
    with open(log, "w") as output:
        return subprocess.Popen([str(BIN / "ray"), "start", *args, "--temp-dir",
                                 str(temp_dir), "--block"], stdout=output,
                                stderr=subprocess.STDOUT, start_new_session=True, env=ENV)


def _temp_dir() -> Path:
    """The nodes' temporary folder: a new one, short (Ray's socket paths live under it)."""
    return Path(tempfile.mkdtemp(prefix="ray_bench_", dir="/tmp"))


def _group_alive(pgid: int) -> bool:
    """Whether a process of the group ``pgid`` still exists."""
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def _stop(nodes: list[subprocess.Popen], temp_dir: Path, grace: float = 30.0) -> None:
    """End the nodes by their process groups — SIGTERM, then SIGKILL to a group still there
    after ``grace`` seconds — wait until no process of the groups is left (Ray's own
    processes outlive ``ray start`` by a moment), and remove their temporary folder."""
    for p in nodes:
        try:
            os.killpg(p.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
    for sig, wait in ((None, grace), (signal.SIGKILL, grace)):
        end = time.monotonic() + wait
        for p in nodes:
            if sig is not None and _group_alive(p.pid):
                os.killpg(p.pid, sig)
            while _group_alive(p.pid) and time.monotonic() < end:
                p.poll()                   # reaps ``ray start`` itself
                time.sleep(0.2)
    for p in nodes:
        p.wait()
    shutil.rmtree(temp_dir, ignore_errors=True)


def _table(out: Path, extra: list[str]) -> subprocess.Popen:
    return subprocess.Popen([str(BIN / "drake-coop"), "reference-table", "--out", str(out),
                             "--rows", ROWS, "--columns", COLS, "--t-end", T_END, "--batch",
                             "1", "--quiet", *extra], env=ENV)


def _descendants(roots: list[int]) -> list[int]:
    """The processes descended from ``roots`` (Ray's workers are the raylet's children)."""
    parent = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parent[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    found, frontier = [], list(roots)
    while frontier:
        pid = frontier.pop()
        children = [c for c, p in parent.items() if p == pid]
        found += children
        frontier += children
    return found


def _kill_one_worker(groups: list[int], timeout: float = 300.0) -> int | None:
    """SIGKILL the first Ray worker running ``run_batch`` under this run's nodes."""
    end = time.time() + timeout
    while time.time() < end:
        for pid in _descendants(groups):
            try:
                cmd = Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace")
            except OSError:
                continue
            if "run_batch" in cmd:
                time.sleep(1.0)            # inside its case
                os.kill(pid, signal.SIGKILL)
                return pid
        time.sleep(0.2)
    return None


def _numbers(out: Path) -> dict:
    with open(out / "cases.csv") as f:
        return {r["hash"]: (r["status"], r["squeeze"], r["estimate"]) for r in csv.DictReader(f)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", required=True)
    parser.add_argument("--draws", type=int, default=2)
    parser.add_argument("--port", type=int, default=6391)
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    address = f"127.0.0.1:{args.port}"
    draws = ["--draws", str(args.draws)]
    temp_dir = _temp_dir()
    nodes = [_start(["--head", "--port", str(args.port), "--num-cpus", "1",
                     "--include-dashboard", "false"], out / "head.log", temp_dir)]
    try:
        time.sleep(15.0)
        nodes.append(_start(["--address", address, "--num-cpus", "1"], out / "worker.log",
                            temp_dir))
        time.sleep(15.0)
        groups = [p.pid for p in nodes]
        run = _table(out / "cluster", ["--ray", address, *draws])
        killed = _kill_one_worker(groups)
        first = run.wait()
        print(f"first run on {address}: exit {first}, killed Ray worker {killed}", flush=True)
        second = _table(out / "cluster", ["--ray", address, *draws]).wait()
        print(f"resumed: exit {second}")
    finally:
        _stop(nodes, temp_dir)
    local = _table(out / "local", ["--workers", "1", *draws]).wait()
    print(f"local run: exit {local}")
    a, b = _numbers(out / "cluster"), _numbers(out / "local")
    same = a == b and all(v[0] != "pending" for v in a.values())
    print(f"cases: {len(a)} on the cluster, {len(b)} local; same numbers: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
