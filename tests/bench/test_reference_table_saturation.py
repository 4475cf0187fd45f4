"""The saturation bench (``bench/reference_table_saturation.py``): its results file is strict
JSON, its summary leaves undefined numbers null, and (slow) the anti-windup of (6) on the
simulated truth of a saturated lift."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from bench.reference_table_saturation import PAIRED, RUNS, measure, summarize

RESULTS = Path(__file__).resolve().parents[2] / "docs/results/reference_table_saturation.json"


def _refuse(constant):
    raise ValueError(f"not strict JSON: {constant}")


def test_the_results_file_is_strict_json_with_every_run():
    data = json.loads(RESULTS.read_text(), parse_constant=_refuse)
    summary = data["summary"]
    assert summary["n"] == len(data["draws"]) >= 8
    for run in RUNS:
        assert summary[run]["completed"] == summary["n"]
    for run in PAIRED:
        for tail in ("_aw", "_bc"):
            interval = summary[f"{run}{tail}_over_free"]["squeeze_circle_interval"]
            assert interval["low"] <= interval["median"] <= interval["high"]
    # The diagnosis: the sweep's runs (a lost grasp kept with its message) and its line
    # through those that finished.
    sweep = data["sweep"]
    failed = [run for run in sweep["runs"] if run["status"] != "ok"]
    assert sweep["failed"] == len(failed) and all(run["message"] for run in failed)
    assert sweep["runs"][0]["status"] == "ok" and sweep["runs"][0]["draw"] is None
    fit = sweep["fit"]
    assert fit["n"] == len(sweep["runs"]) - len(failed)
    assert fit["a_over_k_F"] == pytest.approx(fit["a"] / fit["k_F"])


def _run(squeeze, saturated=None):
    numbers = {k: squeeze for k in ("squeeze_circle", "estimate_circle", "squeeze_lift",
                                    "estimate_lift", "DF_lift_end")}
    return {"status": "ok", **numbers, "estimate_saturated": saturated}


def test_the_summary_of_draws_with_undefined_numbers_is_strict():
    free = _run(1.0)
    draws = [{"draw": k, "elbow_limit": 11.5, "free_over_saturated": None,
              **{run: _run(2.0 + k) for run in RUNS}} for k in range(3)]
    summary = summarize(draws, free)
    text = json.dumps(summary, allow_nan=False)         # raises on NaN
    assert summary["momentum"]["estimate_saturated"] is None
    assert summary["residual_aw_over_residual"]["squeeze_circle"]["median"] == 1.0
    # The sensor runs are paired with the draw's unsaturated sensor run: (2 + k) / (2 + k).
    assert summary["sensor_over_free"]["squeeze_circle"]["median"] == 1.0
    assert summary["residual_over_free"]["squeeze_circle"]["median"] == 3.0
    assert "NaN" not in text and not math.isnan(
        summary["residual_over_free"]["squeeze_circle_interval"]["low"])


@pytest.mark.slow
@pytest.mark.parametrize("row, noise, variant", [("momentum", None, "applied_torque"),
                                                  ("sensor", 0.3, None)])
def test_anti_windup_recovers_the_squeeze_after_a_saturated_lift(row, noise, variant):
    """Robot 1's elbow limited at 11.28 N·m (the bench's draw 3): saturated on the approach
    and most of the lift. With the option ΔF̃ (rebuilt from the logs by (6), held on the
    clipped ticks) ends the lift smaller, and the squeeze error over the circle is no larger
    than without it."""
    limit = 11.5 * float(np.random.default_rng([1, 3]).uniform(0.98, 1.02))
    plain = measure(row, noise, limit, variant, 3)
    held = measure(row, noise, limit, variant, 3, anti_windup=True)
    assert plain["status"] == held["status"] == "ok"
    assert plain["saturated_ticks"] > 100 and held["saturated_ticks"] > 100
    assert held["DF_lift_end"] < plain["DF_lift_end"]
    assert held["squeeze_circle"] <= plain["squeeze_circle"]


@pytest.mark.slow
def test_back_calculation_drives_the_command_back_to_the_limit_on_the_simulated_lift():
    """Robot 1's elbow limited as in the bench's draw 0, the applied-torque residual: with
    back-calculation at K_aw = 10 1/s the commanded torque's excess over the applied one
    (the plant's, after Drake's saturation) over the saturated ticks after the grasp is
    at most half of that with the paper's (6)."""
    limit = 11.5 * float(np.random.default_rng([1, 0]).uniform(0.98, 1.02))
    plain = measure("momentum", None, limit, "applied_torque", 0)
    back = measure("momentum", None, limit, "applied_torque", 0,
                   anti_windup="back_calculation", gain=10.0)
    assert plain["status"] == back["status"] == "ok"
    assert plain["saturated_ticks"] > 100 and back["saturated_ticks"] > 0
    assert back["excess_saturated"] < 0.5 * plain["excess_saturated"]
