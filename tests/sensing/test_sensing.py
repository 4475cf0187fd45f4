"""The sensor and actuator models of :mod:`drake_coop.sensing`, each against a closed form.

Each system is driven tick by tick as the simulator does it: at ``t_k`` the outputs are read
(with the inputs of that instant), then the periodic update is applied.
"""

import math

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import DiagramBuilder

from drake_coop.plant.arms import Arm
from drake_coop.scenario import Encoders as EncoderSettings
from drake_coop.scenario import ForceSensorModel, ModelError, paper_robots
from drake_coop.sensing.actuators import FRICTION_VELOCITY, add_actuators
from drake_coop.sensing.encoders import Encoders
from drake_coop.sensing.force_sensor import FTSensor
from drake_coop.plant.model_error import add_payload, scaled_urdf_text

H = 0.009
DT = 0.001


def _step(system, context):
    """Apply the system's periodic discrete update at the context's time."""
    context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))


def _encoder_readings(settings, q_of_k, ticks, q0=None, robot_index=0):
    """Outputs of an Encoders system over ``ticks`` with input ``q_of_k(k)``."""
    enc = Encoders(3, H, settings, robot_index)
    ctx = enc.CreateDefaultContext()
    enc.set_initial_state(ctx, q_of_k(0) if q0 is None else q0)
    out = []
    for k in range(ticks):
        ctx.SetTime(k * H)
        enc.GetInputPort("state").FixValue(ctx, np.concatenate([q_of_k(k), np.zeros(3)]))
        out.append(enc.GetOutputPort("q").Eval(ctx).copy())
        _step(enc, ctx)
    return np.array(out)


# --------------------------------------------------------------------------- encoders

def test_ideal_encoder_passes_the_current_position_bit_for_bit():
    rng = np.random.default_rng(3)
    q = rng.normal(size=(20, 3))
    np.testing.assert_array_equal(_encoder_readings(EncoderSettings(), lambda k: q[k], 20), q)


def test_encoder_holds_the_tick_reading_between_ticks():
    enc = Encoders(3, H, EncoderSettings(counts_per_rev=1000))
    ctx = enc.CreateDefaultContext()
    ctx.SetTime(2 * H)
    enc.GetInputPort("state").FixValue(ctx, [0.1, 0.2, 0.3, 0, 0, 0])
    at_tick = enc.GetOutputPort("q").Eval(ctx).copy()
    _step(enc, ctx)
    ctx.SetTime(2 * H + 0.004)
    enc.GetInputPort("state").FixValue(ctx, [0.5, 0.6, 0.7, 0, 0, 0])   # moved since the tick
    np.testing.assert_array_equal(enc.GetOutputPort("q").Eval(ctx), at_tick)


def test_quantization_on_a_ramp_is_the_nearest_count():
    c = 4096
    delta = 2 * math.pi / c
    slope = 0.3712 * delta       # 0.3712 counts per tick: every rounding case, no exact tie
    ramp = lambda k: np.array([slope * k, -slope * k, 1.0 + slope * k])
    r = _encoder_readings(EncoderSettings(counts_per_rev=c), ramp, 200)
    exact = np.array([ramp(k) for k in range(200)])
    counts = r / delta
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-9)   # whole counts only
    assert np.all(np.abs(r - exact) <= delta / 2 + 1e-12)
    # Closed form for joint 1: the count of tick k is floor(0.3712 k + 1/2).
    expected = np.floor(0.3712 * np.arange(200) + 0.5)
    np.testing.assert_array_equal(np.round(counts[:, 0]), expected)


def test_seeded_noise_is_reproducible_and_has_its_standard_deviation():
    std, ticks = 2e-4, 4000
    settings = EncoderSettings(noise_std=std, seed=11)
    const = lambda k: np.array([0.1, 0.2, 0.3])
    a = _encoder_readings(settings, const, ticks)
    b = _encoder_readings(settings, const, ticks)
    np.testing.assert_array_equal(a, b)                       # same seed, same noise
    w = a - const(0)
    assert np.all(np.abs(w.std(axis=0) / std - 1) < 0.05)
    assert np.all(np.abs(w.mean(axis=0)) < 4 * std / math.sqrt(ticks))
    lag1 = [np.corrcoef(w[1:, j], w[:-1, j])[0, 1] for j in range(3)]
    assert np.all(np.abs(lag1) < 4 / math.sqrt(ticks))       # white: uncorrelated ticks
    other_seed = _encoder_readings(EncoderSettings(noise_std=std, seed=12), const, 50)
    other_robot = _encoder_readings(settings, const, 50, robot_index=1)
    assert not np.allclose(other_seed, a[:50]) and not np.allclose(other_robot, a[:50])


def test_delay_shifts_the_readings_by_whole_samples():
    d = 3
    q = np.random.default_rng(5).normal(size=(30, 3))
    r = _encoder_readings(EncoderSettings(delay_samples=d), lambda k: q[k], 30, q0=q[0])
    np.testing.assert_array_equal(r[d:], q[:-d])
    np.testing.assert_array_equal(r[:d], np.tile(q[0], (d, 1)))   # the reading at rest


# --------------------------------------------------------------------------- F/T sensor

def _ft_readings(settings, lam_of_k, ticks, robot_index=0):
    """``λ_s(k)``: the sensor is read at ``t_k − 3Δt/2`` (its own event time) and output at
    ``t_k``."""
    ft = FTSensor(H, DT, settings, robot_index)
    ctx = ft.CreateDefaultContext()
    out = []
    for k in range(ticks):
        ctx.SetTime(k * H)
        out.append(ft.GetOutputPort("lambda_sensor").Eval(ctx)[0])
        ctx.SetTime((k + 1) * H - 1.5 * DT)
        ft.GetInputPort("lambda_true").FixValue(ctx, [lam_of_k(k + 1)])
        _step(ft, ctx)
    return np.array(out)


def test_force_sensor_low_pass_step_response_and_bias():
    f_c, bias, step = 5.0, 0.3, 10.0
    r = _ft_readings(ForceSensorModel(bias=bias, cutoff_hz=f_c), lambda k: step, 60)
    k = np.arange(60)
    # First-order lag T dy/dt = u − y sampled exactly: y(t_k) = u (1 − exp(−t_k / T)).
    expected = step * (1 - np.exp(-2 * math.pi * f_c * k * H)) + bias
    np.testing.assert_allclose(r, expected, rtol=1e-12, atol=1e-12)


def test_force_sensor_without_filter_reads_the_last_force_before_the_tick():
    lam = lambda k: 3.0 * k
    r = _ft_readings(ForceSensorModel(), lam, 10)
    np.testing.assert_array_equal(r[1:], [lam(k) for k in range(1, 10)])
    assert r[0] == 0.0


def test_force_sensor_noise_is_seeded_with_its_standard_deviation():
    settings = ForceSensorModel(noise_std=0.05, seed=4)
    a = _ft_readings(settings, lambda k: 20.0, 4000)
    np.testing.assert_array_equal(a, _ft_readings(settings, lambda k: 20.0, 4000))
    w = a[1:] - 20.0
    assert abs(w.std() / 0.05 - 1) < 0.05 and abs(w.mean()) < 4 * 0.05 / math.sqrt(w.size)


def test_force_sensor_reads_half_a_plant_step_before_the_plants_last_step():
    """The read lies mid-way between two plant updates (t_k − 2Δt, t_k − Δt), where the live
    port is the step [t_k − Δt, t_k); no rounding of ``offset + k h`` can move it across one.
    The whole-run check of every tick is in test_sensing_runs."""
    timing = FTSensor(H, DT, ForceSensorModel()).GetUniquePeriodicDiscreteUpdateAttribute()
    assert timing.period_sec() == H
    assert timing.offset_sec() == pytest.approx(H - 1.5 * DT, abs=1e-15)


def test_force_sensor_with_the_plant_step_as_period_reads_at_the_previous_tick():
    """h = Δt: no plant update lies between two ticks; the read is at t_{k−1} (offset 0)."""
    ft = FTSensor(DT, DT, ForceSensorModel())
    timing = ft.GetUniquePeriodicDiscreteUpdateAttribute()
    assert (timing.period_sec(), timing.offset_sec()) == (DT, 0.0)
    assert ft.read_lead == DT


# --------------------------------------------------------------------------- actuators

def _actuated(limits, friction, tau_cmd, v):
    b = DiagramBuilder()
    from pydrake.systems.primitives import ConstantVectorSource

    state = b.AddSystem(ConstantVectorSource(np.concatenate([np.zeros(3), v])))
    sat, applied = add_actuators(b, "robot1", 3, limits, friction, state.get_output_port())
    cmd = b.AddSystem(ConstantVectorSource(tau_cmd))
    b.Connect(cmd.get_output_port(), sat.get_input_port())
    b.ExportOutput(applied, "applied")
    b.ExportOutput(sat.get_output_port(), "motor")
    d = b.Build()
    ctx = d.CreateDefaultContext()
    return d.GetOutputPort("motor").Eval(ctx), d.GetOutputPort("applied").Eval(ctx)


def test_saturation_clamps_each_joint_to_its_limit():
    motor, applied = _actuated([10.0, 20.0, 5.0], [0.0] * 3, np.array([12.0, -25.0, 4.0]),
                               np.zeros(3))
    np.testing.assert_array_equal(motor, [10.0, -20.0, 4.0])
    np.testing.assert_array_equal(applied, motor)


def test_no_limits_pass_the_command_unchanged():
    tau = np.array([1e300, -3.25, 7.0])
    motor, applied = _actuated(None, [0.0] * 3, tau, np.zeros(3))
    np.testing.assert_array_equal(motor, tau)
    np.testing.assert_array_equal(applied, tau)


def test_coulomb_friction_opposes_the_velocity():
    f_c, v = np.array([2.0, 1.0, 0.5]), np.array([0.5, -0.5, FRICTION_VELOCITY])
    _, applied = _actuated(None, f_c, np.array([1.0, 1.0, 1.0]), v)
    expected = 1.0 - f_c * np.array([math.tanh(50.0), -math.tanh(50.0), math.tanh(1.0)])
    np.testing.assert_allclose(applied, expected, rtol=1e-15)


# --------------------------------------------------------------------------- model error

def _parsed(text):
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModelsFromString(text, "urdf")
    plant.Finalize()
    return plant


@pytest.mark.parametrize("robot", paper_robots(), ids=lambda r: r.model)
def test_model_error_scales_the_parsed_masses_inertias_rotors_and_damping(robot):
    text = Arm(robot).urdf_path.read_text()
    error = ModelError(mass_scale=1.3, inertia_scale=0.8, damping_scale=2.5)
    a, b = _parsed(text), _parsed(scaled_urdf_text(text, error))
    names = ["link1", "link2", "link3", "force_sensor", "pad"]
    for name in names:
        ba, bb = a.GetBodyByName(name), b.GetBodyByName(name)
        assert bb.default_mass() == pytest.approx(1.3 * ba.default_mass(), rel=1e-14)
        # URDF inertias are about the centre of mass: the rotational part scales by 0.8
        Ia = ba.default_rotational_inertia().CopyToFullMatrix3()
        Ib = bb.default_rotational_inertia().CopyToFullMatrix3()
        ma, mb = ba.default_mass(), bb.default_mass()
        c = ba.default_com()
        shift = np.dot(c, c) * np.eye(3) - np.outer(c, c)       # parallel-axis term
        np.testing.assert_allclose(Ib - mb * shift, 0.8 * (Ia - ma * shift), rtol=1e-12,
                                   atol=1e-15)
    for j in ("joint1", "joint2", "joint3"):
        assert b.GetJointByName(j).default_damping() == pytest.approx(
            2.5 * a.GetJointByName(j).default_damping(), rel=1e-14)
    for i in range(a.num_actuators()):
        ra = a.get_joint_actuator(a.GetJointActuatorIndices()[i]).default_rotor_inertia()
        rb = b.get_joint_actuator(b.GetJointActuatorIndices()[i]).default_rotor_inertia()
        assert rb == pytest.approx(0.8 * ra, rel=1e-14)


def test_payload_is_welded_at_the_flange_and_adds_its_mass():
    robot = paper_robots()[0]
    plant = MultibodyPlant(0.0)
    (inst,) = Parser(plant).AddModels(str(Arm(robot).urdf_path))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"))
    body = add_payload(plant, inst, 1.5)
    plant.Finalize()
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, [0.2, 0.4, 0.9])
    X_payload = plant.EvalBodyPoseInWorld(ctx, body)
    X_sensor = plant.EvalBodyPoseInWorld(ctx, plant.GetBodyByName("force_sensor"))
    np.testing.assert_allclose(X_payload.translation(), X_sensor.translation(), atol=1e-14)
    plain = MultibodyPlant(0.0)
    Parser(plain).AddModels(str(Arm(robot).urdf_path))
    plain.WeldFrames(plain.world_frame(), plain.GetFrameByName("base_link"))
    plain.Finalize()
    before = plain.CalcTotalMass(plain.CreateDefaultContext())
    assert plant.CalcTotalMass(ctx) == pytest.approx(before + 1.5, rel=1e-14)
    nothing = MultibodyPlant(0.0)
    (inst,) = Parser(nothing).AddModels(str(Arm(robot).urdf_path))
    assert add_payload(nothing, inst, 0.0) is None and nothing.num_bodies() == plain.num_bodies()
