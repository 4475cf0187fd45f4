"""The ground truth off the control loop (:mod:`drake_coop.plant.ground_truth`).

Without a controller reading the F/T sensor, ``planes`` and ``rigid`` runs hold the plant's
data with C++ blocks and compute ``F_meas``, ``lambda_meas`` and ``lambda_sensor`` after the
run. The reference is the live path (``live_ground_truth=True``: the Python systems latching
at every tick, themselves checked against Drake's reaction forces in ``tests/plant/test_cooperative.py``
and against every plant step in ``tests/plant/test_ground_truth_timing.py``), on the same scenario:
the two runs' trajectories are identical, so their logs must agree tick for tick.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from drake_coop.experiment.diagram import build_experiment

from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.simulate import simulate
from drake_coop.scenario import load_scenario
from drake_coop.sensing.force_sensor import FTModel
from drake_coop.sensing.sampling import FORCE_SENSOR_STREAM, white_noise
from tests.conftest import compress_phases, short_scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
KEYS = ("F_meas", "lambda_meas", "lambda_sensor")


def _both_paths(scenario, t_end):
    runs = [simulate(scenario, t_end=t_end, live_ground_truth=live) for live in (True, False)]
    for r in runs:
        assert r.ok, r.meta["message"]
    return runs


@pytest.mark.parametrize("case", ["paper", "realistic_friction", "rigid", "six_joint"])
def test_offline_ground_truth_equals_the_live_path_tick_for_tick(case):
    """Through the grasp of the shipped scenarios: the paper's, the realistic one (F/T
    model with a 25 Hz filter, bias and noise; encoders) with Coulomb friction added (the
    actuation differs from step to step), the rigid object, and a six-joint arm (least
    squares). Their phases compressed as :func:`~tests.conftest.short_scenario`'s (the grasp
    at 1 s, not 15 s; run to 1.6 s, not 16 s): the two paths are compared tick for tick,
    and the 14 s of free motion before the grasp added no tick the check needs."""
    name = {"realistic_friction": "realistic"}.get(case, case)
    scenario = load_scenario(SCENARIOS / f"{name}.yaml")
    compress_phases(scenario)
    if case == "realistic_friction":
        for r in scenario.robots:
            r.model_error.coulomb_friction = [0.4, 0.3, 0.2]
    live, offline = _both_paths(scenario, 1.6)
    assert offline.experiment.ground_truth is not None
    assert live.experiment.ground_truth is None
    for robot, log in live.logs.items():
        other = offline.logs[robot]
        np.testing.assert_array_equal(log["q"], other["q"])       # the same trajectory
        assert np.abs(log["lambda_meas"]).max() > 1.0             # the squeeze is in it
        for key in KEYS:
            assert other[key].shape == log[key].shape, key
            np.testing.assert_allclose(other[key], log[key], rtol=0, atol=1e-11,
                                       err_msg=f"{case} {robot} {key}")


def test_offline_ground_truth_equals_the_live_path_when_h_is_one_plant_step():
    """``h = Δt`` (no hold before the tick: the F/T model reads the previous tick's step),
    with a biased, filtered, noisy sensor; compressed scenario through the grasp."""
    scenario = short_scenario("planes", 0.003)
    scenario.control_period = 0.003
    for r in scenario.robots:
        r.force_sensor.bias, r.force_sensor.noise_std, r.force_sensor.cutoff_hz = 0.3, 0.1, 40.0
    live, offline = _both_paths(scenario, 1.6)
    for robot, log in live.logs.items():
        assert np.abs(log["lambda_meas"]).max() > 1.0
        for key in KEYS:
            np.testing.assert_allclose(offline.logs[robot][key], log[key], rtol=0, atol=1e-11,
                                       err_msg=f"{robot} {key}")


def test_offline_path_has_no_python_ground_truth_in_the_diagram():
    exp = build_experiment(plan_run(load_scenario(SCENARIOS / "paper.yaml")))
    kinds = {type(s).__name__ for s in exp.diagram.GetSystems()}
    assert not kinds & {"WristDynamics", "WristKinematics", "ForceSensor", "FTSensor"}
    assert {"ZeroOrderHold", "Multiplexer"} <= kinds
    assert all(rs.force_sensor is None and rs.ft_sensor is None for rs in exp.robots)


@pytest.mark.parametrize("change", ["sensor", "none"])
def test_live_path_is_automatic_and_required_with_a_sensor_feedback_or_other_modes(change):
    scenario = short_scenario("planes", 0.003)
    if change == "sensor":
        scenario.robots[1].force_source = "sensor"
    else:
        scenario.plant.object_mode = change
    exp = build_experiment(plan_run(scenario), log=False)
    assert exp.ground_truth is None and all(rs.force_sensor is not None for rs in exp.robots)
    with pytest.raises(ValueError, match="live_ground_truth=False"):
        build_experiment(plan_run(scenario), log=False, live_ground_truth=False)


@pytest.mark.parametrize("sensor", [False, True])
def test_contact_mode_takes_the_pads_forces_off_the_loop(sensor):
    """``contact`` mode: no Python ground-truth system with a period in the loop (the pads'
    forces are computed once per plant step for a C++ hold), and only a controller that reads
    its F/T sensor gets a live model (fed by the hold); ``live_ground_truth=True`` keeps the
    reaction-force chain."""
    scenario = short_scenario("planes", 0.003)
    scenario.plant.object_mode = "contact"
    if sensor:
        scenario.robots[1].force_source = "sensor"
    exp = build_experiment(plan_run(scenario))
    kinds = [type(s).__name__ for s in exp.diagram.GetSystems()]
    assert not set(kinds) & {"WristDynamics", "WristKinematics", "ForceSensor"}
    assert kinds.count("PadForces") == 1 and exp.ground_truth.logger is not None
    assert all(rs.force_sensor is None for rs in exp.robots)
    assert [rs.ft_sensor is not None for rs in exp.robots] == [False, sensor]
    live = build_experiment(plan_run(scenario), log=False, live_ground_truth=True)
    assert live.ground_truth is None and all(rs.force_sensor is not None for rs in live.robots)
    assert "PadForces" not in {type(s).__name__ for s in live.diagram.GetSystems()}


def test_guard_reads_the_offline_force_of_the_step_before_the_tick():
    """At a held tick (before its updates) the guards' measured force is the force of the
    plant step ``[t_k − Δt, t_k)`` from the held data and the current state: equal to a live
    probe's force of that step (recorded at ``t_k − Δt``); a jump of the plant's velocities
    (a force the step before would have needed: ``a = Δv/Δt``) trips the guard on it."""
    from pydrake.systems.analysis import Simulator

    from drake_coop.experiment.ticks import grasp_ticks
    from drake_coop.experiment.simulate import _check_guards, initialize
    from drake_coop.plant.wrist import add_force_sensors
    from drake_coop.scenario import aligned_periods

    scenario = short_scenario("planes", 0.001)
    h, dt = aligned_periods(scenario.control_period, scenario.plant.time_step)
    probes = []
    exp = build_experiment(plan_run(scenario), before_build=lambda b, coop: probes.extend(
        add_force_sensors(b, coop)))
    sim = Simulator(exp.diagram)
    ctx = sim.get_mutable_context()
    initialize(exp, ctx)
    steps = {}

    def record(context):
        t = context.get_time()
        j = int(round(t / dt))
        if t == j * dt and j not in steps:
            steps[j] = [p.GetOutputPort("F_meas").Eval(p.GetMyContextFromRoot(context)).copy()
                        for p in probes]
    sim.set_monitor(record)
    sim.Initialize()
    k_grasp, _ = grasp_ticks(scenario.task, h)
    sim.AdvanceTo(k_grasp * h)
    pc = exp.coop.plant.GetMyMutableContextFromRoot(ctx)
    exp.coop.set_held(pc, True)
    k = k_grasp + 30
    sim.AdvanceTo(k * h)
    forces = exp.ground_truth.force_before_tick(ctx)
    before = steps[int(round(k * h / dt)) - 1]
    for F, F_probe in zip(forces, before):
        assert np.linalg.norm(F_probe) > 1.0                 # the object is squeezed
        np.testing.assert_allclose(F, F_probe, rtol=0, atol=1e-9)
    assert _check_guards(exp, ctx) is None
    plant = exp.coop.plant
    plant.SetVelocities(pc, plant.GetVelocities(pc) + 5.0)
    message = _check_guards(exp, ctx)
    assert message is not None and "robot1 measured force" in message, message


def test_ft_model_readings_follow_the_first_order_filter_and_the_seeded_noise():
    """``FTModel.readings`` against the filter's closed form for a constant input,
    ``y(k) = λ (1 − (1 − α)^k)``, plus the bias and the seeded noise of each tick."""
    model = FTModel(alpha=0.3, bias=0.2, noise_std=0.05, seed=4, robot=1, m=2)
    lam = np.array([3.0, -1.5])
    K = 40
    out = model.readings(np.tile(lam, (K, 1)))
    k = np.arange(1, K)[:, None]
    noise = np.array([white_noise(4, 1, FORCE_SENSOR_STREAM, int(i), 0.05, 2)
                      for i in range(1, K)])
    np.testing.assert_allclose(out[1:], lam * (1 - 0.7 ** k) + 0.2 + noise, rtol=0, atol=1e-13)
    np.testing.assert_array_equal(out[0], [0.2, 0.2])           # before any read: the bias
    ideal = FTModel(alpha=1.0, bias=0.0, noise_std=0.0, seed=0, robot=0, m=1)
    lams = np.random.default_rng(1).normal(size=(5, 1))
    np.testing.assert_array_equal(ideal.readings(lams)[1:], lams[1:])   # λ itself, bit for bit


def test_tick_forces_give_during_the_run_the_logged_force_of_the_last_ticks_step():
    """``wrist_forces_at_tick`` (what the Meshcat arrows draw on the offline path) at a tick,
    before the tick's updates, is the force of the step from the previous tick: the logged
    ``F_meas`` of that tick, evaluated after the run from the same hold."""
    scenario = short_scenario()
    box, seen = {}, []

    def progress(t, T, wall):
        exp, sim = box["exp"], box["sim"]
        system = exp.diagram.GetSubsystemByName("wrist_forces_at_tick")
        ctx = system.GetMyContextFromRoot(sim.get_context())
        seen.append((t, [system.GetOutputPort(f"{rs.name}_F_step").Eval(ctx).copy()
                         for rs in exp.robots]))

    result = simulate(scenario, t_end=1.5, progress=progress,
                      before_build=lambda builder, coop: None,     # a visualizer's hook
                      on_start=lambda exp, sim: box.update(exp=exp, sim=sim))
    assert result.ok and len(seen) > 10
    h = scenario.control_period
    for t, forces in seen[1:]:
        k = round(t / h)
        for rs, F in zip(result.experiment.robots, forces):
            np.testing.assert_allclose(F, result.logs[rs.name]["F_meas"][k - 1],
                                       rtol=0, atol=1e-12)
    assert max(np.linalg.norm(F) for _, forces in seen for F in forces) > 1.0   # held
