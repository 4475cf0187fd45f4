"""The sensing and the alternative sources in the whole diagram (compressed 8 s scenario).

* the diagram reads plant → sensors → control block → actuators → plant, per robot;
* for each source that claims not to use them, the next torque is unchanged when the plant's
  joint velocities or its true contact force are perturbed (and it changes for ``measured``,
  which does use the velocities);
* each new source completes the compressed run under realistic sensing;
* a harsh setting (raw difference of a coarse encoder) diverges: exit 1, logs kept, and such
  logs without the new arrays still plot.
"""

import json
import math

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.experiment.diagram import build_experiment
from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.ticks import grasp_ticks
from drake_coop.experiment.simulate import simulate
from drake_coop.results.logs import COLUMNS, OPTIONAL_COLUMNS, load_logs, save_logs
from drake_coop.results.metrics import compute_metrics
from drake_coop.scenario import aligned_periods, dump_scenario
from tests.conftest import advance_to_tick, short_scenario


def _scenario(velocity_source, force_source, **encoders):
    s = short_scenario("planes", 0.003)
    for r in s.robots:
        r.velocity_source, r.force_source = velocity_source, force_source
        for key, value in encoders.items():
            setattr(r.encoders, key, value)
    return s


def test_diagram_reads_plant_sensors_control_actuators_plant():
    exp = build_experiment(plan_run(_scenario("difference", "sensor")), log=False)
    names = {s.get_name() for s in exp.diagram.GetSystems()}
    for n in ("robot1_encoders", "robot1_control", "robot1_actuators", "robot1_ft_sensor",
              "robot1_force_sensor"):
        assert n in names
    rs = exp.robots[0]
    inner = {s.get_name() for s in rs.control.GetSystems()}
    assert inner == {"robot1_difference_velocity", "robot1_sensed_force", "robot1_controller"}
    # The control block's inputs: encoder q, reference, the F/T model's λ; no plant state.
    ports = {rs.control.get_input_port(i).get_name() for i in range(rs.control.num_input_ports())}
    assert ports == {"q", "reference", "lambda_sensor"}


def _tau_before_and_after_perturbation(scenario):
    """τ(k) at a held tick, then after changing the plant's velocities and contact force."""
    h, _ = aligned_periods(scenario.control_period, scenario.plant.time_step)
    k_grasp, _ = grasp_ticks(scenario.task, h)
    # The live ground truth: its ports show that the perturbation reaches the plant's force.
    exp, sim, ctx = advance_to_tick(scenario, k_grasp + 40, live_ground_truth=True)
    pc = exp.coop.plant.GetMyMutableContextFromRoot(ctx)

    def taus():
        # τ(k) that the tick's update latches (the tau port is state, still τ(k−1)).
        return [rs.controller.next_tau(rs.controller.GetMyContextFromRoot(ctx)).copy()
                for rs in exp.robots]

    def force():
        rs = exp.robots[0]
        return rs.force_sensor.GetOutputPort("lambda_meas").Eval(
            rs.force_sensor.GetMyContextFromRoot(ctx))[0]

    before, lam_before = taus(), force()
    plant = exp.coop.plant
    plant.SetVelocities(pc, np.random.default_rng(0).normal(size=plant.num_velocities()))
    exp.coop.set_held(pc, False)                   # the true contact force disappears
    assert abs(force() - lam_before) > 1.0         # ...the ground truth did change
    return before, taus()


@pytest.mark.slow
@pytest.mark.parametrize("velocity_source, force_source", [
    ("observer", "sensor"), ("difference", "none"), ("difference", "observer"),
    ("observer", "momentum")])
def test_next_torque_ignores_true_velocities_and_contact_force(velocity_source, force_source):
    before, after = _tau_before_and_after_perturbation(
        _scenario(velocity_source, force_source, counts_per_rev=100000, noise_std=1e-5,
                  delay_samples=1))
    for a, b in zip(before, after):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow
def test_measured_baseline_torque_does_depend_on_the_true_velocities():
    before, after = _tau_before_and_after_perturbation(_scenario("measured", "observer"))
    assert np.abs(before[0] - after[0]).max() > 1.0


@pytest.mark.slow
def test_harsh_raw_difference_of_a_coarse_encoder_diverges_exit_1_logs_kept(tmp_path, capsys):
    s = _scenario("difference", "observer", counts_per_rev=256)
    path = tmp_path / "harsh.yaml"
    path.write_text(dump_scenario(s))
    out = tmp_path / "o"
    code = main(["run", str(path), "--out", str(out), "--quiet", "--no-replay"])
    assert code == 1
    err = capsys.readouterr().err
    assert "diverged" in err
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "diverged"
    logs, _ = load_logs(out)
    assert 0 < logs["robot1"]["t"][-1] < 8.0
    assert set(OPTIONAL_COLUMNS) <= set(logs["robot1"])
    header = (out / "robot1.csv").read_text().splitlines()[0].split(",")
    assert header[-10:] == [c for names in OPTIONAL_COLUMNS.values() for c in names]
    # The same logs without the new arrays (as written before the sensing fields existed) still load and plot.
    old = tmp_path / "old"
    save_logs(old, {r: {k: v for k, v in log.items() if k in COLUMNS}
                    for r, log in logs.items()}, meta)
    assert main(["plot", str(old), "--quiet"]) == 0
    assert (old / "fig3_force_tracking.png").exists()
    assert not (old / "fig7_velocity_estimate.png").exists()
    assert "velocity_error" not in json.loads((old / "metrics.json").read_text())[
        "robot1"]["free"]


@pytest.mark.slow
def test_filtered_difference_with_force_sensor_completes_under_realistic_sensing():
    s = _scenario("difference", "sensor", counts_per_rev=200000)
    for r in s.robots:
        r.difference_cutoff_hz = 20.0
        r.force_sensor.noise_std, r.force_sensor.bias, r.force_sensor.cutoff_hz = 0.05, 0.2, 25.0
        r.actuators.torque_limits = [60.0, 60.0, 60.0]
    result = simulate(s)
    assert result.ok, result.meta["message"]
    metrics = compute_metrics(result.logs, result.meta)
    for robot, log in result.logs.items():
        c = metrics[robot]["circle"]
        assert c["force_error"]["rms"] < 0.05 * s.task.force_mean     # within 5 % of (29)
        assert max(c[k]["max"] for k in ("x_tilde", "y_tilde", "z_tilde")) < 1e-3
        assert c["velocity_error"]["max"] < 0.1
        held = (log["t"] > s.task.t_circle_start) & (log["t"] < s.task.t_circle_end)
        # The sensor reads the true squeeze, low-passed, biased and noisy.
        gap = log["lambda_sensor"][held] - log["lambda_meas"][held]
        assert abs(gap.mean() - 0.2) < 0.1 and gap.std() < 0.5
        np.testing.assert_array_equal(log["lambda_hat"][held], log["lambda_sensor"][held])
        assert np.all(np.abs(log["tau"]) <= 60.0)
        # q̂ = q (encoder) on the count grid of 200000 per revolution.
        counts = log["q"] / (2 * np.pi / 200000)
        np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)


@pytest.mark.slow
def test_measured_velocity_without_force_estimate_completes_with_model_error():
    s = _scenario("measured", "none", noise_std=1e-5, delay_samples=1)
    for r in s.robots:
        m = r.model_error
        m.mass_scale, m.inertia_scale, m.damping_scale = 1.1, 1.1, 1.2
        m.payload_mass, m.coulomb_friction = 0.3, [0.5, 0.5, 0.3]
    result = simulate(s)
    assert result.ok, result.meta["message"]
    metrics = compute_metrics(result.logs, result.meta)
    for robot, log in result.logs.items():
        c = metrics[robot]["circle"]
        np.testing.assert_array_equal(log["qdot_hat"], log["qdot"])     # the true velocities
        held = (log["t"] > s.task.t_circle_start) & (log["t"] < s.task.t_circle_end)
        np.testing.assert_array_equal(log["lambda_hat"][held], log["lambda_d"][held])
        assert c["force_error"]["rms"] < 0.25 * s.task.force_mean
        assert max(c[k]["max"] for k in ("x_tilde", "y_tilde", "z_tilde")) < 5e-3


# --------------------------------------------------------------------------- F/T sensor timing
def _ft_readings_and_step_forces(t_end):
    """``scenarios/realistic.yaml`` to ``t_end``: the logged F/T readings (the offline path:
    computed after the run from held plant data) and, recorded by a Simulator monitor at every
    plant step time ``j Δt`` (publishes run before that time's updates), the ground truth ``λ``
    of each plant step from a probe (:func:`~drake_coop.plant.wrist.add_force_sensors` without
    a period: output ports only, evaluated by the monitor alone): the plant's live port there
    is the step the plant then takes."""
    from pathlib import Path

    from drake_coop.plant.wrist import add_force_sensors
    from drake_coop.scenario import load_scenario

    scenario = load_scenario(Path(__file__).resolve().parents[2] / "scenarios" / "realistic.yaml")
    h, dt = aligned_periods(scenario.control_period, scenario.plant.time_step)
    steps = {}
    probes = []

    def before_build(builder, coop):
        probes.extend(add_force_sensors(builder, coop))

    def on_start(exp, simulator):
        assert exp.ground_truth is not None and all(rs.force_sensor is None
                                                    for rs in exp.robots)

        def record(context):
            # Only at the plant's own step times j Δt (Drake's periodic event time): an event
            # one rounding off the grid makes a ~1e-18 s step whose live port is not a step.
            t = context.get_time()
            j = int(round(t / dt))
            if t == j * dt and j not in steps:
                steps[j] = [probe.GetOutputPort("lambda_meas").Eval(
                    probe.GetMyContextFromRoot(context)).copy() for probe in probes]
        simulator.set_monitor(record)

    result = simulate(scenario, t_end=t_end, before_build=before_build, on_start=on_start)
    assert result.ok, result.meta["message"]
    return scenario, h, dt, result, steps


@pytest.mark.slow
def test_ft_sensor_reads_the_low_pass_of_the_plant_step_before_every_tick():
    """Every tick k >= 1 of a realistic run (ideal sensors would hide nothing: noise, bias and a
    25 Hz filter are on) holds ``y(k) + b + v_k`` with ``y(k) = y(k−1) + α (λ_j − y(k−1))`` and
    ``λ_j`` the ground truth of the plant step ``j = N k − 1``, ``[t_k − Δt, t_k)`` (an
    event at ``t_k − Δt`` read the step after it on ~1 % of the ticks)."""
    from drake_coop.sensing.sampling import FORCE_SENSOR_STREAM, white_noise
    from drake_coop.control.timing import lowpass_alpha

    scenario, h, dt, result, steps = _ft_readings_and_step_forces(16.5)
    N = int(round(h / dt))
    for i, robot in enumerate(scenario.robots):
        s = robot.force_sensor
        alpha = 1.0 - math.exp(-2.0 * math.pi * s.cutoff_hz * h)    # exact step invariance
        assert alpha == pytest.approx(lowpass_alpha(s.cutoff_hz, h), rel=1e-15)
        logged = result.logs[robot.name]["lambda_sensor"]
        ticks = logged.shape[0]
        y, expected = 0.0, [s.bias]
        for k in range(1, ticks):
            lam = steps[N * k - 1][i][0]
            y = y + alpha * (lam - y)
            noise = white_noise(s.seed, i, FORCE_SENSOR_STREAM, k, s.noise_std, 1)[0]
            expected.append(y + s.bias + noise)
        expected = np.array(expected)
        held = np.abs(result.logs[robot.name]["lambda_meas"]) > 1.0
        assert held.sum() > 150        # the squeeze is on for well over a second of ticks
        np.testing.assert_allclose(logged, expected, rtol=0, atol=1e-12 * np.abs(expected).max(),
                                   err_msg=robot.name)
