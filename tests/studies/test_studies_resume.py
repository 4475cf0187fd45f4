"""Every shipped study resumes: interrupted at any point, a rerun computes only the cases
that had not finished, and ``results.csv`` lists every finished case as finished — whatever
its metrics look like (the object carry's counts, times and nulls included).

The cases' results are real (each shipped study shrunk with ``--t-end``/``--draws``/
``--cases`` and its cases simulated once, in this process); the interruptions are played by
a stand-in engine that hands those results back and stops where the test says (a signal
between two cases, after a case's file is written, before its tables are), so that every
point is reached without racing a real signal. One test sends a real SIGTERM to a real
rerun of the object carry on the local pool.

Each shrunk study is expanded once for the module (:func:`_expand_once`, keyed on the study
and its size; the expansion and its reachability checks are deterministic in them), and
the ``study`` command gets those cases on every run here: these tests are about what a run
keeps and what a resume runs again, not about expanding (the expansion's own tests, and the
last test here, which counts a resume's reachability checks without this memo)."""

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
from drake_coop.control.arm_plant import description_packages
from drake_coop.studies import expand, load_study
from drake_coop.studies.expand import MAX_CASES
from drake_coop.studies.cli import Terminated
from drake_coop.studies.size import apply_size
from drake_coop.studies.store import FINISHED, ResultStore

ROOT = Path(__file__).resolve().parents[2]
STUDIES = sorted((ROOT / "studies").glob("*.yaml"))
#: The shipped studies whose base scenarios need the lab arms' descriptions (the robots extra).
NEEDS_ROBOTS = {"object_carry_lab"}
HAVE_ROBOTS = "example-robot-data" in description_packages()
needs_robots = pytest.mark.skipif(
    not HAVE_ROBOTS, reason='example-robot-data is not installed (pip install -e ".[robots]")')
T_END = 0.02
#: The shrunk size of each study: its first cases (the object carry's first four are the
#: four object models on one draw: none, known, estimated, estimated + shared; the lab arms'
#: first three the paper's control on two Pandas, two UR5s and three arms, one draw).
SIZES = {"object_carry": {"t_end": T_END, "draws": 1, "cases": 4},
         "object_carry_lab": {"t_end": T_END, "draws": 1, "cases": 3}}


def _size(path: Path) -> dict:
    return SIZES.get(path.stem, {"t_end": T_END, "cases": 2})


def _argv(size: dict) -> list[str]:
    return [x for k, v in size.items() for x in (f"--{k.replace('_', '-')}", str(v))]


#: (the study's repr, max_cases, first) -> (its cases, its reachability checks' cache).
_EXPANDED: dict = {}


def _expand_once(study, *, max_cases: int = MAX_CASES, first=None, cache=None):
    """:func:`expand`, once per study and size in this module: a later call gets the
    same cases (a new list) and, in ``cache``, the reachability checks the first made."""
    key = (repr(study), max_cases, first)
    if key not in _EXPANDED:
        reach: dict = {}
        _EXPANDED[key] = (expand(study, max_cases=max_cases, first=first, cache=reach), reach)
    cases, reach = _EXPANDED[key]
    if cache is not None:
        cache.update(reach)
    return list(cases)


@pytest.fixture
def expanded_once():
    """The ``study`` command expands through :func:`_expand_once` during the test (a
    patch of its own, kept when the test undoes ``monkeypatch``)."""
    import drake_coop.studies.cli as study_cli

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(study_cli, "expand", _expand_once)
        yield


@pytest.fixture(scope="module")
def real_results() -> dict[str, dict[str, dict]]:
    """study name -> case hash -> the case's real result (``run_case``)."""
    from drake_coop.studies.engines import run_case

    out = {}
    for path in STUDIES:
        if path.stem in NEEDS_ROBOTS and not HAVE_ROBOTS:
            continue
        study, first = apply_size(load_study(path), _size(path))
        out[path.stem] = {c.hash: run_case(c.scenario_yaml, study.t_end)
                          for c in _expand_once(study, first=first)}
    return out


def _engine(monkeypatch, results: dict[str, dict], calls: list, stop=None):
    """A stand-in for the local pool: the real results, in order; ``stop(i)`` is called
    before the i-th case and may raise."""
    import drake_coop.studies.engines as engines

    def run_local(cases, t_end, on_result, *, workers=2):
        for i, case in enumerate(cases):
            if stop is not None:
                stop(i)
            calls.append(case.hash)
            on_result(case, results[case.hash])

    monkeypatch.setattr(engines, "run_local", run_local)


def _rows(out: Path) -> dict[str, str]:
    with open(out / "results.csv", newline="") as f:
        return {r["hash"]: r["status"] for r in csv.DictReader(f)}


def _finished_on_disk(out: Path) -> dict[str, tuple[int, bytes]]:
    return {p.stem: (p.stat().st_mtime_ns, p.read_bytes()) for p in (out / "cases").glob("*.json")}


def _check_tables(out: Path) -> None:
    """results.csv and study.json list every case with a file as finished, the others not."""
    on_disk = set(_finished_on_disk(out))
    rows = _rows(out)
    assert {h for h, s in rows.items() if s in FINISHED} == on_disk, rows
    doc = json.loads((out / "study.json").read_text())
    assert {c["hash"] for c in doc["cases"] if c["status"] in FINISHED} == on_disk


def _interrupt_and_resume(tmp_path, monkeypatch, capsys, path: Path, results: dict,
                          where: str, k: int) -> None:
    out = tmp_path / "out"
    argv = ["study", str(path), "--out", str(out), *_argv(_size(path)), "--quiet"]
    n = len(results)
    calls: list = []
    if where == "between":                       # a signal before the k-th case
        def stop(i):
            if i == k:
                raise Terminated()
        _engine(monkeypatch, results, calls, stop)
    else:
        _engine(monkeypatch, results, calls)
        cls = ResultStore
        real = cls.save if where == "saved" else cls.write_tables
        saved = []

        def cut(self, *a, **kw):
            value = real(self, *a, **kw)
            if where == "saved":
                saved.append(1)
                if len(saved) == k + 1:          # the k-th case's file is written: cut
                    raise Terminated()
            return value

        def cut_tables(self, *a, **kw):          # the k-th case's tables: cut before them
            if len(calls) == k + 1 and not getattr(self, "_cut", False):
                self._cut = True
                raise Terminated()
            return real(self, *a, **kw)

        monkeypatch.setattr(cls, "save" if where == "saved" else "write_tables",
                            cut if where == "saved" else cut_tables)
    assert main(argv) == 143
    _check_tables(out)
    kept = _finished_on_disk(out)
    monkeypatch.undo()
    resumed: list = []
    _engine(monkeypatch, results, resumed)
    capsys.readouterr()
    assert main(argv[:-1]) == 0
    assert f"{len(kept)} already finished, running {n - len(kept)}" in capsys.readouterr().err
    assert sorted(resumed) == sorted(set(results) - set(kept))       # only the unfinished
    after = _finished_on_disk(out)
    assert set(after) == set(results)
    assert all(after[h] == kept[h] for h in kept)                    # none run again
    _check_tables(out)
    assert set(_rows(out).values()) <= set(FINISHED)


@pytest.mark.parametrize("path", [pytest.param(p, marks=needs_robots) if p.stem in NEEDS_ROBOTS
                                  else p for p in STUDIES], ids=[p.stem for p in STUDIES])
def test_every_shipped_study_resumes_after_an_interruption(tmp_path, monkeypatch, capsys,
                                                            real_results, expanded_once, path):
    results = real_results[path.stem]
    assert all(r["status"] in FINISHED for r in results.values())
    _interrupt_and_resume(tmp_path, monkeypatch, capsys, path, results, "between", 1)


@pytest.mark.parametrize("where, k", [("between", 0), ("between", 2), ("between", 3),
                                      ("saved", 0), ("saved", 2), ("tables", 1),
                                      ("tables", 3)])
def test_the_object_carry_resumes_from_any_point(tmp_path, monkeypatch, capsys,
                                                 real_results, expanded_once, where, k):
    results = real_results["object_carry"]
    phases = [p for r in results.values() for m in r["metrics"].values() for p in m.values()]
    assert any(p.get("mass_convergence_time", {}).get("time", 0) is None for p in phases)
    assert any("slips" in p and "drops" in p for p in phases)
    _interrupt_and_resume(tmp_path, monkeypatch, capsys, ROOT / "studies" / "object_carry.yaml",
                          results, where, k)


@needs_robots
@pytest.mark.parametrize("where, k", [("between", 2), ("saved", 1), ("tables", 2)])
def test_the_lab_arms_carry_resumes_with_its_arm_sets_in_one_table(tmp_path, monkeypatch,
                                                                   capsys, real_results,
                                                                   expanded_once, where, k):
    """studies/object_carry_lab.yaml (a grid over base scenarios): two- and three-arm cases
    in one folder, interrupted anywhere, resume to one table naming each case's base."""
    path = ROOT / "studies" / "object_carry_lab.yaml"
    results = real_results["object_carry_lab"]
    robots = {len(r["metrics"]) for r in results.values()}
    assert robots == {2, 3}
    _interrupt_and_resume(tmp_path, monkeypatch, capsys, path, results, where, k)
    with open(tmp_path / "out" / "results.csv", newline="") as f:
        bases = [r["base"] for r in csv.DictReader(f)]
    assert bases == ["../scenarios/two_pandas.yaml", "../scenarios/two_ur5.yaml",
                     "../scenarios/three_arms_contact.yaml"]


def test_a_finished_contact_case_is_kept_by_the_store(tmp_path, real_results):
    """The stored-case check accepts the object's counts, times and nulls as the metrics
    write them, and still refuses a count that is not a count."""
    study, first = apply_size(load_study(ROOT / "studies" / "object_carry.yaml"),
                              SIZES["object_carry"])
    cases = _expand_once(study, first=first)
    store = ResultStore(tmp_path)
    for case in cases:
        store.save(case, real_results["object_carry"][case.hash], study.t_end)
    assert set(store.load()) == {c.hash for c in cases} and store.skipped == []
    victim = tmp_path / "cases" / f"{cases[2].hash}.json"
    doc = json.loads(victim.read_text())
    doc["metrics"]["robot1"]["all"]["slips"]["count"] = 1.5
    victim.write_text(json.dumps(doc))
    assert set(store.load()) == {c.hash for c in cases[:2] + cases[3:]}
    assert "all.slips: needs 'count', an integer >= 0" in store.skipped[0]


@pytest.mark.slow
def test_a_real_sigterm_during_a_rerun_keeps_every_finished_case_finished(tmp_path):
    """The case first reported: a finished contact study, two case files removed, rerun on the
    local pool and stopped by SIGTERM as soon as it runs a case; every case file on disk is
    finished in results.csv, and the resume runs only the missing ones."""
    path = ROOT / "studies" / "object_carry.yaml"
    out = tmp_path / "out"
    size = _argv({"t_end": T_END, "draws": 1, "cases": 3})
    assert main(["study", str(path), "--out", str(out), *size, "--quiet"]) == 0
    files = sorted((out / "cases").glob("*.json"))
    for p in files[:2]:
        p.unlink()
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "drake_coop", "study", str(path), "--out",
                             str(out), "--workers", "1"], env=env, cwd=ROOT,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if any("spawn_main" in " ".join(_cmdline(c)) for c in _children(proc.pid)):
            break                              # a case's process is running
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and "Traceback" not in err, err
    assert "resuming at the size recorded" in err
    _check_tables(out)
    kept = _finished_on_disk(out)
    assert files[2].stem in kept
    assert main(["study", str(path), "--out", str(out), "--quiet"]) == 0
    assert all(_finished_on_disk(out)[h] == kept[h] for h in kept)
    assert len(_finished_on_disk(out)) == 3
    _check_tables(out)


def _children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(x) for x in text.split()]


def _cmdline(pid: int) -> list[str]:
    try:
        return Path(f"/proc/{pid}/cmdline").read_text().split("\0")
    except OSError:
        return []


def test_a_resume_reach_checks_nothing_it_stored(tmp_path, monkeypatch, capsys):
    """The first run reach-checks each base geometry once and keeps the results in its
    folder (``reach_checks.json``); the resume reads them and checks nothing again, its
    warning about the measured phase included (the check counted; a new folder checks
    again, so the counter can fail)."""
    import drake_coop.scenario.reach as reach
    from drake_coop.studies.engines import run_case
    from drake_coop.studies.folder import REACH

    path = ROOT / "studies" / "sampling_period.yaml"
    study, first = apply_size(load_study(path), _size(path))
    results = {c.hash: run_case(c.scenario_yaml, study.t_end)
               for c in expand(study, first=first)}
    checks: list = []
    inner = reach.check_reachable
    monkeypatch.setattr(reach, "check_reachable",
                        lambda scenario: (checks.append(1), inner(scenario))[1])
    out = tmp_path / "out"
    argv = ["study", str(path), "--out", str(out), *_argv(_size(path)), "--quiet"]

    def stop(i):
        if i == 1:
            raise Terminated()

    calls: list = []
    _engine(monkeypatch, results, calls, stop)
    assert main(argv) == 143
    assert len(checks) == 1 and (out / REACH).is_file()       # one base, one geometry
    checks.clear()
    _engine(monkeypatch, results, calls)
    assert main(argv[:-1]) == 0             # not quiet: the phase warning reads a case too
    assert checks == []                                        # the resume: nothing again
    assert main(["study", str(path), "--out", str(tmp_path / "new"), *argv[4:]]) == 0
    assert len(checks) == 1
