"""The more-draws comparison of the reference table (``bench/reference_table_draws.py``)."""

import json

from bench.reference_table_draws import compare, main


def _cell(n, diverged, median, lo, hi):
    return {"n": n, "diverged": diverged, "squeeze": {"median": [median, lo, hi]}}


def _table(cells):
    return {"rows": sorted(cells), "columns": ["a", "b", "c"], "cells": cells, "cases": 3,
            "finished": 3, "cpu_time_s": {"per_case_mean": 1.0}}


def test_a_median_inside_outside_or_against_a_point_interval():
    many = _table({"r": {"a": _cell(100, 30, 1.0, 0.9, 1.1), "b": _cell(100, 0, 2.5, 2.4, 2.6),
                         "c": _cell(100, 0, 0.5, 0.5, 0.5), "d": _cell(100, 0, 1, 1, 1)}})
    twenty = _table({"r": {"a": _cell(20, 6, 1.05, 0.8, 1.3), "b": _cell(20, 0, 2.0, 1.9, 2.1),
                           "c": _cell(20, 0, 0.5, 0.5, 0.5)}})
    result = compare(many, twenty)
    a, b, c = (result["cells"]["r"][k] for k in "abc")
    assert a["inside_20_interval"] is True and abs(a["width_ratio"] - 0.2 / 0.5) < 1e-12
    assert a["diverged_fraction"] == 0.3 and a["diverged_fraction_20"] == 0.3
    assert b["inside_20_interval"] is False
    assert c["inside_20_interval"] is None and c["width_ratio"] is None
    assert "d" not in result["cells"]["r"]            # a cell the 20-draw table lacks
    assert (result["inside"], result["compared"]) == (1, 2)


def test_a_missing_store_is_one_line_and_exit_2(tmp_path, capsys):
    assert main([str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "table.json" in err


def test_written_file_names_its_command(tmp_path, monkeypatch):
    store = tmp_path / "store"
    store.mkdir()
    (store / "table.json").write_text(json.dumps(
        _table({"observer": {"model_30": _cell(100, 1, 1.0, 0.9, 1.1)}})))
    out = tmp_path / "cmp.json"
    assert main([str(store), "--write", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert "--draws 100" in doc["command"] and doc["cases"] == 3


def test_both_directions_of_the_interval_check_and_the_unfinished_cells():
    # "a": the 100-draw median inside the 20-draw interval, but the 20-draw median outside the
    # (narrower) 100-draw interval; "b": inside both ways; "c": 40 draws of 100 (unfinished).
    many = _table({"r": {"a": _cell(100, 0, 1.0, 0.95, 1.05), "b": _cell(100, 0, 2.0, 1.9, 2.2),
                         "c": _cell(40, 0, 3.0, 2.0, 4.0)},
                   "s": {"a": _cell(100, 0, 0.5, 0.5, 0.5)}})
    twenty = _table({"r": {"a": _cell(20, 0, 1.2, 0.8, 1.3), "b": _cell(20, 0, 2.1, 1.8, 2.4),
                           "c": _cell(20, 0, 5.0, 4.5, 6.0)},
                     "s": {"a": _cell(20, 0, 0.4, 0.3, 0.6)}})
    result = compare(many, twenty)
    a, b, c = (result["cells"]["r"][k] for k in "abc")
    assert a["inside_20_interval"] is True and a["median_20_inside_interval"] is False
    assert b["inside_20_interval"] is True and b["median_20_inside_interval"] is True
    assert c["inside_20_interval"] is False
    assert result["cells"]["s"]["a"]["median_20_inside_interval"] is None   # a point at 100
    assert result["cells"]["s"]["a"]["inside_20_interval"] is True
    assert (result["inside"], result["compared"]) == (3, 4)
    assert result["outside"] == ["r/c"]
    assert (result["inside_100"], result["compared_100"]) == (1, 3)
    assert result["outside_100"] == ["r/a", "r/c"]
    assert result["draws"] == 100 and result["incomplete"] == ["r/c"]


def test_the_command_names_rows_and_columns_only_where_not_all():
    from bench.reference_table_draws import command
    from drake_coop.studies.reference_table import COLUMNS, ROWS

    every = {"rows": [r.name for r in ROWS], "columns": list(COLUMNS)}
    assert command(every, 100) == ("drake-coop reference-table --out STORE --draws 100 "
                                   "--ray 127.0.0.1:PORT")
    some = {"rows": ["observer", "none"], "columns": list(COLUMNS)[:2]}
    text = command(some, 60)
    assert "--rows observer,none" in text and f"--columns {COLUMNS[0]},{COLUMNS[1]}" in text
    assert "--draws 60" in text


def test_an_interval_narrower_than_a_millionth_of_its_median_is_a_point():
    # The clock column under a source that ignores the skew: draws 1e-10 apart.
    many = _table({"r": {"a": _cell(100, 0, 0.0486885187, 0.04868851871, 0.04868851873),
                         "b": _cell(100, 0, 1.0, 0.99999, 1.00001)}})
    twenty = _table({"r": {"a": _cell(20, 0, 0.0486885186, 0.04868851869, 0.04868851872),
                           "b": _cell(20, 0, 1.0, 0.99, 1.01)}})
    result = compare(many, twenty)
    a, b = result["cells"]["r"]["a"], result["cells"]["r"]["b"]
    assert a["inside_20_interval"] is None and a["median_20_inside_interval"] is None
    assert b["median_20_inside_interval"] is True      # 2e-5 wide: compared
    assert (result["compared"], result["compared_100"]) == (1, 1)


def test_a_run_log_gives_its_plan_its_last_progress_and_its_exit(tmp_path):
    from bench.reference_table_draws import run_log

    log = tmp_path / "more_1.log"
    log.write_text(
        "reference table: 5600 cases, 4600 already finished, running 1000 -> /x\n"
        "reference table: 4505 of 5600\nreference table: 4825 of 5600\n"
        "drake-coop: interrupted (Ctrl-C)\nCommand exited with non-zero status 130\n"
        "\tUser time (seconds): 18.63\n\tSystem time (seconds): 0.98\n"
        "\tElapsed (wall clock) time (h:mm:ss or m:ss): 1:14:48.12\n\tExit status: 130\n")
    got = run_log(log)
    assert (got["cases"], got["already_finished"], got["running"]) == (5600, 4600, 1000)
    assert got["last_progress"] == "reference table: 4825 of 5600" and got["exit"] == 130
    assert got["progress"] == 4825
    assert abs(got["cpu_s"] - 19.61) < 1e-9 and abs(got["wall_s"] - 4488.12) < 1e-9
    assert got["log"] == "more_1.log"


def test_written_file_records_the_runs(tmp_path):
    store = tmp_path / "store"
    store.mkdir()
    (store / "table.json").write_text(json.dumps(
        _table({"observer": {"model_30": _cell(100, 1, 1.0, 0.9, 1.1)}})))
    log = tmp_path / "first.log"
    log.write_text("reference table: 3 cases, 0 already finished, running 3 -> s\n"
                   "reference table: 3 of 3\n\tExit status: 0\n")
    out = tmp_path / "cmp.json"
    assert main([str(store), "--write", str(out), "--runs", str(log)]) == 0
    runs = json.loads(out.read_text())["runs"]
    assert [(r["log"], r["running"], r["exit"]) for r in runs] == [("first.log", 3, 0)]


def test_the_committed_5x_file_covers_the_whole_table_and_matches_the_20_draw_table():
    """The shipped comparison: every row and default column, its 20-draw side equal to the
    committed 20-draw table's cells, its counts and lists what its cells say."""
    from pathlib import Path

    from bench.reference_table_draws import POINT
    from drake_coop.studies.reference_table import COLUMNS, ROWS

    root = Path(__file__).resolve().parents[2] / "docs" / "results"
    doc = json.loads((root / "reference_table_5x.json").read_text())
    twenty = json.loads((root / "reference_table_run.json").read_text())["cells"]
    assert doc["rows"] == [r.name for r in ROWS] and doc["columns"] == list(COLUMNS)
    assert {(r, c) for r in doc["cells"] for c in doc["cells"][r]} == {
        (r.name, c) for r in ROWS for c in COLUMNS}
    inside = compared = 0
    for row, cols in doc["cells"].items():
        for col, c in cols.items():
            ref = twenty[row][col]
            assert c["median_20"] == ref["squeeze"]["median"][0]
            assert c["interval_20"] == ref["squeeze"]["median"][1:]
            assert c["diverged_20"] == ref["diverged"] and 20 <= c["draws"] <= doc["draws"]
            lo, hi = c["interval_20"]
            if hi - lo > max(POINT * abs(c["median_20"]), 1e-12):
                compared += 1
                inside += lo <= c["median"] <= hi
    assert (inside, compared) == (doc["inside"], doc["compared"])
    assert doc["incomplete"] == [f"{r}/{k}" for r, cols in doc["cells"].items()
                                 for k, c in cols.items() if c["draws"] < doc["draws"]]
    assert doc["finished"] <= doc["cases"] == len(ROWS) * len(COLUMNS) * doc["draws"]
