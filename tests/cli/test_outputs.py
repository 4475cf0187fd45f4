"""The commands' outputs as safe as ``run``'s: checked before any work, written whole or not at
all, one line per error; and the inputs review found accepted or crashing.

Full disks are simulated by making the write raise ``OSError(ENOSPC)``; an unwritable folder by
a file where a folder is needed, or by making the write probe fail (the tests run as root, whom
``chmod`` does not stop).
"""

from __future__ import annotations

import errno
import math
from pathlib import Path

import pytest

from drake_coop.cli import main

ROOT = Path(__file__).resolve().parents[2]
REALISTIC = str(ROOT / "scenarios" / "realistic.yaml")


def _enospc(*args, **kwargs):
    raise OSError(errno.ENOSPC, "No space left on device")


def _err_lines(capsys) -> list[str]:
    return capsys.readouterr().err.strip().splitlines()


def _no_work(*args, **kwargs):
    raise AssertionError("the work started although --out was refused")


def _hidden(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


# --- --out refused before any work (stability, identify) -------------------------------------

def _blocked_out(tmp_path: Path, how: str, monkeypatch) -> Path:
    if how == "file-blocked":
        (tmp_path / "afile").write_text("mine")
        return tmp_path / "afile" / "sub"
    if how == "read-only":
        import drake_coop.results.io as io

        def refuse(path):
            raise PermissionError(errno.EACCES, "Permission denied", str(path))
        monkeypatch.setattr(io, "_new_temp", refuse)
        return tmp_path / "out"
    if how == "full":
        import collections

        import drake_coop.results.io as io
        usage = collections.namedtuple("usage", "total used free")
        monkeypatch.setattr(io.shutil, "disk_usage", lambda p: usage(10**9, 10**9, 1000))
        return tmp_path / "out"
    raise ValueError(how)


@pytest.mark.parametrize("how", ["file-blocked", "read-only", "full"])
def test_stability_refuses_an_unwritable_out_before_the_grid(tmp_path, monkeypatch, capsys, how):
    import drake_coop.stability.grid as grid

    out = _blocked_out(tmp_path, how, monkeypatch)
    monkeypatch.setattr(grid, "run_grid", _no_work)
    assert main(["stability", "paper", "--out", str(out)]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and err[0].startswith(f"drake-coop: error: --out {out}")
    assert not out.exists()


@pytest.mark.parametrize("how", ["file-blocked", "read-only", "full"])
def test_identify_refuses_an_unwritable_out_before_identifying(tmp_path, monkeypatch, capsys,
                                                                how):
    import drake_coop.identification.report as report

    out = _blocked_out(tmp_path, how, monkeypatch)
    monkeypatch.setattr(report, "identify_robot", _no_work)
    assert main(["identify", REALISTIC, "--out", str(out), "--robots", "1"]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and err[0].startswith(f"drake-coop: error: --out {out}")
    assert not out.exists()


# --- written whole or not at all --------------------------------------------------------------

def test_stability_on_a_disk_that_fills_keeps_the_previous_map(tmp_path, monkeypatch, capsys):
    import drake_coop.results.io as io

    out = tmp_path / "map"
    out.mkdir()
    (out / "stability.csv").write_text("previous\n")
    real = io.atomic_write_bytes

    def fill_on_the_figure(path, data):
        if Path(path).suffix == ".png":
            _enospc()
        return real(path, data)
    import drake_coop.stability.output as output
    monkeypatch.setattr(output, "atomic_write_bytes", fill_on_the_figure)
    code = main(["stability", "paper", "--out", str(out), "--quiet", "--workers", "1",
                 "--grid", "control_period=0.009"])
    err = _err_lines(capsys)
    assert code == 1 and len(err) == 1 and "No space left on device" in err[0]
    assert (out / "stability.csv").read_text() == "previous\n"
    assert sorted(p.name for p in out.iterdir()) == ["stability.csv"]
    assert _hidden(tmp_path) == []


@pytest.mark.slow
def test_identify_on_a_disk_that_fills_keeps_the_previous_output(tmp_path, monkeypatch, capsys):
    import drake_coop.identification.report as report

    out = tmp_path / "ident"
    out.mkdir()
    (out / "identify.json").write_text("previous")
    monkeypatch.setattr(report, "fit_figure", _enospc)
    code = main(["identify", REALISTIC, "--out", str(out), "--robots", "1", "--duration", "1",
                 "--quiet"])
    err = _err_lines(capsys)
    assert code == 1 and len(err) == 1 and "No space left on device" in err[0]
    assert sorted(p.name for p in out.iterdir()) == ["identify.json"]
    assert (out / "identify.json").read_text() == "previous"
    assert _hidden(tmp_path) == []


# --- stability's finite-difference step --------------------------------------------------------

@pytest.mark.parametrize("epsilon", ["1e-16", "1e-14", "1e-20", "0.005", "nan"])
def test_stability_refuses_a_step_outside_where_the_map_is_resolved(tmp_path, capsys, epsilon):
    assert main(["stability", "paper", "--out", str(tmp_path / "o"), "--epsilon", epsilon]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and "--epsilon" in err[0]


@pytest.fixture(scope="module")
def paper_free_map():
    from drake_coop.scenario import default_scenario
    from drake_coop.stability.operating import operating_point

    return operating_point(default_scenario(), "free").map


def test_the_maps_own_step_check_catches_a_wrong_rho(paper_free_map):
    """At ε = 1e-16 rounding gives ρ = 1.11 for the paper's loop (ρ = 0.896 on the plateau,
    tests/stability/test_stability.py); the second step disagrees, so the report says so."""
    from drake_coop.stability.period_map import analyse

    good = analyse(paper_free_map, epsilon=1e-5)
    assert good.step_agrees and math.isclose(good.rho, good.rho_check, rel_tol=1e-4)
    bad = analyse(paper_free_map, epsilon=1e-16)
    assert not bad.step_agrees
    assert abs(bad.rho - good.rho) > 0.05            # the wrong ρ it would have reported


def test_stability_exits_1_with_the_reason_when_the_steps_disagree(tmp_path, monkeypatch,
                                                                    capsys):
    """With the bound lifted, a step-dependent ρ is written as such and the command exits 1."""
    import csv

    import drake_coop.stability.period_map as period_map

    monkeypatch.setattr(period_map, "EPSILON_RANGE", (1e-20, 1e-3))
    out = tmp_path / "map"
    code = main(["stability", "paper", "--out", str(out), "--quiet", "--workers", "1",
                 "--epsilon", "1e-16", "--grid", "control_period=0.009"])
    err = _err_lines(capsys)
    assert code == 1 and len(err) == 1 and "step" in err[0] and "1e-16" in err[0]
    rows = list(csv.DictReader((out / "stability.csv").open()))
    assert [r["status"] for r in rows] == ["step_dependent"]


# --- stability's other inputs -------------------------------------------------------------------

def test_stability_refuses_an_empty_scenario_file_naming_it(tmp_path, capsys):
    empty = tmp_path / "empty.yaml"
    empty.write_text("\n")
    assert main(["stability", str(empty), "--out", str(tmp_path / "o")]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and str(empty) in err[0]


def test_stability_names_no_option_it_does_not_have(tmp_path, capsys):
    values = ",".join(str(30 + i) for i in range(101))
    code = main(["stability", "paper", "--out", str(tmp_path / "o"),
                 "--grid", f"robots.*.gains.k_d={values}",
                 "--grid", f"robots.*.gains.Lambda={values}"])
    err = _err_lines(capsys)
    assert code == 2 and len(err) == 1 and "more than" in err[0]
    assert "--max-cases" not in err[0]


# --- identify's inputs ----------------------------------------------------------------------------

@pytest.mark.parametrize("seed", ["-1", str(2**40)])
def test_identify_refuses_a_bad_seed_in_one_line(tmp_path, capsys, seed):
    assert main(["identify", REALISTIC, "--out", str(tmp_path / "o"), "--seed", seed]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and "--seed" in err[0]


# --- run ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("t_end", ["0.001", "0.0089"])
def test_run_shorter_than_one_control_period_exits_2(tmp_path, capsys, t_end):
    out = tmp_path / "o"
    assert main(["run", "--out", str(out), "--t-end", t_end, "--quiet"]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and "shorter than one control period" in err[0]
    assert not out.exists() and _hidden(tmp_path) == []


def test_two_runs_cannot_both_claim_one_new_out(tmp_path, capsys):
    from drake_coop.results.run_folder import OutputFolderError, RunFolder

    out = tmp_path / "o"
    first = RunFolder(out)
    first.prepare(10)
    try:
        with pytest.raises(OutputFolderError, match="another drake-coop run"):
            RunFolder(out).prepare(10)
        assert main(["run", "--out", str(out), "--t-end", "0.05", "--quiet"]) == 2
        err = _err_lines(capsys)
        assert len(err) == 1 and "another drake-coop run" in err[0]
    finally:
        first.discard()
    assert _hidden(tmp_path) == []              # the lock and the staging folder are gone
    second = RunFolder(out)                     # free again once the first is done
    second.prepare(10)
    second.discard()


# --- study ------------------------------------------------------------------------------------------

def test_a_study_with_t_end_1e_300_is_refused(tmp_path, capsys):
    path = tmp_path / "tiny.yaml"
    path.write_text("name: tiny\nt_end: 1.0e-300\ngrid:\n  control_period: [0.009]\n")
    assert main(["study", str(path), "--out", str(tmp_path / "o")]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and "t_end" in err[0]


def test_a_study_shorter_than_a_cases_control_period_is_refused_before_running(tmp_path,
                                                                                 capsys):
    path = tmp_path / "short.yaml"
    path.write_text("name: short\nt_end: 0.005\ngrid:\n  control_period: [0.003, 0.009]\n")
    assert main(["study", str(path), "--out", str(tmp_path / "o")]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and "shorter than one control period" in err[0]


def test_a_case_file_that_is_a_folder_is_refused_before_running(tmp_path, monkeypatch, capsys):
    import drake_coop.studies.engines as engines
    from drake_coop.studies import expand, load_study
    from drake_coop.studies.folder import MARKER

    path = tmp_path / "small.yaml"
    path.write_text("name: small\nt_end: 0.05\ngrid:\n  control_period: [0.009]\n")
    case = expand(load_study(path))[0]
    out = tmp_path / "o"
    (out / "cases" / f"{case.hash}.json").mkdir(parents=True)
    (out / MARKER).write_text('{"name": "small"}\n')            # the study's own folder
    monkeypatch.setattr(engines, "run_case", _no_work)
    monkeypatch.setattr(engines, "run_in_processes", _no_work)
    assert main(["study", str(path), "--out", str(out), "--workers", "1"]) == 2
    err = _err_lines(capsys)
    assert len(err) == 1 and f"cases/{case.hash}.json is a folder" in err[0]
