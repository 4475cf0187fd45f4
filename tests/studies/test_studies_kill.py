"""Killed processes: a case whose process dies is retried, never stored; a study killed with
``kill -9`` takes its case processes with it; a killed and resumed study equals a fresh one
cell for cell; Ray's driver exits 143 on SIGTERM and leaves none of its helpers."""

import csv
import multiprocessing
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drake_coop.cli import main

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}

# 2 x 2 with a short t_end; k_d = 1000 makes the observer diverge within 0.2 s (a result).
GRID = """
name: small
t_end: 1.0
phase: all
grid:
  control_period: [0.003, 0.009]
  robots.*.gains.k_d: [40, 1000]
metrics: [worst.position_error.max, worst.observation_error.max]
"""


def _cells(out: Path) -> dict[str, dict]:
    """results.csv by hash, every column but the wall time."""
    with open(out / "results.csv", newline="") as f:
        return {r["hash"]: {k: v for k, v in r.items() if k != "wall_time_s"}
                for r in csv.DictReader(f)}


def _children(pid: int) -> list[int]:
    found = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
                cmd = Path(f"/proc/{entry}/cmdline").read_bytes()
            except OSError:
                continue
            if int(stat[stat.rindex(")") + 2:].split()[1]) == pid and b"spawn_main" in cmd:
                found.append(int(entry))
    return found


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rindex(")") + 2] != "Z"


def _start(path: Path, out: Path, *extra: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "drake_coop", "study", str(path), "--out",
                             str(out), "--workers", "1", *extra], env=ENV, cwd=ROOT,
                            stderr=subprocess.PIPE, text=True)


def _a_running_case(proc: subprocess.Popen, out: Path, after_cases: int = 0) -> int:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read()
        done = len(list((out / "cases").glob("*.json"))) if (out / "cases").is_dir() else 0
        children = _children(proc.pid)
        if done >= after_cases and children:
            time.sleep(0.5)                         # inside the case, not at its start
            return children[0]
        time.sleep(0.05)
    raise AssertionError("no case process appeared")


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fresh")
    path = tmp / "small.yaml"
    path.write_text(GRID)
    assert main(["study", str(path), "--out", str(tmp / "out"), "--quiet"]) == 0
    return path, _cells(tmp / "out")


@pytest.mark.slow
def test_a_killed_case_is_retried_not_stored_and_the_resume_equals_a_fresh_study(
        fresh, tmp_path):
    path, reference = fresh
    out = tmp_path / "out"
    proc = _start(path, out)
    victim = _a_running_case(proc, out)
    os.kill(victim, signal.SIGKILL)                  # as the OOM killer does
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err
    assert "killed by SIGKILL; it runs again on the next resume" in err
    assert "1 of 4 cases did not finish" in err and "Traceback" not in err
    assert len(list((out / "cases").glob("*.json"))) == 3
    (died,) = (out / "cases").glob("*.died")
    cells = _cells(out)
    assert cells[died.stem]["status"] == "died"
    resumed = subprocess.run([sys.executable, "-m", "drake_coop", "study", str(path), "--out",
                              str(out)], env=ENV, cwd=ROOT, stderr=subprocess.PIPE, text=True,
                             timeout=120)
    assert resumed.returncode == 0, resumed.stderr
    assert "3 already finished, running 1 (1 again: their process died before)" in \
        resumed.stderr
    assert not list((out / "cases").glob("*.died"))
    assert _cells(out) == reference


@pytest.mark.slow
def test_kill_9_of_a_study_ends_its_cases_and_the_resume_equals_a_fresh_study(fresh, tmp_path):
    path, reference = fresh
    out = tmp_path / "out"
    proc = _start(path, out, "--quiet")
    case = _a_running_case(proc, out, after_cases=1)
    proc.kill()
    proc.communicate(timeout=30)
    deadline = time.monotonic() + 5
    while _alive(case) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(case), "the case process outlived its study"
    assert main(["study", str(path), "--out", str(out), "--quiet"]) == 0
    assert _cells(out) == reference


_MIDDLE = """
import multiprocessing, sys, time
from drake_coop.studies.engines import die_with_parent

def grandchild(parent):
    die_with_parent(parent)
    time.sleep(60)

if __name__ == "__main__":
    import os
    p = multiprocessing.get_context("spawn").Process(target=grandchild, args=(os.getpid(),))
    p.start()
    print(p.pid, flush=True)
    time.sleep(60)
"""


def test_a_worker_dies_with_its_parent_even_on_kill_9(tmp_path):
    script = tmp_path / "middle.py"
    script.write_text(_MIDDLE)
    middle = subprocess.Popen([sys.executable, str(script)], env=ENV, stdout=subprocess.PIPE,
                              text=True)
    worker = int(middle.stdout.readline())
    time.sleep(0.5)
    assert _alive(worker)
    middle.kill()
    middle.wait()
    deadline = time.monotonic() + 3
    while _alive(worker) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(worker)


def test_a_worker_whose_study_is_gone_exits_quietly(tmp_path):
    """The record cannot be sent (the study's end of the pipe is closed): exit 1, no
    traceback on stderr."""
    context = multiprocessing.get_context("spawn")
    receiver, sender = context.Pipe(duplex=False)
    receiver.close()
    log = tmp_path / "stderr.txt"
    process = context.Process(target=_quiet_child, args=(sender, str(log)))
    process.start()
    sender.close()
    process.join(timeout=60)
    assert process.exitcode == 1
    text = log.read_text()
    assert "Traceback" not in text and "BrokenPipe" not in text, text


def _quiet_child(sender, log: str) -> None:
    sys.stderr = open(log, "w", buffering=1)
    from drake_coop.studies.engines import _child, run_case
    _child(sender, run_case, ("not: [a scenario", None))   # a quick 'error' record, then send


_DRIVER = """
import subprocess, sys, time
sys.path.insert(0, sys.argv[1])
from drake_coop.studies.reaper import start
reaper = start()
helper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"],
                          start_new_session=True)
print(reaper.process.pid, helper.pid, flush=True)
time.sleep(60)
"""


def test_the_reaper_ends_the_helpers_of_a_killed_driver_and_spares_a_clean_one(tmp_path):
    script = tmp_path / "driver.py"
    script.write_text(_DRIVER)
    driver = subprocess.Popen([sys.executable, str(script), str(ROOT)], stdout=subprocess.PIPE,
                              text=True)
    reaper, helper = map(int, driver.stdout.readline().split())
    time.sleep(0.8)                                    # the reaper has seen the helper
    driver.kill()
    driver.wait()
    deadline = time.monotonic() + 5
    while (_alive(helper) or _alive(reaper)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(helper) and not _alive(reaper)
    # a driver that says "done" keeps what is left running (Ray was shut down by then)
    from drake_coop.studies.reaper import start
    watcher = start()
    keep = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    time.sleep(0.8)
    watcher.done()
    assert watcher.process.returncode == 0 and _alive(keep.pid)
    keep.kill()
    keep.wait()


@pytest.mark.slow
@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGKILL, -9)])
def test_ray_driver_stopped_or_killed_leaves_no_helper(fresh, tmp_path, signum, code):
    """SIGTERM: exit 143 after ray.shutdown(); kill -9: the watcher ends Ray's helpers (its
    agents outlived the driver before)."""
    pytest.importorskip("ray")
    path, _ = fresh
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "drake_coop", "study", str(path), "--out",
                             str(out), "--ray", "--workers", "1", "--quiet"], env=ENV,
                            cwd=ROOT, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list((out / "cases").glob("*.json")) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read()
        time.sleep(0.1)
    started = _descendants(proc.pid)
    assert started                                   # Ray's helpers
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    assert "Traceback" not in err
    deadline = time.monotonic() + 10
    while any(map(_alive, started)) and time.monotonic() < deadline:
        time.sleep(0.1)
    left = {pid: _cmdline(pid) for pid in started if _alive(pid)}
    assert not left, left


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes()[:100].decode(errors="replace")
    except OSError:
        return ""


def _descendants(pid: int) -> set[int]:
    tree: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            tree.setdefault(int(stat[stat.rindex(")") + 2:].split()[1]), []).append(int(entry))
    found, stack = set(), [pid]
    while stack:
        for child in tree.get(stack.pop(), []):
            found.add(child)
            stack.append(child)
    return found
