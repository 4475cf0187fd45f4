"""``bench.every_arm``: the pair set up as the how-to says (mirrored, the box between the pads),
the row's bars on the worst arm, and the guide's table generated from the results file."""

import json
import math
from pathlib import Path

import pytest

from bench.every_arm import BARS, CONTACT_X, TABLE, pair_yaml, table, verdict
from drake_coop.control.arm_plant import description_packages

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results" / "every_arm.json"


def _robot(squeeze, box, slips=0, tilt=1e-3):
    return {"squeeze_error_rms_N": squeeze, "object_position_error_rms": box, "slips": slips,
            "object_tilt_rms": tilt}


def test_the_worst_arm_decides_each_bar():
    case = {"robots": {"a": _robot(0.1, 0.2e-3), "b": _robot(0.31, 0.1e-3)}}
    v = verdict(case)
    assert v["squeeze_error_rms_N"] == {"value": 0.31, "bar": 0.3, "passes": False}
    assert v["object_position_error_rms_m"]["passes"] and not v["passes"]
    case["robots"]["b"]["squeeze_error_rms_N"] = 0.2
    assert verdict(case)["passes"]
    case["robots"]["a"]["slips"] = 1
    assert verdict(case)["slips"] == {"value": 1, "bar": BARS["slips"], "passes": False}


def test_the_table_shows_numbers_or_the_one_line_refusal():
    data = {"cases": {
        "ur5": {"arms": ["ur5", "ur5"], "robots": {"a": _robot(0.04, 0.16e-3, tilt=2e-3)},
                "verdict": verdict({"robots": {"a": _robot(0.04, 0.16e-3)}}),
                "mass_error_at_lift_end": -0.012},
        "jaco2": {"arms": ["jaco2", "jaco2"], "refusal": "drake-coop gains: grasp buckling:\n "
                                                         "the squeeze | buckles"},
        "jaco2@buckling": {"arms": ["jaco2", "jaco2"], "runs": {}}}}
    lines = table(data).splitlines()
    rows = [line for line in lines if line.startswith("| jaco2") or line.startswith("| ur5")]
    assert rows[0] == ("| jaco2 + jaco2 | refused: drake-coop gains: grasp buckling: the squeeze "
                       "/ buckles | | | | | refused |")
    assert rows[1] == "| ur5 + ur5 | 0.040 | 0.16 | 2.00 | 0 | -1.2 | pass |"
    assert len(rows) == 2                               # the diagnosis is not a row


def test_a_row_says_what_its_run_past_the_refusal_did_and_a_miss_its_remedy():
    ok = verdict({"robots": {"a": _robot(0.03, 0.1e-3)}})
    miss = verdict({"robots": {"a": _robot(0.05, 1.9e-3)}})
    data = {"cases": {
        "z1": {"arms": ["z1", "z1"], "refusal": "drake-coop gains: grasp buckling"},
        "z1@past": {"arms": ["z1", "z1"], "status": "failed", "verdict": miss,
                    "message": "failed at t = 33.750 s: box tilted 10.6 deg"},
        "xarm7": {"arms": ["xarm7", "xarm7"], "refusal": "drake-coop gains: grasp buckling"},
        "xarm7@past": {"arms": ["xarm7", "xarm7"], "status": "ok", "verdict": ok},
        "ur3": {"arms": ["ur3", "ur3"], "status": "failed", "message": "failed at t = 29 s",
                "robots": {"a": _robot(0.05, 1.9e-3)}, "verdict": miss},
        "ur3@sqfriction": {"arms": ["ur3", "ur3"], "status": "ok", "verdict": ok,
                           "robots": {"a": _robot(0.03, 0.1e-3)}}}}
    rows = {line.split(" |")[0]: line for line in table(data).splitlines()[3:]}
    assert rows["| z1 + z1"].endswith("run past the refusal: failed at t = 33.750 s: box "
                                      "tilted 10.6 deg | | | | | refused |")
    assert "run past the refusal: carried (0.030 N, 0.10 mm): the refusal is wrong here" \
        in rows["| xarm7 + xarm7"]
    assert rows["| ur3 + ur3"].endswith("| miss (failed at t = 29 s; `squeeze: friction` "
                                        "passes) |")
    assert rows["| ur3 + ur3, `squeeze: friction`"].endswith("| pass |")
    assert len(rows) == 4                               # the runs past a refusal are no rows


def test_the_shipped_table_is_the_results_files():
    assert TABLE.read_text() == table(json.loads(RESULTS.read_text()))


@pytest.mark.skipif("example-robot-data" not in description_packages(),
                    reason='example-robot-data is not installed (pip install -e ".[robots]")')
def test_the_pair_is_the_hows_mirror_image():
    from pydrake.common.yaml import yaml_load_typed

    from drake_coop.scenario.schema import Scenario

    s = yaml_load_typed(schema=Scenario, data=pair_yaml(("z1", "ur5"), ((0.4, 0.25),
                                                                         (0.5, 0.1))))
    r1, r2 = s.robots
    assert (r1.name, r2.name) == ("z1_1", "ur5_2")
    assert r1.contact_xy[0] == CONTACT_X[0] and r2.contact_xy[0] == CONTACT_X[1]
    assert r1.base_xyz == pytest.approx([CONTACT_X[0] - 0.4, 0.0, 0.25])
    assert r2.base_xyz == pytest.approx([CONTACT_X[1] + 0.5, 0.0, 0.1])
    assert (r1.base_yaw_deg, r2.base_yaw_deg) == (0.0, 180.0)
    assert r1.ee_rpy_deg == [0.0, 90.0, 0.0] and r2.ee_rpy_deg == [0.0, 90.0, 180.0]
    assert r1.normals == [[-1.0, 0.0, 0.0]] and r2.normals == [[1.0, 0.0, 0.0]]
    assert s.plant.object_mode == "contact" and s.object_model.mode == "estimated"
    assert s.plant.object_mass == 0.5 and s.plant.friction == 1.0     # contact.yaml's box


def _grasp_checks(cases: dict) -> dict:
    """Per row key (``ur3``, ``ur3@sqfriction``, ``ur3@scale0.5``): the grasp dynamics check's
    verdict, from the row's own ``gains`` checks (a run past the refusal included) or its
    ``@grasp`` case (the check run alone) — the check that follows the moving reference only
    (its record has ``amplification``)."""
    out = {}
    for key, case in cases.items():
        if key.endswith("@grasp"):
            if "amplification" in case:
                out[key[: -len("@grasp")]] = case["passes"]
            continue
        grasp = case.get("gains", {}).get("task_checks", {}).get("grasp", {})
        if "amplification" in grasp.get("values", {}):
            out[key[: -len("@past")] if key.endswith("@past") else key] = grasp["passes"]
    return out


def _run_outcomes(cases: dict) -> dict:
    """Per row key: True when its run (or its run past the refusal) carried the box through
    the circle, False when the run ended failed or diverged, or when the buckling diagnosis
    run (``@buckling``, the task's squeeze) tilted the box past the tilt guard's default, or
    the run to the lift's end (``@lift``) ended failed."""
    out = {}
    for key, case in cases.items():
        if key.endswith("@buckling"):      # the diagnosis run to the lift's end: lost if tilted
            angle = case["runs"]["profile"]["box_angle_max_rad"]
            if angle > math.radians(10.0):          # guards.max_object_tilt_deg's default
                out[key[: -len("@buckling")]] = False
            continue
        if key.endswith("@lift"):          # the run to the lift's end: lost if it failed
            if case["status"] != "ok":
                out[key[: -len("@lift")]] = False
            continue
        base = key[: -len("@past")] if key.endswith("@past") else key
        if case.get("status") in ("failed", "diverged"):     # lost, in the circle or before
            out[base] = False
            continue
        if "verdict" not in case:
            continue
        out[base] = case.get("status") == "ok"
    return out


def test_the_grasp_check_agrees_with_every_run_in_the_file():
    """The simulated truth in the results file: every row whose run carried the box passes the
    grasp's dynamics check, every row whose run (past a refusal) lost it is refused by it."""
    cases = json.loads(RESULTS.read_text())["cases"]
    checks, runs = _grasp_checks(cases), _run_outcomes(cases)
    both = sorted(set(checks) & set(runs))
    assert {"ur3", "z1", "jaco2", "jaco2@sqfriction"} <= set(both), both
    wrong = {k: (checks[k], runs[k]) for k in both if checks[k] != runs[k]}
    assert wrong == {}
