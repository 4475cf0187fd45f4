"""bench.reference_table_friction: its bases, the saturation column's reach, the overlap."""

from __future__ import annotations

import json

import pytest

from bench.reference_table_friction import ROOT, overlap, saturating_joints, write_bases
from drake_coop.scenario.loading import load_scenario
from drake_coop.control.arm_plant import description_packages
from drake_coop.studies.reference_table import default_columns, FRICTION_COLUMNS


@pytest.mark.skipif("example-robot-data" not in description_packages(),
                    reason='example-robot-data is not installed (pip install -e ".[robots]")')
def test_the_bases_are_the_contact_scenario_and_the_every_arm_ur10_row(tmp_path):
    """The paper's arms: contact.yaml's plant with an estimated box; the lab pair: the UR10
    row of every_arm.json, its placement and its derived gains, the box held by friction."""
    paths = write_bases(tmp_path)
    paper = load_scenario(paths["paper_contact"])
    shipped = load_scenario(ROOT / "scenarios" / "contact.yaml")
    assert paper.plant == shipped.plant and paper.plant.object_mode == "contact"
    assert (shipped.object_model.mode, paper.object_model.mode) == ("none", "estimated")
    pair = load_scenario(paths["ur10_pair"])
    row = json.loads((ROOT / "docs" / "results" / "every_arm.json").read_text())["cases"]["ur10"]
    assert pair.plant.object_mode == "contact" and pair.object_model.mode == "estimated"
    for robot in pair.robots:
        gains = row["gains"]["robots"][robot.name]
        assert robot.gains.K_R == gains["K_R"] and robot.gains.Lambda == gains["Lambda"]
        assert "ur10_robot.urdf" in robot.model
    assert default_columns(pair) == FRICTION_COLUMNS
    assert not list(tmp_path.glob(".*"))             # the loader's file removed


def test_the_saturation_column_reaches_a_joint_only_above_the_floor():
    """The limit is max(0.9 × U(0.95, 1.05) × lift, 1.02 × other): below the lift's peak on
    some draw only where 0.945 × lift > 1.02 × other."""
    peaks = {"robot1": {"lift": [10.0, 10.0, 10.0], "other": [9.0, 9.4, 1.0]}}
    # 0.945 × 10 = 9.45: above 1.02 × 9.0 = 9.18, below 1.02 × 9.4 = 9.588
    assert saturating_joints(peaks) == {"robot1": [0, 2]}


def test_the_overlap_compares_the_order_of_the_medians():
    short = {"cells": {"observer": {"exact": {"squeeze": {"median": [0.2, 0.2, 0.2]}}},
                       "momentum": {"exact": {"squeeze": {"median": [0.1, 0.1, 0.1]}}},
                       "none": {"exact": {"squeeze": {"median": [0.3, 0.3, 0.3]}}}}}
    full = {"rows": {"observer": [{"squeeze": 0.08}], "momentum": [{"squeeze": 0.03}],
                     "none": [{"squeeze": 0.02}]}}
    verdicts = {tuple(v["pair"]): v["verdict"] for v in overlap(short, full)}
    assert verdicts[("momentum", "observer")] == "agrees"
    assert verdicts[("momentum", "none")] == "disagrees"
    assert verdicts[("none", "observer")] == "disagrees"


def _record(folder, h, row, col, draw, status, squeeze, cpu=1.0):
    metrics = {} if squeeze is None else {"robot1": {
        "circle": {"force_error": {"rms": squeeze, "max": 1.0},
                   "estimate_error": {"rms": 0.5, "max": 1.0}},
        "lift": {"force_error": {"rms": 0.7, "max": 1.0}}}}
    (folder / "cases").mkdir(parents=True, exist_ok=True)
    (folder / "cases" / f"{h}.json").write_text(json.dumps({
        "hash": h, "params": {"row": row, "column": col, "draw": draw}, "status": status,
        "message": "", "t_reached": 8.0, "wall_time_s": cpu, "metrics": metrics,
        "cpu_time_s": cpu}))


def test_two_folders_are_compared_case_by_case_by_row_column_and_draw(tmp_path):
    """The same numbers under another hash count as the same; a diverged case (NaN numbers)
    equals itself; a changed squeeze differs; a case in one folder only is counted apart."""
    from bench.reference_table import compare_stores

    a, b = tmp_path / "a", tmp_path / "b"
    _record(a, "h1", "momentum", "exact", 0, "ok", 0.1)
    _record(b, "h1", "momentum", "exact", 0, "ok", 0.1, cpu=2.0)
    _record(a, "h2", "momentum", "id_map_sdp_5s", 3, "ok", 0.2)
    _record(b, "k2", "momentum", "id_map_sdp_5s", 3, "ok", 0.2)    # its model file elsewhere
    _record(a, "h3", "observer", "coulomb", 1, "diverged", None)
    _record(b, "h3", "observer", "coulomb", 1, "diverged", None)
    _record(a, "h4", "observer", "exact", 0, "ok", 0.3)
    _record(b, "h4", "observer", "exact", 0, "ok", 0.3000000000000001)
    _record(a, "h5", "none", "exact", 0, "ok", 0.4)
    c = compare_stores(a, b)
    assert (c["compared"], c["same"], c["same_hash"]) == (4, 3, 3)
    # an earlier version of a case in one folder, which its table (cases.csv) no longer lists
    _record(b, "h4", "observer", "exact", 0, "ok", 0.3)
    _record(b, "old4", "observer", "exact", 0, "diverged", None)
    (b / "cases.csv").write_text("row,column,draw,hash\n" + "".join(
        f"r,c,0,{h}\n" for h in ("h1", "k2", "h3", "h4")))
    again = compare_stores(a, b)
    assert (again["compared"], again["same"]) == (4, 4)    # h4 compared, not old4
    assert [d["case"] for d in c["differ"]] == [["observer", "exact", 0]]
    assert (c["only_a"], c["only_b"]) == (1, 0)
    assert (c["cpu_cases_s_a"], c["cpu_cases_s_b"]) == (5.0, 5.0)
