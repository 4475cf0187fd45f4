"""Summary columns, results tables and study figures from records (no simulation)."""

import csv
import json
import math

import numpy as np

from drake_coop.studies import expand, load_study
from drake_coop.studies.plots import plot_study
from drake_coop.studies.store import ResultStore, check_metric_names, summary_columns


def _phase(rng):
    return {e: {"rms": float(rng.uniform(0.1, 1)), "max": float(rng.uniform(1, 2)), "unit": "m"}
            for e in ("x_tilde", "y_tilde", "z_tilde", "force_error", "estimate_error",
                      "aux_force_error", "z1", "z2", "z3")}


def test_summary_columns_combine_axes_and_robots_as_documented():
    rng = np.random.default_rng(0)
    metrics = {"robot1": {"circle": _phase(rng)}, "robot2": {"circle": _phase(rng),
                                                             "free": _phase(rng)}}
    s = summary_columns(metrics, "circle")
    for robot in ("robot1", "robot2"):
        m = metrics[robot]["circle"]
        assert s[f"{robot}.position_error.rms"] == math.sqrt(
            m["x_tilde"]["rms"] ** 2 + m["y_tilde"]["rms"] ** 2 + m["z_tilde"]["rms"] ** 2)
        assert s[f"{robot}.position_error.max"] == max(m[a]["max"] for a in
                                                       ("x_tilde", "y_tilde", "z_tilde"))
        assert s[f"{robot}.observation_error.max"] == max(m[z]["max"] for z in ("z1", "z2", "z3"))
        assert s[f"{robot}.force_error.rms"] == m["force_error"]["rms"]
    assert s["worst.force_error.rms"] == max(metrics[r]["circle"]["force_error"]["rms"]
                                             for r in ("robot1", "robot2"))
    # a phase that one robot never reached: only the other robot's columns
    s = summary_columns(metrics, "free")
    assert "robot1.force_error.rms" not in s
    assert s["worst.force_error.rms"] == metrics["robot2"]["free"]["force_error"]["rms"]


def test_tables_and_figures_of_a_grid_with_monte_carlo(tmp_path):
    study = load_study(data="""
name: syn
phase: circle
grid:
  robots.*.gains.k_d: [20, 40]
  robots.*.gains.K_R: [60, 120]
  robots.*: [{velocity_source: observer}, {velocity_source: measured}]
monte_carlo: {n: 3, seed: 5, perturb: {robots.0.gains.k_F: {uniform: [0.04, 0.06]}}}
metrics: [worst.force_error.rms, worst.position_error.max]
guides: [{label: g, slope: 1.0}]
""")
    cases = expand(study)
    assert len(cases) == 2 * 2 * 2 * 3
    store = ResultStore(tmp_path)
    rng = np.random.default_rng(1)
    records = {}
    for c in cases[:-2]:                  # the last two still pending
        diverged = c.params["robots.*.gains.K_R"] == 120 and c.params["robots.*.gains.k_d"] == 40
        result = {"status": "diverged" if diverged else "ok",
                  "message": "diverged at t = 1 s" if diverged else "completed",
                  "t_reached": 1.0, "wall_time_s": 0.1,
                  "metrics": {"robot1": {"circle": _phase(rng)},
                              "robot2": {"circle": _phase(rng)}}}
        records[c.hash] = store.save(c, result, study.t_end)
    store.write_tables(study, cases, records, "local")
    assert store.load() == records
    with open(tmp_path / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["hash"] for r in rows] == [c.hash for c in cases]
    assert [r["status"] for r in rows[-2:]] == ["pending", "pending"]
    assert rows[0]["robots.*"] == "velocity_source=observer" and rows[0]["sample"] == "0"
    doc = json.loads((tmp_path / "study.json").read_text())
    # (k_d, K_R) = (40, 120) holds 6 cases (2 variants x 3 samples), the last 2 still pending
    assert doc["counts"] == {"ok": 18, "diverged": 4, "pending": 2}
    names = sorted(p.name for p in plot_study(tmp_path))
    assert names == ["syn_hist.png", "syn_map.png", "syn_vs_gains_K_R.png",
                     "syn_vs_gains_k_d.png", "syn_vs_robots.png"]
    for name in names:
        assert (tmp_path / name).stat().st_size > 5_000


def test_observation_error_covers_every_joint_of_the_arm():
    """A 6-joint arm's summary combines z1 … z6 (a 3-joint arm's z1 … z3)."""
    import math

    from drake_coop.studies.store import summary_columns

    six = {f"z{k}": {"rms": 0.1 * k, "max": 0.2 * k} for k in range(1, 7)}
    three = {f"z{k}": {"rms": 0.1 * k, "max": 0.2 * k} for k in range(1, 4)}
    cols = summary_columns({"robot1": {"circle": six}, "robot2": {"circle": three}}, "circle")
    assert cols["robot1.observation_error.rms"] == math.sqrt(sum((0.1 * k) ** 2
                                                                 for k in range(1, 7)))
    assert cols["robot1.observation_error.max"] == 0.2 * 6
    assert cols["robot2.observation_error.max"] == 0.2 * 3
    assert cols["robot1.z6.rms"] == 0.1 * 6 and "robot2.z4.rms" not in cols


def test_object_counts_and_times_become_columns():
    phase = {"force_error": {"rms": 1.0, "max": 2.0, "unit": "N"},
             "object_position_error": {"rms": 0.002, "max": 0.003, "unit": "m"},
             "slips": {"count": 2, "unit": "events"}, "drops": {"count": 0, "unit": "events"},
             "mass_convergence_time": {"time": 4.5, "unit": "s"}}
    other = {**phase, "slips": {"count": 3, "unit": "events"},
             "mass_convergence_time": {"time": None, "unit": "s"}}     # never converged
    columns = summary_columns({"robot1": {"circle": phase}, "robot2": {"circle": other}},
                              "circle")
    assert columns["robot1.slips.count"] == 2 and columns["robot2.slips.count"] == 3
    assert columns["worst.slips.count"] == 3 and columns["worst.drops.count"] == 0
    assert columns["robot1.mass_convergence_time.time"] == 4.5
    assert "robot2.mass_convergence_time.time" not in columns
    assert columns["worst.object_position_error.rms"] == 0.002
    robots = ["robot1", "robot2"]
    assert check_metric_names(["worst.drops.count", "robot2.slip.max"], robots) is None
    assert "unknown column" in check_metric_names(["worst.drops.rms"], robots)
