"""No committed result says ``ok`` past a failure guard (the guards' test on logged maxima)."""

from __future__ import annotations

import json
import math

import pytest

from bench import guard_audit
from drake_coop.experiment.failure import summary_failure
from drake_coop.scenario.schema import Guards


def test_no_committed_study_row_says_ok_past_a_guard():
    for path in sorted(guard_audit.ROOT.glob(guard_audit.STUDY_RESULTS)):
        _, rows, failures = guard_audit.audit_csv(path)
        assert not failures, (path.name, [(rows[k]["index"], f.text) for k, f in failures])


def test_no_committed_study_case_file_says_ok_past_a_guard():
    for path in sorted(guard_audit.ROOT.glob(guard_audit.STUDY_CASES)):
        record = json.loads(path.read_text())
        if record.get("status") == "ok":
            assert not guard_audit.audit_metrics(record.get("metrics") or {}), path.name


def test_no_committed_benchmark_row_says_ok_past_a_guard():
    for path in sorted(guard_audit.ROOT.glob(guard_audit.BENCH_RESULTS)):
        assert not guard_audit.audit_bench(json.loads(path.read_text())), path.name


def test_the_benchmark_audit_sees_a_tilted_box_in_an_ok_row():
    row = {"status": "ok", "robots": {"a": {"object_tilt_max": math.radians(12.0),
                                            "object_position_error_max": 0.001}}}
    found = guard_audit.audit_bench({"cases": {"ur3": row, "x": {**row, "status": "failed"}}})
    assert [(where, f.guard) for where, f in found] == [("cases.ur3", "max_object_tilt_deg")]


def test_a_shipped_run_past_a_guard_is_said_so_on_its_page():
    """Each run listed as past a guard is in FAILED_RUNS, whose page names the guard."""
    past = {p.parent.name for p in guard_audit.ROOT.glob(guard_audit.RUN_METRICS)
            if guard_audit.audit_metrics(json.loads(p.read_text()))}
    assert past == set(guard_audit.FAILED_RUNS)
    for name, page in guard_audit.FAILED_RUNS.items():
        assert "max_object_position_error" in (guard_audit.ROOT / page).read_text(), name


@pytest.mark.parametrize("phase, maxima, guard", [
    ("circle", {"r": {"force_error": 20.5}}, "max_squeeze_error"),
    ("circle", {"r": {"force_error": 19.5}}, None),
    # The squeeze guard starts 0.5 s after the grasp: a lift maximum proves nothing.
    ("lift", {"r": {"force_error": 50.0}}, None),
    ("free", {"r": {"position_error": 0.021}}, "max_pad_error"),
    ("circle", {"r": {"object_tilt": math.radians(10.3)}}, "max_object_tilt_deg"),
    ("circle", {"r": {"object_tilt": math.radians(9.9)}}, None),
    # The box is guarded while held only.
    ("free", {"r": {"object_position_error": 0.5}}, None),
    ("put_down", {"r": {"object_position_error": 0.021}}, "max_object_position_error"),
])
def test_summary_failure_reads_each_guard_bound_and_phase(phase, maxima, guard):
    failure = summary_failure(maxima, Guards(), phase)
    assert (failure.guard if failure else None) == guard


def test_a_row_past_a_guard_is_rewritten_failed(tmp_path):
    path = tmp_path / "results.csv"
    path.write_text("index,hash,status,t_reached,robot1.force_error.max,robot1.position_error"
                    ".max,message\n0,a,ok,65,28.0,0.001,completed 65 s\n"
                    "1,b,ok,65,3.0,0.001,completed 65 s\n2,c,diverged,30,90.0,0.5,x\n")
    header, rows, failures = guard_audit.audit_csv(path)
    assert [k for k, _ in failures] == [0]
    guard_audit.rewrite(path, header, rows, failures)
    _, rows, failures = guard_audit.audit_csv(path)
    assert failures == [] and [r["status"] for r in rows] == ["failed", "ok", "diverged"]
    assert rows[0]["message"].startswith("failed in the circle phase: robot1 squeeze 28.0 N")


def test_every_committed_study_figure_is_drawn_from_its_results_as_committed():
    """Each study figure names, in its PNG text field, the bytes of its ``results.csv`` as
    committed: a row rewritten after the figure was drawn (``failed`` by a guard) fails here
    until ``python -m bench.guard_audit --figures`` redraws it (and the redraw marks every
    failed row: ``tests/studies/test_plots.py``)."""
    figures = guard_audit.study_figures()
    for name in ("model_mismatch", "object_carry", "object_carry_lab", "velocity_estimation"):
        assert figures[name], name                # the studies the guards rewrote have figures
    assert "object_carry_lab_vs_base.png" not in [p.name for p in figures["object_carry"]]
    assert guard_audit.stale_figures() == []


def test_a_figure_drawn_from_other_results_is_stale(tmp_path, monkeypatch):
    """The check reads the source the figure names: a figure of an older results.csv, and one
    that names none, are listed; one drawn from the file as it is is not."""
    from matplotlib.figure import Figure

    from drake_coop.studies.plots import SOURCE_KEY, source_text

    folder = tmp_path / guard_audit.STUDY_FIGURES
    folder.mkdir(parents=True)
    csv = folder / "demo_results.csv"
    csv.write_text("index,hash,status\n0,a,ok\n")
    current = source_text(csv)
    for png, source in (("demo_vs_a.png", current), ("demo_vs_b.png", None),
                        ("demo_hist.png", current)):
        Figure().savefig(folder / png, metadata={SOURCE_KEY: source} if source else None)
    csv.write_text("index,hash,status\n0,a,failed\n")     # rewritten after demo_hist was drawn
    Figure().savefig(folder / "demo_hist.png", metadata={SOURCE_KEY: current})
    Figure().savefig(folder / "demo_vs_a.png", metadata={SOURCE_KEY: source_text(csv)})
    monkeypatch.setattr(guard_audit, "ROOT", tmp_path)
    assert [p.name for p in guard_audit.stale_figures()] == ["demo_hist.png", "demo_vs_b.png"]
