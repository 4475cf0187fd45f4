"""Golden test: the paper's run, with every optional scenario field at its default, is the
run that was checked independently (``tests/golden/paper_run.json``, kept as recorded).

The rule is a physical tolerance, not bit-exactness: faster but mathematically
equivalent code (closed-form kinematics, one inverse-dynamics call, other operation orders)
moves the last bits of the torques, and SAP's iterative solve carries those bits through the
90 s run. What must not move is the result:

* the circle-phase metrics within **1e-6 relative** of the record (units exactly);
* the raw logs (every 30th sample) within **1e-6 of each signal's largest magnitude** over the
  run (joint angles ~1 rad: 1 µrad; forces ~10 N: 10 µN; torques ~10 N·m: 10 µN·m). That is
  the metrics' budget applied sample by sample, and it stays well below every physical effect
  the run is about: the sampling errors of the paper's loop (millinewtons, ~1 µrad of
  observation error) and the compliance of SAP's constraint (~7 µm at 1 ms, ~1e-5 rad of
  joint angle). A real change of the loop (a sample of delay, a sign, a gain) moves these
  signals by orders of magnitude more. The sample times must be identical (same grid).
"""

import json
from pathlib import Path

import numpy as np
import pytest

from tests.golden.make_golden import SIGNALS, golden_record

GOLDEN = Path(__file__).parent / "golden" / "paper_run.json"


@pytest.fixture(scope="module")
def fresh_and_golden():
    return golden_record(), json.loads(GOLDEN.read_text())


def _numbers(tree, prefix=""):
    """Flatten nested metrics into ``path -> float`` (units and counts included)."""
    if isinstance(tree, dict):
        out = {}
        for k, v in tree.items():
            out.update(_numbers(v, f"{prefix}.{k}" if prefix else k))
        return out
    return {prefix: tree}


@pytest.mark.slow
def test_paper_run_circle_metrics_stay_within_1e6_relative_of_the_golden_record(fresh_and_golden):
    fresh, golden = fresh_and_golden
    got, want = _numbers(fresh["circle_metrics"]), _numbers(golden["circle_metrics"])
    assert want.keys() <= got.keys()    # metrics added later (velocity_error) are not pinned
    for key, value in want.items():
        if isinstance(value, str):
            assert got[key] == value, key
        else:
            assert got[key] == pytest.approx(value, rel=1e-6, abs=1e-300), key


@pytest.mark.slow
def test_paper_run_logs_stay_within_1e6_of_each_signals_scale(fresh_and_golden):
    fresh, golden = fresh_and_golden
    for robot, want in golden["samples"].items():
        np.testing.assert_array_equal(np.asarray(fresh["samples"][robot]["t"]),
                                      np.asarray(want["t"]), err_msg=f"{robot}.t")
        for key in SIGNALS:
            if key == "t":
                continue
            a, b = np.asarray(fresh["samples"][robot][key]), np.asarray(want[key])
            assert a.shape == b.shape, (robot, key)
            scale = max(np.abs(b).max(), 1e-12)
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-6 * scale,
                                       err_msg=f"{robot}.{key}")
