"""The reference table end to end: 2 draws × 2 cells on a tiny segment, resumed, its numbers
checked against the simulated truth computed here from the logs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from drake_coop.studies.reference_engine import run_table
from drake_coop.studies.reference_table import (
    SEGMENT,
    bootstrap_interval,
    compress,
    expand_table,
)
from drake_coop.scenario.loading import load_scenario

T_TINY = 5.3     # 0.3 s of the circle


def test_bootstrap_interval_against_closed_forms():
    v, lo, hi = bootstrap_interval(np.full(7, 2.5), 0.5)
    assert (v, lo, hi) == (2.5, 2.5, 2.5)           # no spread, no interval
    v, lo, hi = bootstrap_interval(np.array([1.0, 2.0, 3.0, 4.0, 5.0, np.nan]), 0.5)
    assert v == 3.0 and 1.0 <= lo <= 3.0 <= hi <= 5.0   # NaN (did not complete) left out
    assert np.isnan(bootstrap_interval(np.array([np.nan]), 0.9)[0])


def test_draws_are_paired_across_rows_and_differ_across_draws():
    cases = expand_table(load_scenario(), ["observer", "sensor_3"], ["model_30"], 2,
                         t_end=T_TINY)
    scales = {(c.params["row"], c.params["draw"]):
              load_scenario(data=c.scenario_yaml).robots[0].model_error.mass_scale
              for c in cases}
    assert scales[("observer", 0)] == scales[("sensor_3", 0)]
    assert scales[("observer", 1)] == scales[("sensor_3", 1)]
    assert scales[("observer", 0)] != scales[("observer", 1)]
    assert all(0.7 <= s <= 1.3 for s in scales.values())
    task = load_scenario(data=cases[0].scenario_yaml).task
    assert task.t_grasp == SEGMENT["t_grasp"] and task.t_circle_start == SEGMENT["t_circle_start"]


@pytest.mark.parametrize("rows, cols, draws, message", [
    (["nope"], ["exact"], 1, "rows: unknown row 'nope'"),
    (["observer"], ["nope"], 1, "columns: unknown column 'nope'"),
    (["observer"], ["exact"], 0, "draws: must be an integer >= 1"),
    (["observer"], ["saturation"], 1, "columns: saturation needs"),
])
def test_bad_input_is_one_line(rows, cols, draws, message):
    with pytest.raises(ValueError, match=message):
        expand_table(load_scenario(), rows, cols, draws, t_end=T_TINY)


def _circle_rms_from_logs(scenario, t_end):
    """λ − λ_d and λ̂ − λ over the circle, RMS, worst robot, from the logs (not the metrics)."""
    from drake_coop.experiment.simulate import simulate

    result = simulate(scenario, t_end=t_end)
    squeeze, estimate = [], []
    for log in result.logs.values():
        circle = log["t"] >= scenario.task.t_circle_start - 1e-9
        lam, lam_d, lam_hat = (np.asarray(log[k])[circle] for k in
                               ("lambda_meas", "lambda_d", "lambda_hat"))
        squeeze.append(np.sqrt(np.mean((lam - lam_d) ** 2)))
        estimate.append(np.sqrt(np.mean((lam_hat - lam) ** 2)))
    return max(squeeze), max(estimate)


def test_table_end_to_end_resumes_and_matches_the_logs(tmp_path):
    rows, cols = ["observer", "sensor_3"], ["exact"]
    table = run_table(tmp_path, rows=rows, cols=cols, draws=2, t_end=T_TINY, workers=2,
                      batch=2, quiet=True)
    assert table["missing"] == [] and table["finished"] == 4
    files = sorted((tmp_path / "cases").glob("*.json"))
    # the observer under the exact model has nothing random: its two draws are one case
    assert len(files) == 3
    assert table["cells"]["observer"]["exact"]["n"] == 2
    # the numbers against the simulated truth (observer, exact model: deterministic)
    cell = table["cells"]["observer"]["exact"]
    squeeze, estimate = _circle_rms_from_logs(compress(load_scenario()), T_TINY)
    assert cell["squeeze"]["median"][0] == pytest.approx(squeeze, rel=1e-6)
    assert cell["estimate"]["median"][0] == pytest.approx(estimate, rel=1e-6)
    # the sensor's noise differs between draws: its estimate error is about σ = 3 N
    sensor = table["cells"]["sensor_3"]["exact"]["estimate"]["median"][0]
    assert 1.5 < sensor < 4.5
    assert "force observer (22)" in (tmp_path / "table.md").read_text()
    # resumed: nothing runs again, the same table
    mtimes = [f.stat().st_mtime_ns for f in files]
    again = run_table(tmp_path, rows=rows, cols=cols, draws=2, t_end=T_TINY, quiet=True)
    assert [f.stat().st_mtime_ns for f in files] == mtimes
    assert again["cells"] == table["cells"]
    assert json.loads((tmp_path / "table.json").read_text())["cells"] == table["cells"]


@pytest.mark.parametrize("args, message", [
    (["--rows", "bogus"], "rows: unknown name 'bogus'"),
    (["--columns", "exact,nope"], "columns: unknown name 'nope'"),
    (["--rows", "online_prior", "--columns", "exact,open_loop"],
     "columns: open_loop has no case of the optional row 'online_prior'"),
    (["--draws", "0"], "draws: must be an integer >= 1"),
    (["--workers", "0"], "batch and workers: must be >= 1"),
])
def test_command_refuses_bad_input_in_one_line(tmp_path, capsys, args, message):
    from drake_coop.cli.parser import main

    assert main(["reference-table", "--out", str(tmp_path / "t"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err and "Traceback" not in err
    assert not (tmp_path / "t").exists()


def test_every_cell_expands_and_the_saturation_limits_follow_the_peaks():
    """Every row under every column validates as `drake-coop run` validates a scenario; the
    saturation column's limits are 0.9 × the lift's peak × U(0.95, 1.05), never below 1.02 ×
    the peak outside the lift."""
    from drake_coop.studies.reference_table import COLUMNS, ROWS

    peaks = {"robot1": {"lift": [10.0, 20.0, 5.0], "other": [1.0, 30.0, 1.0]},
             "robot2": {"lift": [8.0, 8.0, 8.0], "other": [1.0, 1.0, 1.0]}}
    cases = expand_table(load_scenario(), [r.name for r in ROWS], list(COLUMNS), 2,
                         t_end=T_TINY, peaks=peaks)
    assert len(cases) == len(ROWS) * len(COLUMNS) * 2
    # every case its own, but the applied-torque residual's without torque limits (the
    # momentum row's: the same system), the F/T rows' open-loop cases (their exact ones)
    # and the later draws of the exact model without a sensor (nothing random: one case)
    shared = [c for c in cases if (c.params["row"] == "applied_torque"
                                   and c.params["column"] != "saturation")
              or (c.params["row"].startswith("sensor") and c.params["column"] == "open_loop")
              or (c.params["column"] == "exact" and c.params["draw"] > 0
                  and c.params["row"] not in ("sensor_0p3", "sensor_3", "applied_torque"))]
    assert len({c.hash for c in cases}) == len(cases) - len(shared)
    for case in cases:
        if case.params["column"] != "saturation":
            continue
        limits = load_scenario(data=case.scenario_yaml).robots[0].actuators.torque_limits
        assert 0.9 * 10.0 * 0.95 <= limits[0] <= 0.9 * 10.0 * 1.05
        assert limits[1] == pytest.approx(1.02 * 30.0)       # the peak outside the lift


def test_identified_columns_take_their_models_and_refuse_without(tmp_path):
    """An identified column runs each draw on that draw's identified URDFs (the model error's
    scales reset: the identified model replaces the ±30 % prior); without them, one line."""
    from pathlib import Path

    from drake_coop.studies.reference_table import ALL_COLUMNS, identified_name

    col = identified_name("didim", 5.0)
    assert col in ALL_COLUMNS
    urdf = Path(__file__).resolve().parents[2] / "urdf"
    models = {(col, 0): {"robot1": str(urdf / "crs_a465_3dof.urdf"),
                         "robot2": str(urdf / "crs_a255_3dof.urdf")}}
    (case,) = expand_table(load_scenario(), ["observer"], [col], 1, t_end=T_TINY,
                           models=models)
    robots = load_scenario(data=case.scenario_yaml).robots
    assert [r.controller_model for r in robots] == [models[(col, 0)]["robot1"],
                                                   models[(col, 0)]["robot2"]]
    assert all(r.model_error.mass_scale == 1.0 for r in robots)
    with pytest.raises(ValueError, match=f"columns: {col} needs its identified models"):
        expand_table(load_scenario(), ["observer"], [col], 2, t_end=T_TINY, models=models)


@pytest.mark.slow
@pytest.mark.parametrize("path", ["scenarios/contact.yaml", "scenarios/two_pandas.yaml"])
def test_the_friction_held_part_expands_on_the_paper_arms_and_a_lab_pair(path):
    """The box held by friction (``object_mode: contact``): every row under the model-error
    and friction columns validates as ``drake-coop run`` validates a scenario, the lab pair's
    Coulomb draws one value per joint of its arm (seven on a Panda, three on the paper's)."""
    from drake_coop.scenario.loading import dump_scenario
    from drake_coop.studies.reference_table import ROWS

    base = load_scenario(path)
    base.plant.object_mode = "contact"
    base = load_scenario(data=dump_scenario(base))
    cases = expand_table(base, [r.name for r in ROWS], ["exact", "model_30", "coulomb"], 1,
                         t_end=T_TINY)
    assert len(cases) == len(ROWS) * 3
    joints = 7 if "panda" in path else 3
    for case in cases:
        s = load_scenario(data=case.scenario_yaml)
        assert s.plant.object_mode == "contact"
        if case.params["column"] == "coulomb":
            assert len(s.robots[0].model_error.coulomb_friction) == joints


def test_identified_columns_identify_from_the_encoders_columns_readings(tmp_path, monkeypatch):
    """Each identified column's draw identifies from data read as the encoders column's draw
    of the same index reads the arm (31 µrad counts, its noise), on the ±30 % column's prior;
    the run then reads exact encoders (the column's only error is the identified model)."""
    from pathlib import Path

    from drake_coop.studies import reference_engine
    from drake_coop.studies.reference_table import ALL_COLUMNS, identified_name

    seen = []
    monkeypatch.setattr(reference_engine, "_run", lambda tasks, *a, **k: seen.extend(tasks))
    col = identified_name("idim_iv", 2.0)
    reference_engine.identify_columns(tmp_path, load_scenario(), [col], 2, 7, workers=1,
                                      ray=None, quiet=True)
    assert [t.key for t in seen] == [(col, 0), (col, 1)]
    for task in seen:
        draw = task.key[1]
        robots = load_scenario(data=task.args[0]).robots
        rng = np.random.default_rng([7, ALL_COLUMNS.index("encoders"), draw])
        for robot in robots:                     # one draw per arm, in the arms' order
            assert robot.encoders.counts_per_rev == 200000
            assert robot.encoders.noise_std == pytest.approx(rng.uniform(0.5e-4, 2e-4),
                                                             rel=1e-12)
            assert robot.encoders.seed == draw
            assert robot.model_error.mass_scale != 1.0          # the ±30 % prior
        assert task.args[2:] == ("idim_iv", 2.0, draw)
    urdf = Path(__file__).resolve().parents[2] / "urdf"
    models = {(col, 0): {"robot1": str(urdf / "crs_a465_3dof.urdf"),
                         "robot2": str(urdf / "crs_a255_3dof.urdf")}}
    (case,) = expand_table(load_scenario(), ["observer"], [col], 1, t_end=T_TINY,
                           models=models)
    base = load_scenario().robots
    for robot, ref in zip(load_scenario(data=case.scenario_yaml).robots, base):
        assert robot.encoders.noise_std == ref.encoders.noise_std
        assert robot.encoders.counts_per_rev == ref.encoders.counts_per_rev


def _record(status: str) -> dict:
    """A case's result of ``status``; an ``ok`` one with the circle's two errors."""
    metrics = ({"robot1": {"circle": {"force_error": {"rms": 0.1},
                                      "estimate_error": {"rms": 0.2}}}}
               if status == "ok" else {})
    return {"status": status, "message": f"a {status} case", "t_reached": 1.0,
            "wall_time_s": 0.1, "metrics": metrics}


@pytest.mark.parametrize("statuses, quiet, code, line", [
    (("ok", "diverged"), False, 0, "2 of 2 cases finished, 1 of them diverged"),
    (("diverged", "failed"), False, 0, "2 of 2 cases finished, 2 of them diverged"),
    (("ok", "error"), True, 1, "of 2 cases 1 ended in an error"),
    (("died", "diverged"), True, 1, "of 2 cases 1 did not finish (a worker died); run the "
                                    "same command again"),
])
def test_command_exits_0_with_diverged_draws_and_1_with_unfinished_or_errored_cases(
        tmp_path, capsys, monkeypatch, statuses, quiet, code, line):
    """A diverged draw is data (counted in its cell): the command exits 0 and says how many;
    a case that did not finish or ended in an error exits 1 in one line. The cases' results
    come from a dispatcher standing in for the workers; the store, the table and the exit
    are the command's own."""
    import drake_coop.studies.reference_engine as engine
    from drake_coop.cli.parser import main

    def dispatch(batches, work, args_of, on_result, on_death, **kwargs):
        cases = [c for b in batches for c in b.cases]
        for b in batches:
            on_result(b, [(c.hash, _record(statuses[cases.index(c)])) for c in b.cases])
    monkeypatch.setattr(engine, "_run", dispatch)
    out = tmp_path / "t"
    args = ["reference-table", "--out", str(out), "--rows", "sensor_3", "--columns", "exact",
            "--draws", "2", "--batch", "1", *(["--quiet"] if quiet else [])]
    assert main(args) == code
    err = capsys.readouterr().err.strip()
    assert line in err and "Traceback" not in err
    if quiet:
        assert "\n" not in err
    table = json.loads((out / "table.json").read_text())
    assert table["cells"]["sensor_3"]["exact"]["diverged"] == sum(
        s in ("diverged", "failed", "error") for s in statuses)
