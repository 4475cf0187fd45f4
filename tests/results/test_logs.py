"""``run.json`` holds rounded numbers: a period aligned in floating point is written as 0.009."""

from __future__ import annotations

import json

import numpy as np

from drake_coop.results.logs import load_logs, save_logs
from tests.results.test_io import synthetic_run


def test_run_json_numbers_are_rounded_to_12_significant_digits(tmp_path):
    logs, meta = synthetic_run(t_end=2.0, h=0.03)
    h = 9 * 0.001
    meta = {**meta, "control_period": 0.009000000000000008, "t_end": 90.00000000000009,
            "gains": {"K_R": np.array([120.0, 120.0, 1 / 3])}}
    assert h != 0.009 or meta["control_period"] != 0.009
    save_logs(tmp_path, logs, meta)
    text = (tmp_path / "run.json").read_text()
    assert "0.009000000000000008" not in text and "90.00000000000009" not in text
    doc = json.loads(text)
    assert doc["control_period"] == 0.009 and doc["t_end"] == 90.0
    assert doc["gains"]["K_R"] == [120.0, 120.0, 0.333333333333]
    assert doc["phases"] == [list(p) for p in meta["phases"]]
    _, read = load_logs(tmp_path)
    assert read["control_period"] == 0.009
