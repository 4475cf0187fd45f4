"""A run's output folder holds one whole run; signals end a run cleanly; plot reads safely.

Outputs, signals and plot: a rerun with ``--force`` replaces the previous folder whole, a
killed run leaves the previous folder as it was, ``--out`` is checked before simulating, SIGTERM is handled like Ctrl-C (exit 143), a signal during start-up or while
writing ends without a traceback and without a mixed folder, and ``drake-coop plot`` reads
only regular files inside its run folder with their sizes checked before unpacking.
"""

import json
import os
import signal
import subprocess
import sys
import time
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.results import save_logs
from drake_coop.results.run_folder import OutputFolderError, RunFolder
from drake_coop.scenario import dump_scenario
from tests.conftest import short_scenario, start_paper_run
from tests.results.test_io import synthetic_run


def _previous_run(out: Path) -> dict:
    """A previous run's folder (its files with distinct contents)."""
    logs, meta = synthetic_run(t_end=0.09)
    save_logs(out, logs, meta)
    (out / "fig2_tracking_errors.png").write_bytes(b"old figure")
    return {p.name: p.read_bytes() for p in out.iterdir()}


def _leftovers(parent: Path, name: str) -> list[str]:
    return [p.name for p in parent.iterdir() if p.name.startswith(f".{name}.")]


# ---------------------------------------------------------------- the folder itself


def test_commit_replaces_a_previous_run_whole(tmp_path):
    out = tmp_path / "run"
    _previous_run(out)
    folder = RunFolder(out)
    staging = folder.prepare(ticks=100, replace=True)
    assert staging.parent == tmp_path and staging.name.startswith(".run.drake-coop-")
    (staging / "left.npz").write_bytes(b"new")
    folder.commit()
    assert sorted(p.name for p in out.iterdir()) == ["left.npz"]
    assert _leftovers(tmp_path, "run") == []


@pytest.mark.parametrize("entry", ["notes.txt", "subfolder"])
def test_a_folder_with_foreign_files_is_refused_and_kept(tmp_path, entry):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "run.json").write_text("{}")
    (out / entry).mkdir() if entry == "subfolder" else (out / entry).write_text("keep me")
    with pytest.raises(OutputFolderError, match=f"holds '{entry}', which is not a drake-coop"):
        RunFolder(out).prepare(ticks=100)
    assert (out / entry).exists() and _leftovers(tmp_path, "mine") == []


def test_a_previous_folder_with_stray_temporary_files_is_replaced(tmp_path):
    out = tmp_path / "run"
    _previous_run(out)
    (out / ".robot1.npz.0123abcd.tmp").write_bytes(b"half-written by a killed writer")
    folder = RunFolder(out)
    folder.prepare(ticks=1, replace=True)
    folder.commit()
    assert list(out.iterdir()) == []


def test_out_that_is_a_file_a_link_or_under_a_file_is_refused(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    with pytest.raises(OutputFolderError, match="is a symbolic link"):
        RunFolder(tmp_path / "link").prepare(ticks=1)
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputFolderError, match="exists and is not a folder"):
        RunFolder(tmp_path / "f").prepare(ticks=1)
    with pytest.raises(OutputFolderError, match="cannot write there"):
        RunFolder(tmp_path / "f" / "run").prepare(ticks=1)


def test_a_full_disk_is_found_before_simulating(tmp_path, monkeypatch, capsys):
    import shutil

    import drake_coop.experiment.simulate

    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage._replace(free=10_000_000))
    monkeypatch.setattr(drake_coop.experiment.simulate, "simulate",
                        lambda *a, **k: pytest.fail("simulated before checking --out"))
    out = tmp_path / "o"
    assert main(["run", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "10 MB free on its disk, the run needs about" in err
    assert not out.exists() and _leftovers(tmp_path, "o") == []


def test_the_room_needed_grows_with_the_number_of_robots(tmp_path, monkeypatch):
    import shutil

    from drake_coop.results import run_folder

    ticks = 10_000
    two = run_folder.BYTES_FIXED + 2 * ticks * run_folder.BYTES_PER_ROBOT_TICK
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda p: usage._replace(free=two))
    RunFolder(tmp_path / "a").prepare(ticks, robots=2)
    with pytest.raises(OutputFolderError, match="the run needs about"):
        RunFolder(tmp_path / "b").prepare(ticks, robots=3)
    assert _leftovers(tmp_path, "b") == []


def test_stale_staging_folders_of_dead_processes_are_removed(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    stale = tmp_path / f".run.drake-coop-{dead}-00ff.tmp"
    stale.mkdir()
    (stale / "robot1.npz").write_bytes(b"half")
    alive = tmp_path / f".run.drake-coop-{os.getpid()}-00ff.tmp"   # a run in progress
    alive.mkdir()
    folder = RunFolder(tmp_path / "run")
    folder.prepare(ticks=1)
    assert not stale.exists() and alive.exists()
    folder.discard()
    assert _leftovers(tmp_path, "run") == [alive.name]


# ---------------------------------------------------------------- signals


def test_a_signal_while_writing_skips_the_figures_and_marks_run_json(tmp_path, monkeypatch,
                                                                      capsys):
    import drake_coop.results

    def interrupted_figures(*args, **kwargs):   # a Ctrl-C lands while figures are drawn
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.1)
        return []

    monkeypatch.setattr(drake_coop.results, "plot_figures", interrupted_figures)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(short_scenario("planes", 0.003)))
    out = tmp_path / "o"
    code = main(["run", str(path), "--out", str(out), "--quiet", "--no-replay", "--t-end",
                 "0.1"])
    err = capsys.readouterr().err
    assert code == 130 and "Traceback" not in err
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "ok"
    assert meta["outputs_incomplete"].startswith("reference figure, diagrams skipped after "
                                                 "Ctrl-C")
    assert (out / "robot1.npz").exists() and (out / "metrics.json").exists()
    assert not (out / "fig_references.png").exists()
    assert _leftovers(tmp_path, "o") == []


@pytest.mark.slow
def test_sigterm_stops_the_run_like_ctrl_c_and_keeps_the_logs(tmp_path):
    out = tmp_path / "o"
    proc, lines = start_paper_run(out)
    proc.send_signal(signal.SIGTERM)
    err = "".join(lines) + proc.stderr.read()
    proc.wait(timeout=120)
    assert proc.returncode == 143, err
    assert "SIGTERM" in err and "Traceback" not in err
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "interrupted" and meta["signal"] == "SIGTERM"
    assert 0.0 < np.load(out / "robot1.npz")["t"][-1] < 90.0
    assert _leftovers(tmp_path, "o") == []


@pytest.mark.slow
def test_a_killed_run_leaves_the_previous_folder_as_it_was(tmp_path):
    out = tmp_path / "o"
    before = _previous_run(out)
    proc, _ = start_paper_run(out)
    proc.kill()
    proc.wait(timeout=60)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert len(_leftovers(tmp_path, "o")) == 1          # the dead run's staging folder ...
    RunFolder(out).prepare(ticks=1, replace=True)
    assert len(_leftovers(tmp_path, "o")) == 1          # ... replaced by the new one's only


@pytest.mark.slow
def test_a_second_ctrl_c_while_writing_leaves_no_partial_folder(tmp_path):
    out = tmp_path / "o"
    proc, lines = start_paper_run(out)
    proc.send_signal(signal.SIGINT)
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    err = "".join(lines) + proc.stderr.read()
    proc.wait(timeout=120)
    assert proc.returncode == 130 and "Traceback" not in err, err
    if out.exists():        # the second signal landed while writing: a whole, marked run
        meta = json.loads((out / "run.json").read_text())
        assert meta["status"] == "interrupted"
        assert (out / "robot1.npz").exists() and (out / "robot2.npz").exists()
    assert _leftovers(tmp_path, "o") == []


def test_ctrl_c_during_start_up_ends_without_traceback(tmp_path):
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "drake_coop", "run", "--out", str(out)],
                            stderr=subprocess.PIPE, text=True)
    time.sleep(0.5)            # importing drake and building take longer than this
    proc.send_signal(signal.SIGINT)
    err = proc.stderr.read()
    proc.wait(timeout=60)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and err.count("\n") == 1
    assert not out.exists() and _leftovers(tmp_path, "o") == []


# ---------------------------------------------------------------- plot


@pytest.fixture
def run_dir(tmp_path):
    out = tmp_path / "run"
    logs, meta = synthetic_run(t_end=0.09)
    save_logs(out, logs, meta)
    return out


def _plot_error(run_dir, capsys) -> str:
    assert main(["plot", str(run_dir), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    return err


def test_plot_refuses_robot_names_leading_outside_the_folder(run_dir, capsys):
    (run_dir.parent / "x.npz").write_bytes((run_dir / "robot1.npz").read_bytes())
    meta = json.loads((run_dir / "run.json").read_text())
    meta["robots"] = ["../x", "robot2"]
    (run_dir / "run.json").write_text(json.dumps(meta))
    assert "'robots' must be a list of 1 to 8 distinct identifiers" in _plot_error(run_dir,
                                                                                   capsys)


def test_plot_refuses_a_symlink_out_of_the_folder(run_dir, capsys):
    outside = run_dir.parent / "elsewhere.npz"
    (run_dir / "robot1.npz").rename(outside)
    (run_dir / "robot1.npz").symlink_to(outside)
    assert "must be a regular file inside the run folder" in _plot_error(run_dir, capsys)


def test_plot_checks_npz_sizes_before_unpacking(run_dir, capsys):
    zeros = bytes(1_000_000)
    with zipfile.ZipFile(run_dir / "robot1.npz", "w", zipfile.ZIP_DEFLATED) as archive:
        with archive.open("t.npy", "w", force_zip64=True) as member:   # 200 MB of zeros
            for _ in range(200):
                member.write(zeros)
    assert (run_dir / "robot1.npz").stat().st_size < 1_000_000
    tracemalloc.start()
    err = _plot_error(run_dir, capsys)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert "would unpack to 200 MB, at most 128 MB" in err and peak < 20e6


def test_plot_refuses_a_deeply_nested_run_json(run_dir, capsys):
    (run_dir / "run.json").write_text("[" * 100_000 + "]" * 100_000)
    assert "nested too deeply" in _plot_error(run_dir, capsys)
