"""``bench.unseen_arms``: the lab-arm bars as stated (0.3 N, 0.5 mm, 0.3°, no
slip, no drop, 5 % of the mass), applied to the worst arm of a case."""

import math

import pytest

from bench.unseen_arms import BARS, verdicts


def _robot(squeeze, box, turn, slips=0, drops=0):
    return {"squeeze_error_rms_N": squeeze, "object_position_error_rms": box,
            "object_turn_rms": turn, "slips": slips, "drops": drops}


def test_the_bars_are_the_stated_ones():
    assert BARS["squeeze_error_rms_N"] == 0.3
    assert BARS["object_position_error_rms_m"] == 0.5e-3
    assert math.degrees(BARS["object_turn_rms_rad"]) == pytest.approx(0.3, rel=1e-12)
    assert BARS["mass_error_at_lift_end"] == 0.05


def test_the_worst_arm_decides_and_a_negative_turn_counts_by_its_size():
    case = {"robots": {"a": _robot(0.1, 0.2e-3, 1e-3), "b": _robot(0.31, 0.1e-3, -6e-3)},
            "mass_error_at_lift_end": -0.049}
    v = verdicts(case)
    assert v["squeeze_error_rms_N"] == {"value": 0.31, "bar": 0.3, "passes": False}
    assert v["object_position_error_rms_m"]["passes"] is True
    assert v["object_turn_rms_rad"]["value"] == 6e-3 and v["object_turn_rms_rad"]["passes"] is False
    assert v["mass_error_at_lift_end"]["passes"] is True
    case["robots"]["a"]["slips"] = 1
    assert verdicts(case)["slips"] == {"value": 1, "bar": 0, "passes": False}
    del case["mass_error_at_lift_end"]                # no estimate: not a pass
    assert verdicts(case)["mass_error_at_lift_end"]["passes"] is False
