"""The held-out checks of back-calculation (``bench/reference_table_saturation_heldout.py``):
its draws are the original bench's, its summary reads hand-made draws as computed by hand,
and its results file is strict JSON with every pre-declared case."""

import json
from pathlib import Path

import numpy as np
import pytest

from bench.reference_table_saturation_heldout import (
    BAR, CASES, ELBOW, draw_limit, nominal_limit, run_case_draw, run_name, summarize_case)

ROOT = Path(__file__).resolve().parents[2]
ORIGINAL = ROOT / "docs/results/reference_table_saturation.json"
RESULTS = ROOT / "docs/results/reference_table_saturation_heldout.json"


def test_the_draws_limits_are_the_original_benchs():
    """Paired with the original file's draws: the same limit per draw, to the bit."""
    original = json.loads(ORIGINAL.read_text())["draws"]
    for d in original:
        assert draw_limit(ELBOW, d["draw"]) == d["elbow_limit"]
    assert draw_limit(10.0, 0) != draw_limit(10.0, 1)


def test_a_joints_nominal_limit_is_at_the_elbows_ratio():
    assert nominal_limit(11.686, 11.686) == pytest.approx(11.5)
    assert nominal_limit(23.81, 11.686) == pytest.approx(23.81 * 11.5 / 11.686)


def test_run_names():
    assert run_name(1.0) == "residual_bc"
    assert run_name(0.5) == "residual_bc_x0p5" and run_name(2.0) == "residual_bc_x2"


def test_a_draw_refuses_an_original_record_of_another_limit():
    record = {"elbow_limit": 11.0, "residual": {}, "residual_bc": {}}
    with pytest.raises(ValueError, match="draw 0: the original file's limit"):
        run_case_draw(CASES["elbow_gains"], ELBOW, 2, 0, 0.05, record)


def _run(squeeze, status="ok"):
    if status != "ok":
        return {"status": status, "message": "grasp lost at 4.1 s"}
    return {"status": "ok", "message": "completed 8 s", "squeeze_circle": squeeze,
            "DF_lift_end": 10 * squeeze}


def test_the_summary_of_hand_made_draws():
    """Free squeeze 0.5: the residual at 2× and 3× it, back-calculation at 0.4–0.5× with one
    draw lost; every ratio hand-computed."""
    free = {"squeeze_circle": 0.5}
    bc = [0.2, 0.25, 0.225, None]
    draws = [{"draw": k, "limit": 11.0 + k, "residual": _run(1.0 + 0.5 * (k % 2)),
              "residual_bc": _run(bc[k], "ok" if bc[k] else "diverged")} for k in range(4)]
    out = summarize_case(draws, free)
    assert out["n"] == 4
    res = out["residual"]
    assert res["completed"] == 4 and res["lost"] == []
    assert res["squeeze_circle_over_free"]["median"] == pytest.approx(2.5)
    assert res["squeeze_circle_over_free"]["max"] == pytest.approx(3.0)
    assert res["squeeze_circle_over_free"]["worst_draw"] == 1
    assert res["meets_bar"] is False
    assert res["DF_lift_end"] == pytest.approx(12.5)
    back = out["residual_bc"]
    assert back["completed"] == 3
    assert back["lost"] == [{"draw": 3, "limit": 14.0, "message": "grasp lost at 4.1 s"}]
    ratio = back["squeeze_circle_over_free"]
    assert ratio["median"] == pytest.approx(0.45) and ratio["min"] == pytest.approx(0.4)
    assert ratio["max"] == pytest.approx(0.5) and ratio["worst_draw"] == 1
    assert ratio["low"] <= ratio["median"] <= ratio["high"] <= BAR
    assert back["meets_bar"] is False           # within the bar, but a draw lost its grasp
    draws[3]["residual_bc"] = _run(0.2)
    assert summarize_case(draws, free)["residual_bc"]["meets_bar"] is True


def test_a_case_whose_every_draw_lost_the_grasp_has_no_ratio():
    draws = [{"draw": 0, "limit": 9.0, "residual": _run(None, "diverged")}]
    out = summarize_case(draws, {"squeeze_circle": 0.5})["residual"]
    assert out["completed"] == 0 and out["squeeze_circle_over_free"] is None
    assert out["meets_bar"] is False


def _refuse(constant):
    raise ValueError(f"not strict JSON: {constant}")


def test_the_results_file_is_strict_json_with_every_case():
    data = json.loads(RESULTS.read_text(), parse_constant=_refuse)
    assert set(data["cases"]) == set(CASES) and data["bar"] == BAR
    for name, case in data["cases"].items():
        if case["nominal"] is None:                 # no depth held: no draws (below)
            assert case["draws"] == [] and case["summary"] == {"n": 0}
            continue
        assert case["summary"]["n"] == len(case["draws"]) == data["draws"] == 20, name
        runs = ["residual"] + [run_name(m) for m in CASES[name]["gains"]]
        for run in runs:
            entry = case["summary"][run]
            assert entry["completed"] + len(entry["lost"]) == 20
            ratio = entry["squeeze_circle_over_free"]
            assert ratio["low"] <= ratio["median"] <= ratio["high"]
            assert entry["meets_bar"] == (ratio["high"] <= BAR and not entry["lost"])
        # The limit is below the joint's unsaturated lift peak, as the original elbow's
        # (11.5 N·m against 11.69), and each draw's within ±2 % of the nominal.
        assert case["nominal"] < case["lift_peak"]
        scale = np.array([d["limit"] for d in case["draws"]]) / case["nominal"]
        assert np.all(scale >= 0.98) and np.all(scale <= 1.02)


def test_the_depth_scans_stop_where_the_grasp_is_lost():
    deep = json.loads(RESULTS.read_text())["cases"]["elbow_deep"]
    for scan in ("depth", "depth_fine"):
        if scan not in deep:
            continue
        last = deep[scan]["scan"][-1]
        assert any(v["status"] != "ok" for k, v in last.items() if k != "nominal")
        assert all(v["status"] == "ok" for step in deep[scan]["scan"][:-1]
                   for k, v in step.items() if k != "nominal")
    if deep["nominal"] is None:
        # The edge lies below the original draws' lowest limit, which both laws held.
        original = json.loads(ORIGINAL.read_text())["draws"]
        edge = deep["edge"]
        assert edge["low"] < edge["high"] <= min(d["elbow_limit"] for d in original)
        assert edge["high"] - edge["low"] <= 0.004


def test_the_diagnosis_reproduces_the_draws_runs():
    """The diagnosis reruns each draw's residual with (6) and with back-calculation at k_F:
    the same numbers as the draw's record, to the bit (the runs are deterministic)."""
    data = json.loads(RESULTS.read_text())
    diagnosed = [c for c in data["cases"].values() if "diagnosis" in c]
    assert diagnosed
    for case in diagnosed:
        for run in case["diagnosis"]["runs"]:
            if run["loop"] != "residual" or run["scheme"] not in (None, "back_calculation") \
                    or run["gain_over_k_F"] not in (None, 1.0):
                continue
            stored = case["draws"][run["draw"]]["residual" if run["scheme"] is None
                                               else "residual_bc"]
            assert run["status"] == stored["status"]
            if run["status"] == "ok":
                assert run["squeeze_circle"] == stored["squeeze_circle"]
                assert run["DF_lift_end"] == stored["DF_lift_end"]
