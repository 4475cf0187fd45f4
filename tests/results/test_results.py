"""Results: atomic files, log round trips, metrics against closed forms, figure files."""

import json

import numpy as np
import pytest

from drake_coop.results import compute_metrics, load_logs, save_logs
from drake_coop.results.io import atomic_path, atomic_write_text
from drake_coop.results.logs import COLUMNS

PHASES = [["free", 0.0, 15.0], ["lift", 15.0, 25.0], ["circle", 25.0, 65.0],
          ["put_down", 65.0, 75.0], ["return", 75.0, 90.0]]


def synthetic_logs(t_end=90.0, h=0.009):
    t = np.arange(0.0, t_end + 1e-9, h)
    n = t.size
    rng = np.random.default_rng(0)
    logs = {}
    for robot in ("robot1", "robot2"):
        q_d = rng.normal(size=(n, 3))
        x_d = rng.normal(size=(n, 3))
        x = x_d.copy()
        x[:, 0] += 1e-3 * np.sin(2 * np.pi * t)          # x̃: amplitude 1 mm, 1 Hz
        x[:, 2] += 2e-3                                   # z̃: constant offset
        lam_d = np.where((t >= 15) & (t <= 75), 20.0, 0.0)
        logs[robot] = dict(t=t, q=q_d + 1e-6, q_hat=q_d.copy(), q_d=q_d, x=x, x_d=x_d,
                           F_meas=rng.normal(size=(n, 3)), lambda_meas=lam_d + 0.5,
                           lambda_hat=lam_d + 0.25, lambda_d=lam_d, tau=rng.normal(size=(n, 3)))
    meta = {"phases": PHASES, "robots": ["robot1", "robot2"], "status": "ok", "message": "",
            "scenario_yaml": ""}
    return logs, meta


def test_atomic_write_leaves_old_file_and_no_temp_on_failure(tmp_path):
    target = tmp_path / "out.txt"
    atomic_write_text(target, "old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("disk full")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]


def test_logs_round_trip_bit_exact_in_npz_and_csv(tmp_path):
    logs, meta = synthetic_logs(t_end=2.0)
    save_logs(tmp_path, logs, meta)
    back, meta_back = load_logs(tmp_path)
    assert meta_back == meta
    for robot, log in logs.items():
        for key in COLUMNS:
            np.testing.assert_array_equal(back[robot][key], log[key])
        table = np.loadtxt(tmp_path / f"{robot}.csv", delimiter=",", skiprows=1)
        np.testing.assert_array_equal(table[:, 0], log["t"])
        np.testing.assert_array_equal(table[:, 1:4], log["q"])
        np.testing.assert_array_equal(table[:, -3:], log["tau"])


def test_loading_a_directory_without_logs_names_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="run.json"):
        load_logs(tmp_path)
    # A run.json whose phases are valid (they are checked before any log is read) and whose
    # robot has no log file.
    (tmp_path / "run.json").write_text(json.dumps({"robots": ["robot1"],
                                                   "phases": [["free", 0.0, 1.0]]}))
    with pytest.raises(FileNotFoundError, match="robot1.npz"):
        load_logs(tmp_path)


def test_metrics_match_closed_forms_per_phase():
    logs, meta = synthetic_logs()
    m = compute_metrics(logs, meta)
    circle = m["robot1"]["circle"]
    # A 1 mm sine over whole periods has RMS 1/√2 mm; its max is 1 mm.
    assert circle["x_tilde"]["rms"] == pytest.approx(1e-3 / np.sqrt(2), rel=1e-3)
    assert circle["x_tilde"]["max"] == pytest.approx(1e-3, rel=1e-4)
    assert circle["z_tilde"]["rms"] == pytest.approx(2e-3) and circle["z_tilde"]["unit"] == "m"
    assert circle["force_error"]["rms"] == pytest.approx(0.5)
    assert circle["estimate_error"]["max"] == pytest.approx(0.25)
    assert circle["aux_force_error"]["rms"] == pytest.approx(0.25)
    assert circle["z2"]["max"] == pytest.approx(1e-6)
    assert set(m["robot2"]) == {"free", "lift", "circle", "put_down", "return", "all"}
    assert m["robot1"]["free"]["n_samples"] == int(np.sum(logs["robot1"]["t"] < 15.0))


def test_metrics_skip_non_finite_samples_and_count_them():
    logs, meta = synthetic_logs(t_end=20.0)
    logs["robot1"]["lambda_meas"][-3:] = np.nan
    m = compute_metrics(logs, meta)
    assert m["robot1"]["lift"]["n_nonfinite"] == 3
    assert np.isfinite(m["robot1"]["lift"]["force_error"]["max"])
    assert "circle" not in m["robot1"]                 # the run ended before the circle


# Every figure as a valid PNG and SVG, of a full run and of one stopped at 20 s: checked (with
# the PNGs' exact sizes and the panels) by tests/results/test_figures.py's
# test_full_run_draws_every_figure_with_its_panels and
# test_run_stopped_at_20s_is_replotted_from_its_logs; a test here drew the same figures again.


def test_diagram_without_graphviz_still_writes_the_dot_and_says_so(tmp_path, monkeypatch):
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    from drake_coop.results import export

    b = DiagramBuilder()
    b.AddNamedSystem("source", ConstantVectorSource([1.0]))
    diagram = b.Build()
    monkeypatch.setattr(export.shutil, "which", lambda name: None)
    with pytest.warns(UserWarning, match="graphviz"):
        files = export.write_diagram(diagram, tmp_path, "d")
    assert files["svg"] is None and "source" in files["dot"].read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.dot"]


def test_progress_bar_reports_simulated_time_and_realtime_factor():
    import io

    from drake_coop.cli import ProgressBar

    stream = io.StringIO()
    bar = ProgressBar(stream)
    for t in (9.0, 45.0, 90.0):
        bar(t, 90.0, t / 6.0)
    lines = stream.getvalue().splitlines()
    assert lines[-1].strip().startswith("90.00/90 s") and "realtime x6.00" in lines[-1]
    assert len(lines) == 3
