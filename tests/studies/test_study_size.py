"""``drake-coop study --t-end/--draws/--cases``: a shipped study shrunk without copying its
file, validated (one line, exit 2), recorded in its folder; a resume keeps the size, and a
resume at another size is refused (no simulation: a stand-in engine)."""

import json
from pathlib import Path

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.studies import expand, load_study
from drake_coop.studies.folder import MARKER
from drake_coop.studies.size import apply_size

ROOT = Path(__file__).resolve().parents[2]
MISMATCH = ROOT / "studies" / "model_mismatch.yaml"
TIMING = ROOT / "studies" / "timing.yaml"


def _fake_engine(monkeypatch, calls: list):
    import drake_coop.studies.engines as engines

    def run_local(cases, t_end, on_result, *, workers=2):
        rng = np.random.default_rng(len(calls))
        for case in cases:
            calls.append((case.hash, t_end))
            phase = {e: {"rms": float(rng.uniform(0.1, 1)), "max": 2.0, "unit": "m"}
                     for e in ("x_tilde", "y_tilde", "z_tilde", "force_error")}
            on_result(case, {"status": "ok", "message": "completed", "t_reached": t_end,
                             "wall_time_s": 0.1, "metrics": {"robot1": {"circle": phase},
                                                             "robot2": {"circle": phase}}})

    monkeypatch.setattr(engines, "run_local", run_local)


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def test_draws_are_the_first_of_the_seeds_sequence():
    study = load_study(MISMATCH)
    small, first = apply_size(study, {"draws": 3})
    assert first is None and small.monte_carlo.n == 3 and study.monte_carlo.n == 60
    full = expand(study, first=5)
    assert [c.hash for c in expand(small)] == [c.hash for c in full[:3]]
    assert len(full) == 5


def test_a_sized_study_runs_that_size_records_it_and_a_resume_keeps_it(tmp_path, capsys,
                                                                       monkeypatch):
    calls: list = []
    _fake_engine(monkeypatch, calls)
    out = tmp_path / "out"
    argv = ["study", str(MISMATCH), "--out", str(out)]
    assert main([*argv, "--t-end", "0.5", "--draws", "4", "--cases", "3", "--quiet"]) == 0
    assert [t for _, t in calls] == [0.5] * 3
    doc = json.loads((out / "study.json").read_text())
    assert doc["t_end"] == 0.5 and doc["n_cases"] == 3 and doc["monte_carlo"]["n"] == 4
    assert json.loads((out / MARKER).read_text()) == {
        "name": "model_mismatch", "size": {"t_end": 0.5, "draws": 4, "cases": 3}}
    capsys.readouterr()
    assert main(argv) == 0                                   # no options: the recorded size
    err = capsys.readouterr().err
    assert "resuming at the size recorded in" in err and "--t-end 0.5 --draws 4 --cases 3" in err
    assert "3 already finished, running 0" in err and len(calls) == 3
    assert main([*argv, "--cases", "3", "--draws", "4", "--t-end", "0.5", "--quiet"]) == 0


@pytest.mark.parametrize("options, named", [
    (["--t-end", "1.0"], "--t-end"),
    (["--cases", "2"], "--cases"),
    (["--t-end", "0.5", "--draws", "4"], "--cases"),
])
def test_a_resume_at_another_size_is_refused_with_one_line(tmp_path, capsys, monkeypatch,
                                                           options, named):
    _fake_engine(monkeypatch, [])
    out = tmp_path / "out"
    argv = ["study", str(MISMATCH), "--out", str(out), "--quiet"]
    assert main([*argv, "--t-end", "0.5", "--draws", "4", "--cases", "3"]) == 0
    before = _tree(out)
    capsys.readouterr()
    assert main([*argv, *options]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"drake-coop study: error: {named}: ")
    assert "--t-end 0.5 --draws 4 --cases 3" in err[0]
    assert _tree(out) == before


def test_a_folder_run_at_the_files_size_refuses_a_sized_resume(tmp_path, capsys, monkeypatch):
    _fake_engine(monkeypatch, [])
    out = tmp_path / "out"
    small = tmp_path / "small.yaml"
    small.write_text("name: small\nt_end: 0.5\ngrid:\n  control_period: [0.003, 0.009]\n")
    assert main(["study", str(small), "--out", str(out), "--quiet"]) == 0
    assert json.loads((out / MARKER).read_text())["size"] == {}
    capsys.readouterr()
    assert main(["study", str(small), "--out", str(out), "--cases", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--cases: " in err[0] and "the study file's own size" in err[0]


@pytest.mark.parametrize("options, message", [
    (["--t-end", "nan"], "--t-end: must be a finite number of seconds"),
    (["--t-end", "0"], "--t-end: must be a finite number of seconds"),
    (["--t-end", "-1"], "--t-end: must be a finite number of seconds"),
    (["--t-end", "soon"], "argument --t-end: invalid float value: 'soon' (allowed: a number)"),
    (["--draws", "0", "--t-end", "1"], "--draws: must be an integer >= 1, got 0"),
    (["--draws", "2.5"], "argument --draws: invalid int value: '2.5' (allowed: an integer)"),
    (["--cases", "0"], "--cases: must be an integer >= 1, got 0"),
    (["--cases", "10"], "--cases: study 'timing' has 9 cases at this size, got 10"),
])
def test_bad_sizes_are_one_line_exit_2_before_anything_is_written(tmp_path, capsys, options,
                                                                   message):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) if "argument" in message else _nothing() as exited:
        study = MISMATCH if "--draws" in options else TIMING
        assert main(["study", str(study), "--out", str(out), *options]) == 2
    if exited is not None:
        assert exited.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not out.exists()


def test_draws_of_a_study_without_monte_carlo_is_refused(tmp_path, capsys):
    assert main(["study", str(TIMING), "--out", str(tmp_path / "o"), "--draws", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--draws: study 'timing' has no monte_carlo block" in err[0]


class _nothing:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False
