"""Running studies end to end: results store, resume after a kill, Ctrl-C, Ray = local."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from drake_coop.cli import main
from drake_coop.studies import expand, load_study

ROOT = Path(__file__).resolve().parents[2]

# 2 x 2 with a short t_end; k_d = 1000 makes the forward-Euler observer (15)-(16) unstable
# (|1 - h k_d| >= 2): its error grows every tick until a joint passes its limit, so two cases
# diverge (recorded, not fatal).
GRID = """
name: small
t_end: {t_end}
phase: all
grid:
  control_period: [0.003, 0.009]
  robots.*.gains.k_d: [40, 1000]
metrics: [worst.position_error.max, worst.observation_error.max]
"""


def _write(tmp_path: Path, t_end: float = 0.5) -> Path:
    path = tmp_path / "small.yaml"
    path.write_text(GRID.format(t_end=t_end))
    return path


def _rows(out: Path) -> list[dict]:
    with open(out / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("study")
    path = _write(tmp)
    out = tmp / "local"
    code = main(["study", str(path), "--out", str(out), "--workers", "2", "--quiet"])
    return code, path, out


def test_grid_end_to_end_writes_cases_csv_json_and_figures(local_run):
    code, path, out = local_run
    assert code == 0
    cases = expand(load_study(path))
    rows = _rows(out)
    assert [r["hash"] for r in rows] == [c.hash for c in cases]
    assert [(float(r["control_period"]), float(r["robots.*.gains.k_d"])) for r in rows] == [
        (0.003, 40), (0.003, 1000), (0.009, 40), (0.009, 1000)]
    assert [r["status"] for r in rows] == ["ok", "diverged", "ok", "diverged"]
    for r in rows:
        if r["status"] == "ok":
            assert float(r["t_reached"]) == pytest.approx(0.5, abs=0.01)
            assert 0 < float(r["worst.position_error.max"]) < 1e-3
        else:
            assert r["message"].startswith("diverged at t = ")
            assert float(r["t_reached"]) < 0.5
    for c in cases:
        record = json.loads((out / "cases" / f"{c.hash}.json").read_text())
        assert record["scenario_yaml"] == c.scenario_yaml and record["params"] == c.params
        # summary column = the full metrics' value (worst over robots of the max of x, y, z)
        if record["status"] == "ok":
            all_ = [record["metrics"][r]["all"] for r in ("robot1", "robot2")]
            worst = max(m[e]["max"] for m in all_ for e in ("x_tilde", "y_tilde", "z_tilde"))
            row = next(r for r in _rows(out) if r["hash"] == c.hash)
            assert float(row["worst.position_error.max"]) == worst
    doc = json.loads((out / "study.json").read_text())
    assert doc["counts"] == {"ok": 2, "diverged": 2} and doc["n_cases"] == 4
    for name in ("small_vs_control_period.png", "small_vs_gains_k_d.png", "small_map.png"):
        assert (out / name).stat().st_size > 5_000
    assert not list(out.rglob("*.tmp"))


def test_rerun_skips_finished_cases_and_plot_redraws(local_run, capsys):
    code, path, out = local_run
    stamps = {p: p.stat().st_mtime_ns for p in (out / "cases").glob("*.json")}
    assert main(["study", str(path), "--out", str(out)]) == 0
    assert "4 already finished, running 0" in capsys.readouterr().err
    assert {p: p.stat().st_mtime_ns for p in (out / "cases").glob("*.json")} == stamps
    (out / "small_map.png").unlink()
    assert main(["study", "--plot", str(out), "--quiet"]) == 0
    assert (out / "small_map.png").is_file()
    assert main(["study", "--plot", str(out / "nowhere"), "--quiet"]) == 2


def _kill_after_first_case(path: Path, out: Path, signum: int) -> int:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "drake_coop", "study", str(path), "--out",
                             str(out), "--workers", "1", "--quiet"], env=env, cwd=ROOT,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list((out / "cases").glob("*.json")) and time.monotonic() < deadline:
        assert proc.poll() is None, proc.stderr.read()
        time.sleep(0.05)
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    assert "Traceback" not in err
    return proc.returncode


def _cases_in_this_process(monkeypatch) -> None:
    """The local pool runs each case with :func:`run_case` in this process, in order (not
    one fresh process per case: the pool itself is run by :func:`local_run`)."""
    import drake_coop.studies.engines as engines

    def run_local(cases, t_end, on_result, *, workers=2):
        for case in cases:
            on_result(case, engines.run_case(case.scenario_yaml, t_end))

    monkeypatch.setattr(engines, "run_local", run_local)


@pytest.mark.parametrize("signum, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_killed_study_keeps_finished_cases_and_resumes(tmp_path, capsys, monkeypatch, signum,
                                                       code):
    """A real study process killed after its first case keeps what finished; the resume
    (its cases run in this process, :func:`_cases_in_this_process`) runs only the rest."""
    path = _write(tmp_path, t_end=1.0)
    out = tmp_path / "out"
    assert _kill_after_first_case(path, out, signum) == code
    kept = {p: (p.stat().st_mtime_ns, p.read_text()) for p in (out / "cases").glob("*.json")}
    assert 1 <= len(kept) < 4
    doc = json.loads((out / "study.json").read_text())
    assert doc["counts"].get("pending", 0) == 4 - len(kept)
    assert not list(out.rglob("*.tmp"))
    _cases_in_this_process(monkeypatch)
    assert main(["study", str(path), "--out", str(out)]) == 0
    assert f"{len(kept)} already finished, running {4 - len(kept)}" in capsys.readouterr().err
    for p, (stamp, text) in kept.items():            # no finished case was run again
        assert (p.stat().st_mtime_ns, p.read_text()) == (stamp, text)
    assert len(list((out / "cases").glob("*.json"))) == 4     # and none lost
    assert [r["status"] for r in _rows(out)] == ["ok", "diverged", "ok", "diverged"]


@pytest.mark.slow
def test_ray_engine_gives_the_local_engine_metrics(local_run, tmp_path):
    try:
        import ray  # noqa: F401
    except ImportError:
        pytest.skip('ray is not installed (pip install "drake_coop[ray]"; CI installs it)')
    code, path, out_local = local_run
    out = tmp_path / "ray"
    assert main(["study", str(path), "--out", str(out), "--ray", "--workers", "2",
                 "--quiet"]) == 0
    local = {p.name: json.loads(p.read_text()) for p in (out_local / "cases").glob("*.json")}
    remote = {p.name: json.loads(p.read_text()) for p in (out / "cases").glob("*.json")}
    assert set(local) == set(remote) and len(local) == 4
    for name, record in local.items():
        for key in ("status", "message", "t_reached", "metrics"):
            assert remote[name][key] == record[key], (name, key)


def test_a_signal_that_arrives_in_a_finalizer_still_stops_the_study(monkeypatch):
    """A Ctrl-C whose handler runs inside a finalizer (here a ``__del__``; in a study, a
    case's process object being collected) is not printed and dropped: it stops the study."""
    import drake_coop.studies.cli as cli

    for name, value in (("_STOPPING", False), ("_DEFER", 0), ("_PENDING", None)):
        monkeypatch.setattr(cli, name, value)

    class Collected:
        def __del__(self):
            signal.raise_signal(signal.SIGINT)     # Python runs the handler in here

    previous = signal.signal(signal.SIGINT, cli._on_signal)
    try:
        with pytest.raises(KeyboardInterrupt):
            Collected()
            for _ in range(200):
                time.sleep(0.01)
    finally:
        signal.signal(signal.SIGINT, previous)
