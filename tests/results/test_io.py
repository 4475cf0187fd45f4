"""Atomic writes and the log files: bit-exact round trips, errors that name the file."""

from __future__ import annotations

import json
import os
import zipfile

import numpy as np
import pytest

from drake_coop.results import load_logs, save_logs
from drake_coop.results.io import atomic_path, atomic_write_bytes, atomic_write_text
from drake_coop.results.logs import COLUMNS

H = 0.009
PHASES = [["free", 0.0, 15.0], ["lift", 15.0, 25.0], ["circle", 25.0, 65.0],
          ["put_down", 65.0, 75.0], ["return", 75.0, 90.0]]
ROBOTS = ["robot1", "robot2"]
FORCE_OFFSET = {"free": 0.1, "lift": 0.2, "circle": 0.3, "put_down": 0.4, "return": 0.5}
"""λ − λ_d, constant in each phase."""
SINE_AMPLITUDE = 2e-3   # z̃ in the circle phase: 20 periods of 2 s
Y_OFFSET = -1.5e-3      # ỹ everywhere
Z_OBS = (1e-6, -2e-6, 3e-6)


def synthetic_run(t_end: float = 90.0, h: float = H) -> tuple[dict, dict]:
    """Logs with errors of known RMS and max per phase (see the constants above)."""
    t = h * np.arange(int(round(t_end / h)) + 1)
    n = t.size
    rng = np.random.default_rng(1)
    circle = (t >= 25.0) & (t < 65.0)
    offset = np.zeros(n)
    for name, a, b in PHASES:
        offset[(t >= a) & ((t < b) if name != "return" else (t <= b))] = FORCE_OFFSET[name]
    logs = {}
    for k, robot in enumerate(ROBOTS):
        q_d = rng.normal(size=(n, 3))
        x_d = rng.normal(size=(n, 3))
        x = x_d.copy()
        x[:, 1] += Y_OFFSET
        x[:, 2] += np.where(circle, SINE_AMPLITUDE * np.sin(np.pi * (t - 25.0)), 0.0)
        lam_d = 20.0 + 5.0 * np.sin(0.3 * t) + k
        lam = lam_d + offset
        F_meas = rng.normal(size=(n, 3))
        F_meas[:, 0] = (-1.0) ** (k + 1) * lam        # λ = s_i F_x, s_1 = −1, s_2 = +1
        logs[robot] = {
            "t": t.copy(), "q": q_d + np.array(Z_OBS), "q_hat": q_d.copy(), "q_d": q_d,
            "x": x, "x_d": x_d, "F_meas": F_meas, "lambda_meas": lam,
            "lambda_hat": lam - 0.25, "lambda_d": lam_d, "tau": rng.normal(size=(n, 3)),
        }
    meta = {"phases": PHASES, "robots": list(ROBOTS), "status": "ok", "message": "done",
            "scenario_yaml": "task:\n  t_end: 90.0\n"}
    return logs, meta


def bits(a: np.ndarray) -> np.ndarray:
    """The IEEE-754 bit patterns of a float64 array (distinguishes -0.0, NaN payloads)."""
    return np.ascontiguousarray(a, dtype=np.float64).view(np.uint64)


def awkward_run() -> tuple[dict, dict]:
    """A short run whose values test the text round trip: subnormals, -0.0, NaN, inf."""
    logs, meta = synthetic_run(t_end=0.09)
    tricky = np.array([0.1, 1 / 3, -0.0, 5e-324, 1.7976931348623157e308, np.nan, -np.inf,
                       np.pi * 1e-17, 2.0 ** -1074 * 3, 123456789.123456789, np.inf])
    log = logs["robot1"]
    log["F_meas"][:, 0] = tricky
    log["lambda_hat"][:] = tricky[::-1]
    return logs, meta


# --- atomic writes ---------------------------------------------------------------------------

def test_atomic_writes_create_and_replace_the_whole_file(tmp_path):
    target = tmp_path / "sub" / "a.bin"
    assert atomic_write_bytes(target, b"\x00\x01old") == target
    atomic_write_bytes(target, b"new content")
    assert target.read_bytes() == b"new content"
    atomic_write_text(tmp_path / "t.txt", "λ = 20 N\n")
    assert (tmp_path / "t.txt").read_bytes() == "λ = 20 N\n".encode("utf-8")
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["a.bin", "sub", "t.txt"]


def test_atomic_path_is_a_temporary_beside_the_target_with_the_usual_mode(tmp_path):
    target = tmp_path / "out.txt"
    umask = os.umask(0o022)
    try:
        with atomic_path(target) as tmp:
            assert tmp.parent == tmp_path and tmp != target and tmp.exists()
            assert not target.exists()            # nothing visible until the block ends
            tmp.write_text("done")
    finally:
        os.umask(umask)
    assert target.read_text() == "done"
    assert target.stat().st_mode & 0o777 == 0o644
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_failed_block_keeps_the_old_file_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "out.txt"
    atomic_write_text(target, "old")
    with pytest.raises(RuntimeError, match="disk full"):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("disk full")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_failed_block_without_an_old_file_leaves_nothing(tmp_path):
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(tmp_path / "new.txt") as tmp:
            tmp.write_text("half")
            raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


# --- logs ------------------------------------------------------------------------------------

def test_save_writes_npz_csv_and_json_and_loads_back_bit_exact(tmp_path):
    logs, meta = awkward_run()
    paths = save_logs(tmp_path, logs, meta)
    assert [p.name for p in paths] == ["robot1.npz", "robot1.csv", "robot2.npz", "robot2.csv",
                                       "run.json"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths)
    back, meta_back = load_logs(tmp_path)
    assert meta_back == meta
    assert json.loads((tmp_path / "run.json").read_text()) == meta
    for robot, log in logs.items():
        assert set(back[robot]) == set(COLUMNS)
        for key in COLUMNS:
            assert back[robot][key].shape == log[key].shape
            np.testing.assert_array_equal(bits(back[robot][key]), bits(log[key]))


def test_csv_has_the_documented_header_and_round_trips_to_the_last_bit(tmp_path):
    logs, meta = awkward_run()
    save_logs(tmp_path, logs, meta)
    lines = (tmp_path / "robot1.csv").read_text().splitlines()
    assert lines[0] == ("t,q1,q2,q3,q_hat1,q_hat2,q_hat3,q_d1,q_d2,q_d3,x,y,z,x_d,y_d,z_d,"
                        "Fx,Fy,Fz,lambda_meas,lambda_hat,lambda_d,tau1,tau2,tau3")
    assert len(lines) == 1 + 11
    table = np.loadtxt(tmp_path / "robot1.csv", delimiter=",", skiprows=1)
    assert table.shape == (11, 25)
    log = logs["robot1"]
    columns = lines[0].split(",")
    expected = {"t": log["t"], "q_hat2": log["q_hat"][:, 1], "z_d": log["x_d"][:, 2],
                "Fx": log["F_meas"][:, 0], "lambda_hat": log["lambda_hat"],
                "tau3": log["tau"][:, 2]}
    for name, values in expected.items():
        np.testing.assert_array_equal(bits(table[:, columns.index(name)]), bits(values))
    whole = np.hstack([log[k].reshape(11, -1) for k in COLUMNS])
    np.testing.assert_array_equal(bits(table), bits(whole))


def test_extra_arrays_are_kept_in_the_npz_and_numpy_metadata_becomes_json(tmp_path):
    logs, meta = synthetic_run(t_end=0.05)
    logs["robot2"]["extra"] = np.arange(6, dtype=np.int32)
    meta = {**meta, "control_period": np.float64(0.009), "n_steps": np.int64(7),
            "gains": np.array([1.5, 2.0])}
    save_logs(tmp_path, logs, meta)
    back, meta_back = load_logs(tmp_path)
    np.testing.assert_array_equal(back["robot2"]["extra"], np.arange(6))
    assert back["robot2"]["extra"].dtype == np.int32
    assert (meta_back["control_period"], meta_back["n_steps"], meta_back["gains"]) == (
        0.009, 7, [1.5, 2.0])
    assert "extra" not in (tmp_path / "robot2.csv").read_text().splitlines()[0]


@pytest.mark.parametrize("change, message", [
    (lambda log: log.pop("lambda_hat"), "lacks arrays \\['lambda_hat'\\]"),
    (lambda log: log.update(q=log["q"][:-1]), "'q' has shape"),
    (lambda log: log.update(tau=log["tau"][:, :2]), "'tau' has shape"),
    (lambda log: log.update(note=np.array([{"a": 1}], dtype=object)), "Python objects"),
], ids=["missing", "short", "narrow", "object"])
def test_bad_logs_are_refused_before_anything_is_written(tmp_path, change, message):
    logs, meta = synthetic_run(t_end=0.05)
    change(logs["robot2"])
    with pytest.raises(ValueError, match=message):
        save_logs(tmp_path, logs, meta)
    assert list(tmp_path.iterdir()) == []


def test_missing_files_are_named(tmp_path):
    with pytest.raises(FileNotFoundError, match="run.json"):
        load_logs(tmp_path)
    logs, meta = synthetic_run(t_end=0.05)
    save_logs(tmp_path, logs, meta)
    (tmp_path / "robot2.npz").unlink()
    with pytest.raises(FileNotFoundError, match="robot2.npz"):
        load_logs(tmp_path)


@pytest.mark.parametrize("corrupt, message", [
    (lambda d: (d / "run.json").write_text("{not json"), "run.json is not valid JSON"),
    (lambda d: (d / "run.json").write_text("[1, 2]"), "run.json must hold a JSON object"),
    (lambda d: (d / "run.json").write_text('{"robots": "robot1", "phases": []}'),
     "run.json: 'robots'"),
    (lambda d: (d / "run.json").write_text('{"robots": ["robot1", "robot2"], "phases": 3}'),
     "run.json: 'phases'"),
    (lambda d: (d / "robot1.npz").write_bytes(b"PK\x03\x04 truncated"),
     "robot1.npz is not a valid log"),
    (lambda d: (d / "robot1.npz").write_bytes((d / "robot1.npz").read_bytes()[:500]),
     "robot1.npz is not a valid log"),
], ids=["json", "not-object", "robots", "phases", "garbage-npz", "truncated-npz"])
def test_malformed_files_are_named(tmp_path, corrupt, message):
    logs, meta = synthetic_run(t_end=0.05)
    save_logs(tmp_path, logs, meta)
    corrupt(tmp_path)
    with pytest.raises(ValueError, match=message):
        load_logs(tmp_path)


def test_npz_lacking_an_array_is_named(tmp_path):
    logs, meta = synthetic_run(t_end=0.05)
    save_logs(tmp_path, logs, meta)
    with zipfile.ZipFile(tmp_path / "robot1.npz", "w") as z:   # rewrite without "tau"
        for key in COLUMNS:
            if key != "tau":
                with z.open(f"{key}.npy", "w") as f:
                    np.lib.format.write_array(f, logs["robot1"][key])
    with pytest.raises(ValueError, match="robot1.npz lacks arrays \\['tau'\\]"):
        load_logs(tmp_path)
