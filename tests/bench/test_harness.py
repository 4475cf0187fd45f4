"""The benchmark's count of Python callbacks per tick (``bench/harness.py``) against the
diagram's known events: every robot's controller latches once per tick; in the paper's run
the ground truth and the F/T sensor models are C++ holds evaluated after the run (no Python
call at all); with a robot reading its F/T sensor the live ground truth latches once and reads
the step before the tick once per tick."""

from __future__ import annotations

import pytest

from bench.harness import _count_callbacks
from drake_coop.experiment.ticks import num_ticks_until
from drake_coop.scenario.loading import default_scenario
from drake_coop.control.timing import aligned_periods


@pytest.fixture(scope="module")
def counts():
    scenario = default_scenario()
    t_end = 0.27
    h, _ = aligned_periods(scenario.control_period, scenario.plant.time_step)
    return scenario, num_ticks_until(t_end, h), _count_callbacks(scenario, t_end)


def test_each_controller_latch_counts_once_per_tick(counts):
    scenario, ticks, result = counts
    latches = result["by_function"]["drake_coop.control.controller.Controller._update_latch"]
    # One latch per robot at each of the ticks 0..K (the last one by finish_last_tick).
    assert latches * ticks == pytest.approx(len(scenario.robots) * (ticks + 1), rel=1e-12)


def test_paper_run_calls_no_ground_truth_or_sensor_model_in_the_loop(counts):
    _, _, result = counts
    by = result["by_function"]
    assert not [name for name in by
                if any(word in name for word in ("wrist", "ForceSensor", "FTSensor", "FTModel",
                                                 "ground_truth"))]
    assert result["per_tick"] == pytest.approx(sum(by.values()))


def test_live_ground_truth_costs_one_latch_and_one_last_step_read_per_tick():
    """``force_source: sensor`` on robot 1 (its ideal F/T model, a C++ hold, feeds (13)):
    the live path."""
    scenario = default_scenario()
    scenario.robots[0].force_source = "sensor"
    t_end = 0.27
    h, _ = aligned_periods(scenario.control_period, scenario.plant.time_step)
    ticks = num_ticks_until(t_end, h)
    result = _count_callbacks(scenario, t_end)
    by = result["by_function"]
    # The latch at ticks 0..K; the read of the step before each tick 1..K.
    assert by["drake_coop.plant.wrist_dynamics.WristDynamics._update_step"] * ticks == \
        pytest.approx(ticks + 1, rel=1e-12)
    assert by["drake_coop.plant.wrist_dynamics.WristDynamics._calc_last_step"] * ticks == \
        pytest.approx(ticks, rel=1e-12)
    assert not [name for name in by if "FTSensor" in name or "ForceSensor._update" in name]
    assert result["per_tick"] == pytest.approx(sum(by.values()))


def test_plant_replay_reproduces_the_runs_joint_angles_exactly_through_grasp_and_release():
    """The replay baseline is the run's own physics: the plant alone, driven by the run's
    logged torques (one sample later or earlier would move the arms), lands on the run's joint
    angles at every tick through the grasp and the release."""
    from bench.harness import _experiment, _plant_replay

    from tests.conftest import short_scenario

    scenario = short_scenario(t_pregrasp=0.3, t_grasp=0.5, t_circle_start=0.8,
                              t_circle_end=1.2, t_release=1.4, t_end=1.6)
    # A circle in 0.4 s leaves the squeeze 25 N from its reference: a failed task, but the
    # replay of its physics is what is checked here.
    scenario.guards.max_squeeze_error = 1e3
    kept: list = []
    _experiment(scenario, 1.6, kept)
    assert _plant_replay(scenario, 1.6, kept[0])[2] == 0.0
    kept[0].logs[scenario.robots[0].name]["tau"][5:] *= 1.01     # from tick 5 on, 1 % more
    assert _plant_replay(scenario, 1.6, kept[0])[2] > 1e-6


def test_plant_replay_reproduces_a_contact_runs_joint_angles_and_box_pose(monkeypatch):
    """``contact`` mode (the box held by friction at the pads, ``object_model: estimated``):
    the replay of the run's torques lands on the run's joint angles and the box's logged pose
    at every tick through the grasp and the circle, the stand lowered by ``stand_clearance``
    while the box goes around it as the run lowers it. The circle's lowest point (the grasp
    height) lies in the run, so a replay that left the stand in place would have the box
    brush it and move elsewhere (checked)."""
    from bench.harness import _experiment, _plant_replay
    from drake_coop.plant.grasp import ContactObject
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.schema import Task
    from pathlib import Path

    scenario = load_scenario(Path(__file__).resolve().parents[2] / "scenarios" / "contact.yaml")
    assert scenario.plant.stand_clearance > 0
    scenario.object_model.mode = "estimated"
    scenario.task = Task(t_pregrasp=0.3, t_grasp=0.6, t_circle_start=1.0, t_circle_end=3.0,
                         t_release=3.4, t_end=3.6)
    t_end = 2.2       # past the circle's lowest point (~1.9 s)
    kept: list = []
    _experiment(scenario, t_end, kept)
    assert _plant_replay(scenario, t_end, kept[0])[2] == 0.0
    lower = ContactObject.set_stand_lowered
    monkeypatch.setattr(ContactObject, "set_stand_lowered",
                        lambda self, context, lowered: lower(self, context, False))
    assert _plant_replay(scenario, t_end, kept[0])[2] > 1e-6


def test_object_blocks_cost_needs_none_first_and_an_object_model():
    """The blocks' own cost is a ratio to the ``none`` run: without it, or without an object
    model to compare, the call is refused before any run."""
    from bench.object_cost import _object_blocks_cost
    from drake_coop.scenario.loading import default_scenario

    for modes in (("estimated",), ("estimated", "none"), ("none",), ()):
        with pytest.raises(ValueError, match="modes"):
            _object_blocks_cost(default_scenario(), 0.1, 1, modes=modes)


@pytest.mark.slow
def test_plant_replay_reproduces_a_pandas_contact_run_with_an_object_model():
    """The baseline of the benchmark's ``--object-arms two_pandas`` rows: the two 7-joint
    Pandas with contact.yaml's plant and ``object_model: estimated`` (the redundant arms'
    pose reference, the pads' contact points, the load feedforward and the mass estimator),
    compressed phases through the grasp and into the lift; the plant alone driven by the
    run's logged torques lands on the run's joint angles and the box's pose at every tick,
    and misses them when one arm's torque is changed by 1 % from tick 5 on."""
    import dataclasses

    from bench.harness import _experiment, _plant_replay
    from bench.lab_arms_object import contact_scenario
    from drake_coop.control.arm_plant import description_packages
    from drake_coop.scenario import validate

    if "example-robot-data" not in description_packages():
        pytest.skip('example-robot-data is not installed (pip install -e ".[robots]")')
    scenario = contact_scenario("two_pandas")
    scenario.task = dataclasses.replace(scenario.task, t_pregrasp=0.6, t_grasp=1.0,
                                        t_circle_start=2.0, t_circle_end=12.0, t_release=13.0,
                                        t_end=14.0)
    validate(scenario)
    t_end = 1.6
    kept: list = []
    _experiment(scenario, t_end, kept)
    assert _plant_replay(scenario, t_end, kept[0])[2] == 0.0
    kept[0].logs[scenario.robots[0].name]["tau"][5:] *= 1.01
    assert _plant_replay(scenario, t_end, kept[0])[2] > 1e-6
