"""bench/lab_arms_object.py's results file: calls running at once each keep the others' cases."""

from __future__ import annotations

import json
import multiprocessing

from bench.lab_arms_object import case_name, write_case


def _write(args):
    out, i = args
    write_case(out, f"case{i}", {"i": i})


def test_calls_writing_at_once_keep_each_others_cases_and_leave_no_temporary_file(tmp_path):
    out = tmp_path / "results" / "cases.json"
    with multiprocessing.get_context("spawn").Pool(4) as pool:
        pool.map(_write, [(out, i) for i in range(24)])
    data = json.loads(out.read_text())
    assert data["cases"] == {f"case{i}": {"i": i} for i in range(24)}
    assert sorted(p.name for p in out.parent.iterdir()) == ["cases.json"]


def test_a_case_key_names_the_changed_box_step_and_squeeze():
    assert case_name("two_ur5", None, None, None) == "two_ur5"
    assert case_name("contact", 1.2, 0.6, None) == "contact@m1p2_mu0p6"
    assert (case_name("contact", 1.5, 0.5, 0.001, "friction")
            == "contact@m1p5_mu0p5_dt0p001_sqfriction")
