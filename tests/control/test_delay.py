"""Delay compensation (:class:`~drake_coop.control.delay.DelayPredictor`) against independent
computations: the arm simulated over the horizon with the same torque (Drake's continuous plant
and its own integrator, not the predictor's formula), forward dynamics with an applied
generalized force, and the control block's wiring."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from drake_coop.control import (
    AddCooperativeController,
    ArmModel,
    DelayPredictor,
    FingerLaw,
    Gains,
    build_control_block,
)
from drake_coop.control.arm_plant import make_arm_controller_plant
from drake_coop.scenario.resources import urdf_dir

H = 0.009
URDF = str(urdf_dir() / "crs_a465_3dof.urdf")
Q0 = np.array([0.1, 0.3, 1.7])
V0 = np.array([0.4, -0.6, 0.9])


@pytest.fixture(scope="module")
def law():
    plant = make_arm_controller_plant(URDF, "base_link")
    model = ArmModel.from_plant(plant, "pad", [[-1.0, 0.0, 0.0]], [0.0, 0.0, 0.43])
    return FingerLaw(model, Gains())


def _predictor(law, horizon, tau, lam=None, q=Q0, v=V0, q_hat=None, qddot_r=None):
    sys = DelayPredictor(law, H, horizon)
    ctx = sys.CreateDefaultContext()
    q_hat = q if q_hat is None else q_hat
    for name, value in (("q", q), ("q_hat", q_hat), ("qdot_hat", v), ("qdot_o", v),
                        ("qddot_r_hat", np.zeros(3) if qddot_r is None else qddot_r),
                        ("tau", tau), ("lambda_hat", np.zeros(law.m) if lam is None else lam)):
        sys.GetInputPort(name).FixValue(ctx, np.asarray(value, dtype=float))
    # latch τ and λ̂ as a tick does (the forced discrete update)
    xd = sys.AllocateDiscreteVariables()
    sys.CalcForcedDiscreteVariableUpdate(ctx, xd)
    ctx.SetDiscreteState(xd)
    return sys, ctx


def _simulate(tau, duration, generalized_force=None):
    """The arm (a separate continuous plant of the same URDF) under constant torque."""
    builder = DiagramBuilder()
    plant = builder.AddSystem(MultibodyPlant(0.0))
    Parser(plant).AddModels(URDF)
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"))
    plant.Finalize()
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    pc = plant.GetMyMutableContextFromRoot(ctx)
    plant.SetPositions(pc, Q0)
    plant.SetVelocities(pc, V0)
    plant.get_actuation_input_port().FixValue(pc, np.asarray(tau, dtype=float))
    if generalized_force is not None:
        plant.get_applied_generalized_force_input_port().FixValue(pc, generalized_force)
    sim.get_mutable_integrator().set_target_accuracy(1e-12)
    sim.AdvanceTo(duration)
    return plant.GetPositions(pc), plant.GetVelocities(pc)


@pytest.mark.parametrize("horizon", [0.001, 0.003, 0.006])
def test_prediction_matches_the_arm_simulated_over_the_horizon(law, horizon):
    tau = np.array([3.0, -20.0, 4.0])
    sys, ctx = _predictor(law, horizon, tau)
    q_sim, v_sim = _simulate(tau, horizon)
    q_p = sys.GetOutputPort("q_p").Eval(ctx)
    v_p = sys.GetOutputPort("qdot_hat_p").Eval(ctx)
    # second order in p: the error is the jerk's p³/6 (and p²/2 in velocity)
    assert np.max(np.abs(q_p - q_sim)) < 2.0 * horizon ** 3 * 100.0
    assert np.max(np.abs(v_p - v_sim)) < 2.0 * horizon ** 2 * 100.0
    # ... and the acceleration term matters at that accuracy (a test that can fail)
    assert np.max(np.abs(Q0 + horizon * V0 - q_sim)) > 20 * np.max(np.abs(q_p - q_sim))
    # q̂ is shifted by the same amount, q̇_o by the same velocity change
    np.testing.assert_allclose(sys.GetOutputPort("q_hat_p").Eval(ctx), q_p, atol=1e-15)
    np.testing.assert_allclose(sys.GetOutputPort("qdot_o_p").Eval(ctx), v_p, atol=1e-15)


def test_constraint_force_enters_the_acceleration(law):
    """``a`` with ``λ̂`` equals Drake's forward dynamics with ``J_φᵀ λ̂`` applied."""
    tau = np.array([1.0, -15.0, 2.0])
    lam = np.array([24.0])
    sys, ctx = _predictor(law, 0.003, tau, lam=lam)
    a = sys.GetOutputPort("acceleration").Eval(ctx)
    plant = make_arm_controller_plant(URDF, "base_link")
    pc = plant.CreateDefaultContext()
    plant.SetPositions(pc, Q0)
    plant.SetVelocities(pc, V0)
    plant.get_actuation_input_port().FixValue(pc, tau)
    plant.get_applied_generalized_force_input_port().FixValue(
        pc, law.model.J_phi(Q0).T @ lam)
    xdot = plant.EvalTimeDerivatives(pc).CopyToVector()
    np.testing.assert_allclose(a, xdot[3:], rtol=1e-9, atol=1e-9)
    without = _predictor(law, 0.003, tau)
    assert np.max(np.abs(without[0].GetOutputPort("acceleration").Eval(without[1]) - a)) > 1.0


def test_observer_is_fed_the_acceleration_weighted_by_the_horizon(law):
    qddot_r = np.array([2.0, -1.0, 0.5])
    sys, ctx = _predictor(law, 0.003, np.array([3.0, -20.0, 4.0]), qddot_r=qddot_r)
    a = sys.GetOutputPort("acceleration").Eval(ctx)
    fed = sys.GetOutputPort("qddot_fed").Eval(ctx)
    np.testing.assert_allclose(fed, a / 3.0 + 2.0 * qddot_r / 3.0, rtol=1e-12)


def test_nothing_latched_predicts_at_constant_velocity(law):
    sys = DelayPredictor(law, H, 0.003)
    ctx = sys.CreateDefaultContext()
    for name in ("q", "q_hat", "qdot_hat", "qdot_o", "qddot_r_hat", "tau"):
        sys.GetInputPort(name).FixValue(ctx, V0 if "dot" in name else Q0)
    sys.GetInputPort("lambda_hat").FixValue(ctx, np.zeros(1))
    np.testing.assert_allclose(sys.GetOutputPort("q_p").Eval(ctx), Q0 + 0.003 * V0, rtol=1e-14)


@pytest.mark.parametrize("horizon", [0.0, -0.001, 0.0091, float("nan"), True])
def test_horizon_out_of_range_is_refused_by_name(law, horizon):
    with pytest.raises(ValueError, match=r"^prediction_horizon: .*\(0, control period"):
        DelayPredictor(law, H, horizon)


def _names(diagram):
    return {s.get_name() for s in diagram.GetSystems()}


def test_block_without_horizon_is_the_papers(law):
    block, *_ = build_control_block("r", law, H)
    assert _names(block) == {"r_velocity_observer", "r_force_observer", "r_controller"}
    block, *_ = build_control_block("r", law, H, prediction_horizon=0.003)
    assert _names(block) == {"r_velocity_observer", "r_force_observer", "r_controller",
                             "r_predictor"}


def _forward_dynamics(q, v, tau):
    plant = make_arm_controller_plant(URDF, "base_link")
    pc = plant.CreateDefaultContext()
    plant.SetPositions(pc, q)
    plant.SetVelocities(pc, v)
    plant.get_actuation_input_port().FixValue(pc, tau)
    return plant.EvalTimeDerivatives(pc).CopyToVector()[3:]


def test_controller_reads_the_predicted_inputs(law):
    """In the block, the tick's torque is the law at the predicted inputs, written out here
    with Drake's forward dynamics of a separate plant for ``a``."""
    block, vel, force, ctrl = build_control_block("r", law, H, prediction_horizon=0.003)
    ctx = block.CreateDefaultContext()
    layout = law.layout
    ref = np.concatenate([Q0 + 0.01, np.zeros(3), np.zeros(3), np.zeros(1), [0.0]])
    block.GetInputPort("q").FixValue(ctx, Q0)
    block.GetInputPort("reference").FixValue(ctx, ref)
    q_hat = Q0 - np.array([1e-3, 2e-3, -1e-3])
    qdot_hat_o = np.array([0.2, -0.1, 0.3])
    vel.set_initial_state(vel.GetMyMutableContextFromRoot(ctx), q_hat, qdot_hat_o)
    pred = block.GetSubsystemByName("r_predictor")
    tau_prev = np.array([2.0, -18.0, 3.0])
    pred.GetMyMutableContextFromRoot(ctx).SetDiscreteState(0, tau_prev)
    pred.GetMyMutableContextFromRoot(ctx).SetDiscreteState(2, [1.0])
    z = Q0 - q_hat
    qdot_hat = qdot_hat_o + (law.Lambda + law.k_d) * z
    qdot_o = qdot_hat_o + law.k_d * z
    p = 0.003
    a = _forward_dynamics(Q0, qdot_hat, tau_prev)
    shift = p * qdot_hat + 0.5 * p * p * a
    expected = law.control(Q0 + shift, q_hat + shift, qdot_hat + p * a, qdot_o + p * a,
                           np.zeros(1), np.zeros(1), layout.unpack(ref))["tau"]
    got = ctrl.next_tau(ctrl.GetMyContextFromRoot(ctx))
    np.testing.assert_allclose(got, expected, rtol=1e-8, atol=1e-8)
    plain = law.control(Q0, q_hat, qdot_hat, qdot_o, np.zeros(1), np.zeros(1),
                        layout.unpack(ref))["tau"]
    assert np.max(np.abs(got - plain)) > 0.1
    # the velocity observer is fed the blend of a and the controller's latched q̈̂_r
    qddot_r = ctrl.GetOutputPort("qddot_r_hat").Eval(ctrl.GetMyContextFromRoot(ctx))
    fed = vel.get_qddot_r_hat_input_port().Eval(vel.GetMyContextFromRoot(ctx))
    np.testing.assert_allclose(fed, a / 3.0 + 2.0 * qddot_r / 3.0, rtol=1e-8, atol=1e-8)


def test_add_cooperative_controller_takes_the_horizon():
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
    plant.SetUseSampledOutputPorts(False)
    (arm,) = Parser(plant, "arm1").AddModels(URDF)
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link", arm),
                     RigidTransform(RotationMatrix.MakeZRotation(0.0), [-0.65, 0.0, 0.0]))
    plant.Finalize()
    handles = AddCooperativeController(
        builder, plant, arm, gains=Gains(), period=H, controller_model=URDF, ee_frame="pad",
        normals=[[-1.0, 0.0, 0.0]], contact_point=[0.0, 0.0, 0.43], prediction_horizon=0.003)
    assert any(n.endswith("_predictor") for n in _names(handles.system))
    with pytest.raises(ValueError, match="prediction_horizon"):
        AddCooperativeController(
            builder, plant, arm, gains=Gains(), period=H, controller_model=URDF,
            ee_frame="pad", normals=[[-1.0, 0.0, 0.0]], contact_point=[0.0, 0.0, 0.43],
            prediction_horizon=0.02, name="again", connect_actuation=False)


@pytest.mark.parametrize("value, message", [
    (0.02, r"robots\[0\]\.timing\.prediction_horizon must be <= control_period"),
    (0.0, r"robots\[0\]\.timing\.prediction_horizon"),
    (-0.001, r"robots\[0\]\.timing\.prediction_horizon")])
def test_scenario_refuses_a_horizon_by_name(value, message):
    from drake_coop.scenario.loading import dump_scenario, load_scenario
    from drake_coop.scenario.schema import ScenarioError

    s = load_scenario()
    s.robots[0].timing.prediction_horizon = value
    with pytest.raises(ScenarioError, match=message):
        load_scenario(data=dump_scenario(s))


def test_scenario_default_has_no_predictor():
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run
    from drake_coop.scenario.loading import load_scenario

    s = load_scenario()
    assert all(r.timing.prediction_horizon is None for r in s.robots)
    names = {sys.get_name() for r in build_experiment(plan_run(s), log=False).robots
             for sys in r.control.GetSystems()}
    assert not any(n.endswith("_predictor") for n in names)
    s.robots[1].timing.prediction_horizon = 0.003
    names = {sys.get_name() for r in build_experiment(plan_run(s), log=False).robots
             for sys in r.control.GetSystems()}
    assert [n for n in names if n.endswith("_predictor")] == ["robot2_predictor"]
