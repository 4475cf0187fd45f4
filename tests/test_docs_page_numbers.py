"""The computed numbers the stability and identification pages read
(``docs/results/stability_page_numbers.json``, ``docs/results/identification_page_numbers.json``)
are what their scripts compute now from the shipped files, and agree with an independent
computation of a sample of them (a polynomial's roots, a CSV read with ``csv`` and NumPy)."""

from __future__ import annotations

import csv
import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"


def _module(path: str):
    spec = importlib.util.spec_from_file_location(Path(path).stem + "_under_test", ROOT / path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _flat(node, path=""):
    if isinstance(node, dict):
        return {k: v for key, child in node.items() for k, v in _flat(child, f"{path}.{key}").items()}
    if isinstance(node, list):
        return {k: v for i, child in enumerate(node) for k, v in _flat(child, f"{path}.{i}").items()}
    return {path: node}


def _rows(path: Path) -> list[dict]:
    with path.open(newline="") as handle:
        return list(csv.DictReader(handle))


def test_the_stability_pages_computed_numbers_are_the_scripts():
    module = _module("studies/stability/page_numbers.py")
    now = {"observer_period_limit": module.observer_limits(),
           "one_joint_measured": module.one_joint_measured(),
           "continuous_margin": module.continuous_margin(),
           "clock_skew_change": module.skew_changes(),
           "jitter_lateness": module.jitter_lateness()}
    shipped = json.loads((RESULTS / "stability_page_numbers.json").read_text())
    assert _flat(shipped) == pytest.approx(_flat(json.loads(json.dumps(now))), abs=1e-12)


@pytest.mark.parametrize("robot, lam", [("robot1", 35.0), ("robot2", 26.0)])
def test_the_observer_period_limit_is_two_over_the_fast_pole(robot, lam):
    shipped = json.loads((RESULTS / "stability_page_numbers.json").read_text())
    for k_d in (40.0, 80.0, 160.0, 320.0):
        poles = np.roots([1.0, 2.0 * lam + k_d, lam * k_d])     # s² + (2Λ + k_d)s + Λk_d
        entry = shipped["observer_period_limit"][robot][f"k_d{k_d:.0f}"]
        assert entry["period_limit_s"] == pytest.approx(2.0 / max(abs(poles)), rel=1e-12)
        assert sorted([entry["pole_fast"], entry["pole_slow"]]) == pytest.approx(sorted(poles))


def test_the_lateness_percentile_and_the_skew_change_read_from_their_definitions():
    shipped = json.loads((RESULTS / "stability_page_numbers.json").read_text())
    s, h = 0.0011, 0.009
    p99 = shipped["jitter_lateness"]["exponential_1p1ms"]["p99_s"]
    assert (1 - math.exp(-p99 / s)) / (1 - math.exp(-h / s)) == pytest.approx(0.99)
    rows = _rows(ROOT / "docs" / "figures" / "stability" / "clock_skew.csv")
    rigid = [r for r in rows if r["object_mode"] == "rigid" and not r["prediction_horizon"]]
    r1 = [float(r["squeeze_rms_robot1"]) for r in rigid]
    assert shipped["clock_skew_change"]["rigid_off"]["robot1"] == pytest.approx(
        abs(r1[1] / r1[0] - 1.0))


def test_the_identification_pages_computed_numbers_are_the_scripts():
    module = _module("studies/identification/page_numbers.py")
    now = {"budgets": module.budgets(), "sources": module.sources("identified_sources.csv"),
           "sources_published": module.sources("identified_sources_published.csv"),
           "saturation_circle_change_robot1": module.saturation(),
           "identify_realistic": module.identify_ratios()}
    shipped = json.loads((RESULTS / "identification_page_numbers.json").read_text())
    assert _flat(shipped) == pytest.approx(_flat(json.loads(json.dumps(now))), abs=1e-12)


def test_a_budget_median_is_the_worst_arms_median_over_the_draws():
    shipped = json.loads((RESULTS / "identification_page_numbers.json").read_text())
    rows = [r for r in _rows(ROOT / "docs" / "figures" / "studies" / "identification_budgets.csv")
            if r["estimator"] == "didim" and float(r["excitation_s"]) == 2.0]
    worst = [max(float(r["robot1.torque_error_rms_identified"]),
                 float(r["robot2.torque_error_rms_identified"])) for r in rows]
    assert len(worst) == shipped["budgets"]["s2"]["didim"]["draws"] == 6
    assert shipped["budgets"]["s2"]["didim"]["torque_error_median"] == pytest.approx(
        float(np.median(worst)))


@pytest.mark.slow
def test_the_rank_table_is_the_regressors_rank_now():
    """The shipped rank table's counts are what the regressor gives now (the lab arms only
    where the robots extra is installed); its gaps are clear (round-off level, not compared)."""
    from drake_coop.plant.arms import shipped_arm_models

    module = _module("studies/identification/rank_table.py")
    shipped = json.loads((RESULTS / "identification_rank_table.json").read_text())["arms"]
    arms = shipped_arm_models()
    assert {"crs_a465", "crs_a255"} <= set(arms)
    for model, where in arms.items():
        n, Y = module.regressor(*where)
        now, row = module.row(n, Y), shipped[model.rsplit("/", 1)[-1].replace(".", "_")]
        assert (now["joints"], now["base_parameters"], now["parameters"]) == (
            row["joints"], row["base_parameters"], row["parameters"])
        assert now["condition_number"] == pytest.approx(row["condition_number"], rel=1e-6)
        assert row["gap_at_rank"] > 1e8
