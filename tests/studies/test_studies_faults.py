"""A study under faults: owned and locked ``--out``, bounded study files and sizes, validation
as ``run`` validates, truthful tables with overlapping paths, names that stay inside ``--out``,
one-line exits on I/O failures, damaged files (no simulation in this file except where a
test says so; the killed-process tests are in tests/studies/test_studies_kill.py)."""

import errno
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.scenario import load_scenario
from drake_coop.scenario.schema import ScenarioError
from drake_coop.studies import StudyError, expand, load_study
from drake_coop.studies.folder import LOCK, MARKER, StudyFolder, StudyFolderError
from drake_coop.studies.plots import plot_study
from drake_coop.studies.spec import file_stem
from drake_coop.studies.store import ResultStore

ROOT = Path(__file__).resolve().parents[2]

SMALL = """
name: small
t_end: 0.5
grid:
  control_period: [0.003, 0.009]
"""


def _study_file(tmp_path: Path, text: str = SMALL, name: str = "small.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def _fake_result(rng, status: str = "ok") -> dict:
    phase = {e: {"rms": float(rng.uniform(0.1, 1)), "max": float(rng.uniform(1, 2)),
                 "unit": "m"} for e in ("x_tilde", "y_tilde", "z_tilde", "force_error")}
    return {"status": status, "message": "completed", "t_reached": 1.0, "wall_time_s": 0.1,
            "metrics": {"robot1": {"circle": phase}, "robot2": {"circle": phase}}}


# --- the --out folder is owned --------------------------------------------------------------

@pytest.mark.parametrize("content, named", [
    ({"results.csv": "a,b\n1,2\n"}, "results.csv"),                  # a user's own file
    ({"run.json": "{}", "robot1.npz": ""}, "robot1.npz"),            # a run's folder
])
def test_out_holding_foreign_files_is_refused_and_left_untouched(tmp_path, capsys, content,
                                                                  named):
    out = tmp_path / "out"
    out.mkdir()
    for name, text in content.items():
        (out / name).write_text(text)
    before = _tree(out)
    assert main(["study", str(_study_file(tmp_path)), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"holds '{named}'" in err[0] and "not part of a drake-coop" in err[0]
    assert _tree(out) == before and sorted(os.listdir(out)) == sorted(content)


def test_out_of_another_study_or_a_file_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    StudyFolder(out).claim("other").release()
    assert main(["study", str(_study_file(tmp_path)), "--out", str(out)]) == 2
    assert "is the folder of study 'other', not of 'small'" in capsys.readouterr().err
    (tmp_path / "file").write_text("x")
    assert main(["study", str(_study_file(tmp_path)), "--out", str(tmp_path / "file")]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err
    assert (tmp_path / "file").read_text() == "x"


def test_empty_or_own_folder_is_claimed_and_marked(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    folder = StudyFolder(out).claim("small")
    folder.release()
    assert json.loads((out / MARKER).read_text()) == {"name": "small"}
    (out / "notes.txt").write_text("mine")            # the study's own folder: a resume
    StudyFolder(out).claim("small").release()
    legacy = tmp_path / "legacy"                       # written before the marker existed
    (legacy / "cases").mkdir(parents=True)
    (legacy / "study.json").write_text(json.dumps({"name": "small"}))
    StudyFolder(legacy).claim("small").release()
    with pytest.raises(StudyFolderError, match="folder of study 'small', not of 'x'"):
        StudyFolder(legacy).claim("x")


_HOLD = """
import sys, time
from drake_coop.studies.folder import StudyFolder
StudyFolder(sys.argv[1]).claim("small")
print("locked", flush=True)
time.sleep(60)
"""


def test_one_process_per_folder_and_a_killed_holder_leaves_no_lock(tmp_path):
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    holder = subprocess.Popen([sys.executable, "-c", _HOLD, str(out)], env=env,
                              stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        with pytest.raises(StudyFolderError) as info:
            StudyFolder(out).claim("small")
        assert f"in use by another study process (pid {holder.pid})" in str(info.value)
        # the CLI refuses before running anything
        assert main(["study", str(_study_file(tmp_path)), "--out", str(out), "--quiet"]) == 2
        assert not list((out / "cases").iterdir())
    finally:
        holder.kill()                                  # kill -9: the kernel drops the lock
        holder.wait()
    StudyFolder(out).claim("small").release()
    assert (out / LOCK).read_text().strip() == str(os.getpid())


# --- bounded, strict study files ---------------------------------------------------------------

BOMB = """
a: &a [x, x, x, x, x, x, x, x, x, x]
b: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]
c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b, *b]
d: &d [*c, *c, *c, *c, *c, *c, *c, *c, *c, *c]
e: &e [*d, *d, *d, *d, *d, *d, *d, *d, *d, *d]
f: [*e, *e, *e, *e, *e, *e, *e, *e, *e, *e]
"""


@pytest.mark.parametrize("raw, start", [
    (BOMB.encode(), "the YAML document expands (through its aliases) to more than"),
    (b"grid: {control_period: [0.009]}\ngrid: {control_period: [0.003]}\n",
     "duplicate key 'grid' at line 2"),
    (b"name: caf\xe9\ngrid: {control_period: [0.009]}\n", "study file"),
    (b"# " + b"x" * 1_100_000 + b"\n", "study file"),
])
def test_study_files_are_read_like_scenario_files(tmp_path, raw, start):
    path = tmp_path / "s.yaml"
    path.write_bytes(raw)
    started = time.process_time()
    with pytest.raises(StudyError) as info:
        load_study(path)
    assert time.process_time() - started < 2.0
    message = str(info.value)
    assert message.startswith(start) and "\n" not in message and len(message) < 400, message
    if raw.startswith(b"name: caf"):
        assert "is not UTF-8 text" in message
    if raw.startswith(b"# x"):
        assert "is larger than 1000000 bytes" in message


def test_a_base_file_that_is_not_utf8_is_a_one_line_error(tmp_path, capsys):
    (tmp_path / "base.yaml").write_bytes(b"control_period: 0.009 # \xff\n")
    path = _study_file(tmp_path, "base: base.yaml\ngrid: {control_period: [0.009]}\n")
    assert main(["study", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "base: scenario file" in err[0] and "is not UTF-8 text" in err[0]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("name", ["a\x00b", "x" * 400, "tab\there"])
def test_bad_study_names_are_refused_before_any_case(tmp_path, capsys, name):
    path = _study_file(tmp_path, json.dumps({"name": name, "grid": {"control_period":
                                                                     [0.009]}}))
    assert main(["study", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("drake-coop study: error: name: must be 1 to")
    assert not (tmp_path / "out").exists()


# --- size computed before expanding, and bounded -----------------------------------------------

@pytest.mark.parametrize("text, cases", [
    ("grid: {robots.0.gains.k_d: " + json.dumps(list(range(1, 101))) + ", "
     "robots.1.gains.k_d: " + json.dumps(list(range(1, 101))) + ", "
     "control_period: " + json.dumps([0.009] * 100) + "}", 10 ** 6),
    ("monte_carlo: {n: 1000000000000000000000000000000, seed: 1, "
     "perturb: {robots.0.gains.k_d: {uniform: [30, 50]}}}", 10 ** 30),
])
def test_a_too_large_study_is_refused_before_it_is_expanded(text, cases):
    started = time.process_time()
    with pytest.raises(StudyError) as info:
        expand(load_study(data=text))
    assert time.process_time() - started < 2.0
    assert str(info.value).startswith(f"the study has {cases} cases")
    assert "--max-cases" in str(info.value)


def test_max_cases_bounds_and_raises_on_purpose(tmp_path, capsys):
    study = load_study(data="grid: {robots.0.gains.k_d: [20, 30, 40]}")
    with pytest.raises(StudyError, match="the study has 3 cases"):
        expand(study, max_cases=2)
    assert len(expand(study, max_cases=3)) == 3
    path = _study_file(tmp_path, "grid: {robots.0.gains.k_d: [20, 30, 40]}")
    assert main(["study", str(path), "--out", str(tmp_path / "o"), "--max-cases", "2"]) == 2
    assert "more than 2" in capsys.readouterr().err and not (tmp_path / "o").exists()


@pytest.mark.parametrize("argv, message", [
    (["--workers", "0"], "--workers must be between 1 and"),
    (["--workers", "1000000"], "--workers must be between 1 and"),
    (["--workers", "8", "--max-workers", "4"], "--workers must be between 1 and 4"),
    (["--max-cases", "0"], "--max-cases must be >= 1"),
])
def test_workers_are_bounded(tmp_path, capsys, argv, message):
    path = _study_file(tmp_path)
    assert main(["study", str(path), "--out", str(tmp_path / "o"), *argv]) == 2
    assert message in capsys.readouterr().err and not (tmp_path / "o").exists()


# --- validation exactly as run, and fast ------------------------------------------------------

def _run_message(scenario_text: str, t_end: float | None) -> str:
    """What `drake-coop run` says about a scenario: load_scenario, then the run size."""
    from drake_coop.experiment.ticks import check_run_size

    try:
        check_run_size(load_scenario(data=scenario_text), t_end)
    except ScenarioError as exc:
        return str(exc)
    return ""


def test_a_case_over_the_run_size_limit_fails_validation_as_run_says(tmp_path):
    from drake_coop.experiment.ticks import MAX_TICKS

    text = "t_end: 300.0\nbase: {task: {t_end: 300.0, t_release: 290.0}}\n" \
           "grid: {control_period: [0.009, 0.001], plant.time_step: [0.001]}"
    with pytest.raises(StudyError) as info:
        expand(load_study(data=text))
    expected = _run_message("task: {t_end: 300.0, t_release: 290.0}\ncontrol_period: 0.001\n"
                            "plant: {time_step: 0.001}\n", 300.0)
    assert f"at most {MAX_TICKS}" in expected
    assert str(info.value) == f"grid.control_period = 0.001: {expected}"


def test_an_unreachable_case_fails_with_the_message_run_gives():
    """A grid over base positions: the reachability check (shared between cases of the same
    geometry) refuses the case that does not reach with exactly load_scenario's message."""
    from drake_coop.scenario.loading import dump_scenario

    study = load_study(data="grid: {robots.*.gains.k_d: [20, 40], "
                            "robots.0.base_xyz: [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]]}")
    with pytest.raises(StudyError) as info:
        expand(study)
    base = load_scenario()
    base.robots[0].base_xyz = [3.0, 0.0, 0.0]
    expected = _run_message(dump_scenario(base), None)
    assert expected and str(info.value) == f"grid.robots.0.base_xyz = [3.0, 0.0, 0.0]: {expected}"


def test_every_case_is_the_scenario_the_yaml_loading_makes_of_its_values():
    """Cases are built on a copy of the base Scenario (numbers) or through the YAML loading
    (variants, texts); each equals what the run's YAML path makes of the base with the
    case's grid values set (set_value, yaml_dump, load_scenario), and its hash is that
    scenario's."""
    from pydrake.common.yaml import yaml_dump, yaml_load

    from drake_coop.scenario.loading import dump_scenario
    from drake_coop.studies.expand import case_hash
    from drake_coop.studies.paths import resolve, set_value

    study = load_study(data="""
grid:
  robots.*.gains.K_R: [90, [100, 110, 120]]
  robots.1: [{velocity_source: measured}, {gains: {k_d: 30}}]
  robots.0.encoders.delay_samples: [0, 2]
""")
    cases = expand(study)
    assert len(cases) == 8
    base = yaml_load(data=dump_scenario(load_scenario()))
    for c in cases:
        data = yaml_load(data=yaml_dump(base))
        for path, value in c.params.items():
            for keys in resolve(data, path, path):
                set_value(data, keys, value)
        expected = load_scenario(data=yaml_dump(data))
        assert load_scenario(data=c.scenario_yaml) == expected
        assert c.hash == case_hash(expected, None)


def test_a_thousand_cases_validate_in_seconds():
    values = [round(10.0 + 0.1 * i, 3) for i in range(100)]
    study = load_study(data=f"grid: {{robots.*.gains.k_d: {values}, "
                            f"robots.*.gains.K_R: [60, 70, 80, 90, 100, 110, 120, 130, 140, 150]}}")
    started = time.process_time()
    cases = expand(study)
    elapsed = time.process_time() - started
    assert len(cases) == 1000 and len({c.hash for c in cases}) == 1000
    assert elapsed < 15.0, elapsed        # ~1 ms a case; the YAML round trip took ~60 ms
    # (bounds of this file count this process's CPU time: blow-ups, not the machine's load)


# --- overlapping paths: the table says what the case ran with ----------------------------------

OVERLAP = """
name: overlap
monte_carlo:
  n: 5
  seed: 11
  perturb:
    robots.*.gains.K_R: {scale_uniform: [0.9, 1.1]}
    robots.0.gains.K_R.*: {uniform: [80, 160]}
"""


def test_overlapping_paths_apply_in_file_order_and_tables_show_the_run_values(tmp_path):
    import csv

    cases = expand(load_study(data=OVERLAP))
    rng = np.random.default_rng(11)      # independent replay: sample, path, element
    for c in cases:
        s = load_scenario(data=c.scenario_yaml)
        rng.uniform(0.9, 1.1)                          # robot 0's factor: overridden
        f1 = rng.uniform(0.9, 1.1)
        k0 = [rng.uniform(80, 160) for _ in range(3)]
        assert s.robots[0].gains.K_R == pytest.approx(k0, rel=1e-12)   # the later path wins
        assert s.robots[1].gains.K_R == pytest.approx([100.0 * f1] * 3, rel=1e-12)
    store = ResultStore(tmp_path)
    rng = np.random.default_rng(0)
    records = {c.hash: store.save(c, _fake_result(rng), None) for c in cases}
    store.write_tables(load_study(data=OVERLAP), cases, records, "local")
    with open(tmp_path / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    for row, c in zip(rows, cases):
        s = load_scenario(data=c.scenario_yaml)
        assert [float(v) for v in row["robots.0.gains.K_R"].split()] == s.robots[0].gains.K_R
        assert [float(row[f"robots.0.gains.K_R.{j}"]) for j in range(3)] == \
            s.robots[0].gains.K_R
        assert [float(v) for v in row["robots.1.gains.K_R"].split()] == s.robots[1].gains.K_R
    doc = json.loads((tmp_path / "study.json").read_text())
    assert doc["cases"][0]["values"]["robots.0.gains.K_R"] == \
        load_scenario(data=cases[0].scenario_yaml).robots[0].gains.K_R


def test_scale_uniform_scales_the_grid_value_of_the_case():
    cases = expand(load_study(data="""
grid: {robots.1.gains.k_d: [20, 80]}
monte_carlo: {n: 3, seed: 2, perturb: {robots.1.gains.k_d: {scale_uniform: [0.9, 1.1]}}}
"""))
    factors = np.random.default_rng(2).uniform(0.9, 1.1, 3)
    got = [load_scenario(data=c.scenario_yaml).robots[1].gains.k_d for c in cases]
    assert got == pytest.approx([20 * f for f in factors] + [80 * f for f in factors], rel=1e-12)
    assert [c.values["robots.1.gains.k_d"] for c in cases] == got
    assert [c.params["robots.1.gains.k_d"] for c in cases] == [20] * 3 + [80] * 3


# --- names never leave --out -------------------------------------------------------------------

@pytest.mark.parametrize("name", ["../../escape", "/tmp/abs/evil", ".. ünï/cødé"])
def test_figures_stay_in_the_study_folder_whatever_the_name(tmp_path, name):
    out = tmp_path / "deep" / "out"
    study = load_study(data=json.dumps({"name": name, "grid": {
        "robots.*.gains.k_d": [20, 40], "robots.*.gains.K_R": [60, 120]}}))
    cases = expand(study)
    store = ResultStore(out)
    rng = np.random.default_rng(3)
    records = {c.hash: store.save(c, _fake_result(rng), None) for c in cases}
    store.write_tables(study, cases, records, "local")
    before = {p for p in tmp_path.rglob("*")}
    written = plot_study(out)
    assert len(written) == 3
    for path in written:
        assert path.parent == out and path.name.startswith(file_stem(name))
        assert "/" not in path.name and not path.name.startswith(".")
    assert {p for p in tmp_path.rglob("*")} - before == set(written)


def test_plot_from_a_doctored_study_json_writes_only_inside(tmp_path, capsys):
    out = tmp_path / "out"
    study = load_study(data="grid: {robots.*.gains.k_d: [20, 40]}")
    cases = expand(study)
    StudyFolder(out).claim("study").release()
    store = ResultStore(out)
    rng = np.random.default_rng(4)
    records = {c.hash: store.save(c, _fake_result(rng), None) for c in cases}
    store.write_tables(study, cases, records, "local")
    doc = json.loads((out / "study.json").read_text())
    doc["name"] = "../../../x"
    (out / "study.json").write_text(json.dumps(doc))
    assert main(["study", "--plot", str(out), "--quiet"]) == 0
    assert (out / "x_vs_gains_k_d.png").is_file()
    assert not list(tmp_path.glob("x*")) and not list(tmp_path.parent.glob("x_vs*"))


# --- I/O failures: one line, exit 2 before work, 1 after -------------------------------------

@pytest.mark.parametrize("text", ['{"name": "s", "grid": {"a": [1]}, "cases": [', "\xff\xfe",
                                  '{"name": 3}', '{"name": "s", "grid": {"a": [1]}, '
                                  '"metrics": ["m"], "cases": [{"params": {}}]}'])
def test_plot_of_a_damaged_study_json_is_one_line_exit_2(tmp_path, capsys, text):
    out = tmp_path / "out"
    StudyFolder(out).claim("s").release()
    (out / "study.json").write_bytes(text.encode("latin-1"))
    assert main(["study", "--plot", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "study.json" in err[0] and "Traceback" not in err[0], err


def test_an_out_that_cannot_be_created_is_one_line_exit_2(tmp_path, capsys):
    (tmp_path / "file").write_text("x")
    assert main(["study", str(_study_file(tmp_path)), "--out",
                 str(tmp_path / "file" / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("drake-coop study: error: --out ")


def test_a_full_disk_before_any_case_is_exit_2_with_one_line(tmp_path, capsys, monkeypatch):
    import drake_coop.studies.store as store_module

    def full(path, text):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(store_module, "atomic_write_text", full)
    assert main(["study", str(_study_file(tmp_path)), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"drake-coop study: error: --out {tmp_path / 'o'}: writing results.csv "
                   "failed (No space left on device)"]


def test_damaged_case_files_are_skipped_with_a_warning(tmp_path):
    study = load_study(data="grid: {robots.*.gains.k_d: [20, 30, 40, 50]}")
    cases = expand(study)
    store = ResultStore(tmp_path)
    rng = np.random.default_rng(5)
    for c in cases:
        store.save(c, _fake_result(rng), None)
    paths = [tmp_path / "cases" / f"{c.hash}.json" for c in cases]
    paths[0].write_text(paths[0].read_text()[:100])                  # truncated
    doc = json.loads(paths[1].read_text())
    del doc["metrics"]
    paths[1].write_text(json.dumps(doc))                             # a field missing
    paths[2].write_bytes(b"\xff\xfe{}")                              # not UTF-8
    records = store.load()
    assert set(records) == {cases[3].hash}
    assert len(store.skipped) == 3
    for path, warning in zip(sorted(paths[:3]), store.skipped):
        assert warning.startswith(path.name) and warning.endswith("its case runs again")


def test_a_died_case_is_not_a_result_and_shows_as_died(tmp_path):
    study = load_study(data="grid: {robots.*.gains.k_d: [20, 30]}")
    cases = expand(study)
    store = ResultStore(tmp_path)
    with pytest.raises(ValueError, match="is not a result"):
        store.save(cases[0], {**_fake_result(np.random.default_rng(0)), "status": "died"}, None)
    store.mark_died(cases[0], "the case's process was killed by SIGKILL")
    assert store.load() == {} and set(store.died()) == {cases[0].hash}
    store.write_tables(study, cases, {}, "local", store.died())
    doc = json.loads((tmp_path / "study.json").read_text())
    assert [c["status"] for c in doc["cases"]] == ["died", "pending"]
    store.save(cases[0], _fake_result(np.random.default_rng(0)), None)   # a retry finished
    assert store.died() == {} and set(store.load()) == {cases[0].hash}


# --- run.json: plot bounds its work ------------------------------------------------------------

def test_plot_refuses_a_run_json_with_400000_phases_quickly(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    phases = [[f"p{i}", i * 1e-3, (i + 1) * 1e-3] for i in range(400_000)]
    (run / "run.json").write_text(json.dumps({"robots": ["robot1", "robot2"],
                                              "phases": phases}))
    started = time.process_time()
    assert main(["plot", str(run)]) == 2
    assert time.process_time() - started < 5.0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'phases' lists 400000 phases, at most" in err[0]


# --- the command with a stand-in engine (no simulation): damaged files, a full disk ----------

def _fake_engine(monkeypatch, calls: list):
    import drake_coop.studies.engines as engines

    def run_local(cases, t_end, on_result, *, workers=2):
        rng = np.random.default_rng(len(calls))
        for case in cases:
            calls.append(case.hash)
            on_result(case, _fake_result(rng))

    monkeypatch.setattr(engines, "run_local", run_local)


def test_a_damaged_case_file_is_rerun_with_a_warning_not_a_blocked_resume(tmp_path, capsys,
                                                                           monkeypatch):
    calls: list = []
    _fake_engine(monkeypatch, calls)
    path, out = _study_file(tmp_path), tmp_path / "out"
    assert main(["study", str(path), "--out", str(out), "--quiet"]) == 0
    assert len(calls) == 2
    victim = out / "cases" / f"{calls[0]}.json"
    doc = json.loads(victim.read_text())
    del doc["status"]
    victim.write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["study", str(path), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"warning: {victim.name}: status must be one of ok, diverged, failed, error; its case runs " \
           "again" in err
    assert "1 already finished, running 1" in err and calls[2:] == [calls[0]]
    assert json.loads(victim.read_text())["status"] == "ok"


def test_a_full_disk_during_a_study_is_exit_1_with_one_line_and_keeps_the_cases(
        tmp_path, capsys, monkeypatch):
    import drake_coop.studies.store as store_module

    calls: list = []
    _fake_engine(monkeypatch, calls)
    real = store_module.atomic_write_text
    writes = []

    def filling(path, text):
        writes.append(path)
        if len(writes) > 4:              # results.csv, study.json, case 0, its tables, ...
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path, text)

    monkeypatch.setattr(store_module, "atomic_write_text", filling)
    out = tmp_path / "out"
    assert main(["study", str(_study_file(tmp_path)), "--out", str(out)]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert err[-1] == (f"drake-coop study: writing to --out {out} failed (No space left on "
                       "device); the cases finished before are kept; free the space and run "
                       "again to resume"), err
    assert not any("Traceback" in line or "error" in line for line in err[:-1]), err
    assert len(list((out / "cases").glob("*.json"))) == 1
