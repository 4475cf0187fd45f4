"""Metrics against closed forms, per phase boundary, with non-finite samples."""

from __future__ import annotations

import json

import numpy as np
import pytest

from drake_coop.results import compute_metrics, write_metrics
from drake_coop.results.metrics import phase_masks
from tests.results.test_io import (
    FORCE_OFFSET,
    PHASES,
    SINE_AMPLITUDE,
    Y_OFFSET,
    Z_OBS,
    synthetic_run,
)

ERRORS = {"x_tilde": "m", "y_tilde": "m", "z_tilde": "m", "force_error": "N",
          "estimate_error": "N", "aux_force_error": "N", "z1": "rad", "z2": "rad", "z3": "rad"}


@pytest.fixture(scope="module")
def full():
    logs, meta = synthetic_run()
    return logs, meta, compute_metrics(logs, meta)


def test_every_error_of_every_phase_is_reported_with_its_unit(full):
    _, _, m = full
    assert set(m) == {"robot1", "robot2"}
    for robot in m:
        assert list(m[robot]) == ["free", "lift", "circle", "put_down", "return", "all"]
        for entry in m[robot].values():
            assert {k: v["unit"] for k, v in entry.items() if isinstance(v, dict)} == ERRORS
            assert entry["n_nonfinite"] == 0
            for k in ERRORS:
                assert set(entry[k]) == {"rms", "max", "unit"}
                assert type(entry[k]["rms"]) is float and type(entry[k]["max"]) is float


def test_phase_boundaries_are_half_open_except_the_last():
    t = np.array([0.0, 14.999, 15.0, 24.999, 25.0, 64.999, 65.0, 75.0, 89.999, 90.0, 90.001])
    masks = phase_masks(t, PHASES)
    assert [np.flatnonzero(masks[p]).tolist() for p, *_ in PHASES] == [
        [0, 1], [2, 3], [4, 5], [6], [7, 8, 9]]
    assert masks["all"].all()                 # also the sample after the last phase


def test_piecewise_constant_error_gives_each_phase_its_own_value(full):
    logs, _, m = full
    t = logs["robot1"]["t"]
    for robot in ("robot1", "robot2"):
        for phase, offset in FORCE_OFFSET.items():
            e = m[robot][phase]
            # One sample of a neighbouring phase would change the max.
            assert e["force_error"]["max"] == pytest.approx(offset, rel=1e-12)
            assert e["force_error"]["rms"] == pytest.approx(offset, rel=1e-12)
            assert e["aux_force_error"]["max"] == pytest.approx(abs(offset - 0.25), rel=1e-9)
            assert e["estimate_error"]["rms"] == pytest.approx(0.25, rel=1e-12)
    counts = {"free": np.sum(t < 15), "lift": np.sum((t >= 15) & (t < 25)),
              "circle": np.sum((t >= 25) & (t < 65)), "put_down": np.sum((t >= 65) & (t < 75)),
              "return": np.sum(t >= 75)}
    assert {p: m["robot1"][p]["n_samples"] for p in counts} == counts
    assert m["robot1"]["all"]["n_samples"] == t.size == 10001
    overall = np.sqrt(sum(counts[p] * FORCE_OFFSET[p] ** 2 for p in counts) / t.size)
    assert m["robot1"]["all"]["force_error"]["rms"] == pytest.approx(overall, rel=1e-12)
    assert m["robot1"]["all"]["force_error"]["max"] == pytest.approx(0.5, rel=1e-12)


def test_sine_over_whole_periods_has_rms_amplitude_over_root_two(full):
    _, _, m = full
    circle = m["robot2"]["circle"]["z_tilde"]
    assert circle["rms"] == pytest.approx(SINE_AMPLITUDE / np.sqrt(2), rel=1e-4)
    assert circle["max"] == pytest.approx(SINE_AMPLITUDE, rel=1e-3)
    assert circle["max"] <= SINE_AMPLITUDE * (1 + 1e-9)
    assert m["robot2"]["lift"]["z_tilde"] == {"rms": 0.0, "max": 0.0, "unit": "m"}


def test_constant_offsets_have_rms_and_max_equal_to_their_size(full):
    _, _, m = full
    for phase in ("free", "circle", "all"):
        e = m["robot1"][phase]
        assert e["y_tilde"]["rms"] == pytest.approx(abs(Y_OFFSET), rel=1e-9)
        assert e["y_tilde"]["max"] == pytest.approx(abs(Y_OFFSET), rel=1e-9)
        assert e["x_tilde"] == {"rms": 0.0, "max": 0.0, "unit": "m"}
        for j, z in enumerate(Z_OBS):
            assert e[f"z{j + 1}"]["rms"] == pytest.approx(abs(z), rel=1e-6)
            assert e[f"z{j + 1}"]["max"] == pytest.approx(abs(z), rel=1e-6)


def test_non_finite_samples_are_skipped_and_counted_and_late_phases_omitted():
    logs, meta = synthetic_run(t_end=20.0)
    log = logs["robot1"]
    n = log["t"].size
    log["lambda_meas"][-3:] = np.nan            # the run diverged: three rows of NaN ...
    log["x"][-5:-1, 1] = np.inf                 # ... overlapping four rows of inf
    m = compute_metrics(logs, meta)
    lift = m["robot1"]["lift"]
    assert lift["n_nonfinite"] == 5             # rows -5 .. -1, counted once each
    assert m["robot1"]["all"]["n_nonfinite"] == 5
    assert m["robot1"]["free"]["n_nonfinite"] == 0 and m["robot2"]["lift"]["n_nonfinite"] == 0
    assert lift["force_error"]["max"] == pytest.approx(FORCE_OFFSET["lift"], rel=1e-12)
    assert lift["estimate_error"]["rms"] == pytest.approx(0.25, rel=1e-12)
    assert lift["y_tilde"]["rms"] == pytest.approx(abs(Y_OFFSET), rel=1e-9)
    assert lift["z1"]["max"] == pytest.approx(Z_OBS[0], rel=1e-6)   # q is finite throughout
    assert lift["n_samples"] == int(np.sum(log["t"] >= 15.0)) and n == 2223
    assert list(m["robot1"]) == ["free", "lift", "all"]   # stopped before the circle


def test_an_error_without_finite_samples_is_left_out():
    logs, meta = synthetic_run(t_end=20.0)
    logs["robot1"]["lambda_hat"][logs["robot1"]["t"] >= 15.0] = np.nan
    lift = compute_metrics(logs, meta)["robot1"]["lift"]
    assert "estimate_error" not in lift and "aux_force_error" not in lift
    assert lift["force_error"]["rms"] == pytest.approx(FORCE_OFFSET["lift"], rel=1e-12)
    assert lift["n_nonfinite"] == lift["n_samples"]


def test_huge_finite_errors_do_not_overflow_the_rms():
    logs, meta = synthetic_run(t_end=1.0)
    logs["robot1"]["lambda_meas"] = logs["robot1"]["lambda_d"] + 1e200
    e = compute_metrics(logs, meta)["robot1"]["free"]["force_error"]
    assert e["rms"] == pytest.approx(1e200, rel=1e-12) and e["max"] == pytest.approx(1e200)


def test_write_metrics_writes_plain_json_numbers(tmp_path):
    logs, meta = synthetic_run(t_end=20.0)
    logs["robot2"]["lambda_meas"][-2:] = np.nan
    m = compute_metrics(logs, meta)
    path = write_metrics(tmp_path, m)
    assert path == tmp_path / "metrics.json"
    text = path.read_text()
    assert json.loads(text) == m
    assert "NaN" not in text and text.startswith('{\n  "robot1": {\n    "free": {')
    assert json.loads(text)["robot2"]["lift"]["n_nonfinite"] == 2


def test_write_metrics_refuses_nan_and_keeps_the_old_file(tmp_path):
    write_metrics(tmp_path, {"robot1": {}})
    with pytest.raises(ValueError):
        write_metrics(tmp_path, {"robot1": {"all": {"force_error": {"rms": float("nan")}}}})
    assert json.loads((tmp_path / "metrics.json").read_text()) == {"robot1": {}}
    assert [p.name for p in tmp_path.iterdir()] == ["metrics.json"]
