"""A resume does not reuse, without being told, a stored case computed by other code.

Every record carries the stamp of the code that computed it; a resume whose stored cases
include some of another stamp (or of none: written before stamps) is refused in one line,
``--stale rerun`` runs exactly those again, ``--stale keep`` keeps them and records how many.
Both commands: ``study`` (a 2 x 2 grid on a tiny segment, its cases run in this process) and
``reference-table`` (its cases' results handed back by a dispatcher standing in for the
workers; the store, the refusal and the tables are the command's own)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from drake_coop.cli import main
from drake_coop.studies.code_stamp import code_stamp

GRID = """
name: tiny
t_end: 0.02
phase: all
grid:
  control_period: [0.003, 0.009]
  robots.*.gains.k_d: [40, 60]
metrics: [worst.position_error.max]
"""


def _files(out: Path) -> dict[str, bytes]:
    return {p.stem: p.read_bytes() for p in sorted((out / "cases").glob("*.json"))}


def _restamp(out: Path, key: str, stamp: str | None) -> None:
    """Rewrite one case file as if other code (``stamp``; None: no stamp) had written it."""
    path = out / "cases" / f"{key}.json"
    record = json.loads(path.read_text())
    record.pop("code")
    if stamp is not None:
        record["code"] = stamp
    path.write_text(json.dumps(record, indent=1) + "\n")


def _make_stale(out: Path, capsys, stamps: dict[int, str | None]
                ) -> tuple[list[str], dict[str, bytes]]:
    """Restamp the study's ``i``-th case (in hash order) with ``stamps[i]`` (None: unstamped);
    returns the sorted hashes and the case files as they then are, output read so far
    dropped."""
    keys = sorted(_files(out))
    for i, stamp in stamps.items():
        _restamp(out, keys[i], stamp)
    capsys.readouterr()
    return keys, _files(out)


@pytest.fixture
def study(tmp_path, monkeypatch):
    """A finished tiny study: (its command line without --stale, its folder, the hashes
    each later run computes)."""
    import drake_coop.studies.engines as engines

    calls: list[str] = []

    def run_local(cases, t_end, on_result, *, workers=2):
        for case in cases:
            calls.append(case.hash)
            on_result(case, engines.run_case(case.scenario_yaml, t_end))

    monkeypatch.setattr(engines, "run_local", run_local)
    path = tmp_path / "tiny.yaml"
    path.write_text(GRID)
    out = tmp_path / "out"
    argv = ["study", str(path), "--out", str(out), "--workers", "1"]
    assert main([*argv, "--quiet"]) == 0
    assert len(calls) == 4
    calls.clear()
    return argv, out, calls


def test_a_resume_with_the_same_code_runs_nothing_and_needs_no_flag(study, capsys):
    argv, out, calls = study
    before = _files(out)
    assert len(before) == 4
    assert all(json.loads(b)["code"] == code_stamp() for b in before.values())
    capsys.readouterr()
    assert main(argv) == 0
    assert calls == [] and _files(out) == before
    assert "4 already finished, running 0" in capsys.readouterr().err
    doc = json.loads((out / "study.json").read_text())
    assert doc["stale_kept"] == 0 and doc["code"] == code_stamp()


def test_cases_of_other_code_or_unstamped_are_refused_in_one_line(study, capsys):
    argv, out, calls = study
    _, before = _make_stale(out, capsys, {0: "0123456789abcdef+drake1.0.0", 2: None})
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    assert f"--out {out}: 2 of the 4 stored cases of this run were computed by other code " \
           "(1 of them carry no code stamp" in err
    assert "--stale rerun" in err and "--stale keep" in err
    assert calls == [] and _files(out) == before


def test_stale_rerun_runs_exactly_those_and_restamps_them(study, capsys):
    argv, out, calls = study
    keys, before = _make_stale(out, capsys, {1: "other", 3: None})
    assert main([*argv, "--stale", "rerun"]) == 0
    assert "2 computed by other code run again (--stale rerun)" in capsys.readouterr().err
    assert sorted(calls) == sorted([keys[1], keys[3]])
    after = _files(out)
    assert {k for k in keys if after[k] != before[k]} == {keys[1], keys[3]}
    assert all(json.loads(b)["code"] == code_stamp() for b in after.values())
    assert json.loads((out / "study.json").read_text())["stale_kept"] == 0
    calls.clear()
    assert main(argv) == 0 and calls == []          # and the next resume needs no flag


def test_stale_keep_keeps_their_numbers_and_records_the_count(study, capsys):
    argv, out, calls = study
    _, before = _make_stale(out, capsys, {0: "other", 3: None})
    assert main([*argv, "--stale", "keep"]) == 0
    err = capsys.readouterr().err
    assert "2 of the finished computed by other code, kept (--stale keep): the results mix " \
           "code versions" in err
    assert calls == [] and _files(out) == before
    doc = json.loads((out / "study.json").read_text())
    assert doc["stale_kept"] == 2
    assert main(argv) == 2                           # still refused without the flag


def test_a_bad_stale_value_is_one_line_exit_2(study, capsys):
    argv, out, calls = study
    capsys.readouterr()
    with pytest.raises(SystemExit) as exited:       # argparse's exit: the process's code
        main([*argv, "--stale", "reuse"])
    assert exited.value.code == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "argument --stale: invalid choice: 'reuse'" in err
    assert "'rerun'" in err and "'keep'" in err and calls == []


def _record(key: str) -> dict:
    """A finished case's result (the circle's two errors, different per case)."""
    rms = (int(key[:6], 16) % 97 + 1) / 100
    return {"status": "ok", "message": "", "t_reached": 1.0, "wall_time_s": 0.1,
            "metrics": {"robot1": {"circle": {"force_error": {"rms": rms, "max": rms},
                                              "estimate_error": {"rms": rms, "max": rms}}}}}


def test_the_reference_table_refuses_reruns_or_keeps_cases_of_other_code(tmp_path, capsys,
                                                                         monkeypatch):
    import drake_coop.studies.reference_engine as engine
    from drake_coop.studies.reference_engine import run_table

    calls: list[str] = []

    def dispatch(batches, work, args_of, on_result, on_death, **kwargs):
        for b in batches:
            calls.extend(c.hash for c in b.cases)
            on_result(b, [(c.hash, _record(c.hash)) for c in b.cases])

    monkeypatch.setattr(engine, "_run", dispatch)
    out = tmp_path / "t"
    kwargs = dict(rows=["sensor_3"], cols=["exact"], draws=3, batch=1, quiet=True)
    first = run_table(out, **kwargs)
    assert first["finished"] == 3 and first["stale_kept"] == 0 and len(calls) == 3
    keys = sorted(_files(out))
    _restamp(out, keys[1], None)
    before, calls[:] = _files(out), []
    with pytest.raises(ValueError, match=f"--out {out}: 1 of the 3 stored cases of this run "
                                         r"were computed by other code \(1 of them carry no"):
        run_table(out, **kwargs)
    argv = ["reference-table", "--out", str(out), "--rows", "sensor_3", "--columns", "exact",
            "--draws", "3", "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "1 of the 3 stored cases" in err
    assert calls == [] and _files(out) == before
    kept = run_table(out, stale="keep", **kwargs)
    assert calls == [] and kept["stale_kept"] == 1 and kept["cells"] == first["cells"]
    assert json.loads((out / "table.json").read_text())["stale_kept"] == 1
    again = run_table(out, stale="rerun", **kwargs)
    assert calls == [keys[1]] and again["stale_kept"] == 0
    assert json.loads((out / "cases" / f"{keys[1]}.json").read_text())["code"] == code_stamp()
    assert main(argv) == 0                          # every record now of this code
    with pytest.raises(ValueError, match="^stale: must be one of rerun, keep"):
        run_table(out, stale="yes", **kwargs)
    with pytest.raises(SystemExit) as exited:
        main([*argv, "--stale", "yes"])
    assert exited.value.code == 2
    assert "argument --stale: invalid choice" in capsys.readouterr().err
