"""The held object's metrics on simulated ``contact`` runs: a box the squeeze cannot hold is
counted as dropped (and slipping); the shipped contact scenario is carried without either."""

from __future__ import annotations

import pytest

from drake_coop.experiment.simulate import simulate
from drake_coop.results.metrics import compute_metrics
from drake_coop.scenario import load_scenario
from drake_coop.scenario.resources import shipped_scenarios

SHORT = dict(t_pregrasp=0.5, t_grasp=1.0, t_circle_start=3.0, t_circle_end=5.0, t_release=6.0,
             t_end=6.5)


def _short_contact(force: float):
    scenario = load_scenario(shipped_scenarios()["contact"])
    for key, value in SHORT.items():
        setattr(scenario.task, key, value)
    scenario.task.force_mean, scenario.task.force_amplitude = force, 0.0
    return scenario


def _counts(metrics: dict, name: str) -> int:
    return sum(metrics[r][p][name]["count"] for r in metrics for p in ("lift", "circle")
               if p in metrics[r])


def _without_failure_guards(scenario):
    """The run carried on past its failure, for its metrics."""
    g = scenario.guards
    g.max_pad_error, g.max_squeeze_error = 10.0, 1e5
    g.max_object_tilt_deg, g.max_object_position_error, g.grasp_lost = 180.0, 10.0, False
    return scenario


def test_a_box_squeezed_with_1_newton_is_dropped():
    # 1 N per pad at μ = 1 holds 2 N of the box's 4.9 N: it stays on the stand as the pads rise.
    result = simulate(_without_failure_guards(_short_contact(1.0)), t_end=3.5)
    assert result.ok
    metrics = compute_metrics(result.logs, result.meta)
    assert _counts(metrics, "drops") >= 1
    assert _counts(metrics, "slips") >= 2            # both pads slide up its faces
    assert metrics["robot1"]["circle"]["object_position_error"]["max"] > 0.03


def test_a_box_squeezed_with_32_newtons_is_carried():
    result = simulate(_short_contact(32.0), t_end=3.5)
    metrics = compute_metrics(result.logs, result.meta)
    assert _counts(metrics, "drops") == 0 and _counts(metrics, "slips") == 0
    assert metrics["robot1"]["circle"]["object_position_error"]["max"] < 0.005
    for robot in metrics:
        assert metrics[robot]["circle"]["friction_use"]["max"] < 0.5


@pytest.mark.slow
def test_the_shipped_contact_run_neither_slips_nor_drops():
    result = simulate(load_scenario(shipped_scenarios()["contact"]))
    assert result.ok
    metrics = compute_metrics(result.logs, result.meta)
    for robot, phases in metrics.items():
        for phase in ("lift", "circle", "put_down"):
            assert phases[phase]["slips"]["count"] == 0, (robot, phase)
            assert phases[phase]["drops"]["count"] == 0, (robot, phase)
            assert phases[phase]["slip"]["max"] < 1.5e-3, (robot, phase)
        assert phases["circle"]["friction_use"]["max"] < 0.5
    # The stand, lowered by stand_clearance during the circle, is never touched there.
    log = result.logs["robot1"]
    circle = (log["t"] >= 26.0) & (log["t"] < 64.0)
    stand_top = 0.535 - 0.05 - 0.010
    assert (log["object_pose"][circle, 6] - 0.05 > stand_top + 2e-3).all()


def test_a_dropped_box_fails_the_run_where_the_grasp_is_lost():
    """With the default guards the same run stops as failed, soon after the pads let go (the
    box off its path or the grasp lost, whichever a guard chunk sees first), and its logs end
    there; the metrics of what was logged count the drop."""
    result = simulate(_short_contact(1.0), t_end=3.5)
    assert result.meta["status"] == "failed"
    failure = result.meta["failure"]
    assert failure["guard"] in ("grasp_lost", "max_object_position_error")
    assert 1.0 < failure["t"] < 3.0
    assert result.meta["message"].startswith(f"failed at t = {failure['t']:.3f} s: ")
    assert result.logs["robot1"]["t"][-1] <= failure["t"] + 1e-9
