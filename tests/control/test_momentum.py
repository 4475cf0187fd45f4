"""The generalized-momentum observer (force_source: momentum) against independent references.

* closed form: an arm at rest on Drake's plant, held against a known constant force on its end
  effector, so that ``τ_ext = J_φᵀ λ``: the estimate converges as ``1 − (1 − h K_O)^k``;
* the identity behind it, ``ṗ = τ − β(q, q̇) + τ_ext``, by finite differences of ``H q̇``
  against Drake's inverse dynamics;
* a closed-loop run against the ground-truth force sensor.
"""

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import (
    AddMultibodyPlant,
    ExternallyAppliedSpatialForce,
    MultibodyPlantConfig,
)
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantValueSource, ConstantVectorSource, MatrixGain
from pydrake.common.value import AbstractValue

from drake_coop.plant.arms import arm_model
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.momentum import MomentumObserver
from drake_coop.plant.arms import Arm
from drake_coop.scenario.loading import default_scenario, load_scenario
from drake_coop.scenario.schema import ScenarioError

H_PERIOD = 0.009


def _arm(i):
    sc = default_scenario()
    return Arm(sc.robots[i], sc.task)


@pytest.mark.parametrize("robot", [0, 1])
@pytest.mark.parametrize("gain", [30.0, 100.0])
def test_arm_at_rest_pushed_by_a_constant_force_converges_at_the_rate_of_the_gain(robot, gain):
    arm = _arm(robot)
    model = arm_model(arm)
    n = model.n
    q0 = arm.ik(arm.c)                    # the grasp posture
    lam = 25.0                            # N, squeeze along the constraint's normal
    F = arm.N.T @ np.array([lam])         # the object's force on the end effector (palm frame)
    b = DiagramBuilder()
    plant, _ = AddMultibodyPlant(MultibodyPlantConfig(time_step=0.001,
                                                      discrete_contact_approximation="sap"), b)
    (inst,) = Parser(plant).AddModels(str(arm.urdf_path))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(arm.base_frame),
                     RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base))
    plant.Finalize()
    # Holding torque from the plant itself: τ = −τ_g(q0) − J_xᵀ F keeps the arm at rest.
    ctx = plant.CreateDefaultContext()
    plant.SetPositions(ctx, q0)
    ee = plant.GetFrameByName(arm.ee_frame)
    Jx = plant.CalcJacobianTranslationalVelocity(ctx, JacobianWrtVariable.kV, ee, np.zeros(3),
                                                 plant.world_frame(), plant.world_frame())
    tau = -plant.CalcGravityGeneralizedForces(ctx) - Jx.T @ F
    push = ExternallyAppliedSpatialForce()
    push.body_index = ee.body().index()
    push.p_BoBq_B = ee.GetFixedPoseInBodyFrame().translation()
    push.F_Bq_W = SpatialForce(np.zeros(3), F)
    forces = b.AddSystem(ConstantValueSource(AbstractValue.Make([push])))
    b.Connect(forces.get_output_port(), plant.get_applied_spatial_force_input_port())
    torque = b.AddSystem(ConstantVectorSource(tau))
    b.Connect(torque.get_output_port(), plant.get_actuation_input_port())
    layout = ReferenceLayout(n, 1)
    obs = b.AddSystem(MomentumObserver(model, layout, H_PERIOD, gain))
    select_q = b.AddSystem(MatrixGain(np.hstack([np.eye(n), np.zeros((n, n))])))
    select_v = b.AddSystem(MatrixGain(np.hstack([np.zeros((n, n)), np.eye(n)])))
    b.Connect(plant.get_state_output_port(), select_q.get_input_port())
    b.Connect(plant.get_state_output_port(), select_v.get_input_port())
    b.Connect(select_q.get_output_port(), obs.get_q_input_port())
    b.Connect(select_v.get_output_port(), obs.get_qdot_hat_input_port())
    b.Connect(torque.get_output_port(), obs.get_tau_input_port())
    ref = b.AddSystem(ConstantVectorSource(np.concatenate([q0, np.zeros(2 * n), [10.0, 1.0]])))
    b.Connect(ref.get_output_port(), obs.get_reference_input_port())
    diagram = b.Build()
    sim = Simulator(diagram)
    root = sim.get_mutable_context()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(root), q0)
    octx = obs.GetMyContextFromRoot(root)
    tau_ext = Jx.T @ F                    # J_φᵀ λ
    for k in range(1, 40, 3):
        sim.AdvanceTo(k * H_PERIOD)       # k updates done, at t_0 … t_{k−1}
        factor = 1.0 - (1.0 - H_PERIOD * gain) ** k
        np.testing.assert_allclose(obs.get_tau_ext_hat_output_port().Eval(octx),
                                   factor * tau_ext, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(obs.get_lambda_hat_output_port().Eval(octx),
                                   [factor * lam], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(obs.get_O_F_ext_hat_output_port().Eval(octx),
                                   factor * F, rtol=1e-6, atol=1e-6)
    v = plant.GetVelocities(plant.GetMyContextFromRoot(root))
    assert np.max(np.abs(v)) < 1e-9       # the arm did stay at rest


def test_momentum_rate_is_torque_minus_beta_by_finite_differences():
    arm = _arm(0)
    model = arm_model(arm)
    obs = MomentumObserver(model, ReferenceLayout(3, 1), H_PERIOD, 50.0)
    rng = np.random.default_rng(3)
    plant = model.plant
    ctx = plant.CreateDefaultContext()
    for _ in range(5):
        q0, v0, a = rng.uniform(-1, 1, 3), rng.uniform(-2, 2, 3), rng.uniform(-3, 3, 3)

        def p(t):
            return obs.momentum(q0 + v0 * t + 0.5 * a * t * t, v0 + a * t)

        eps = 1e-5
        pdot = (p(eps) - p(-eps)) / (2 * eps)
        plant.SetPositions(ctx, q0)
        plant.SetVelocities(ctx, v0)
        f = MultibodyForces(plant)
        plant.CalcForceElementsContribution(ctx, f)      # gravity and joint damping
        tau = plant.CalcInverseDynamics(ctx, a, f)       # the torque that produces a, free arm
        np.testing.assert_allclose(pdot, tau - obs.beta(q0, v0), rtol=1e-6, atol=1e-6)


def test_the_estimate_does_not_depend_on_the_torque_of_the_same_tick():
    arm = _arm(0)
    obs = MomentumObserver(arm_model(arm), ReferenceLayout(3, 1), H_PERIOD, 50.0)
    tau = obs.get_tau_input_port().get_index()
    for name in ("tau_ext_hat", "O_F_ext_hat", "lambda_hat", "Delta_F_tilde"):
        assert not obs.HasDirectFeedthrough(tau, obs.GetOutputPort(name).get_index())


def test_a_forced_update_on_a_default_context_takes_the_first_tick_of_the_closed_form():
    # pydrake's unit-test idiom: FixValue the inputs, CalcForcedDiscreteVariableUpdate. An arm
    # at rest whose commanded torque is g(q) − τ_ext (statics under a constant external torque):
    # r(1) = h K_O τ_ext, the k = 1 term of r(k) = (1 − (1 − h K_O)^k) τ_ext.
    arm = _arm(0)
    model, gain = arm_model(arm), 50.0
    layout = ReferenceLayout(3, 1)
    obs = MomentumObserver(model, layout, H_PERIOD, gain)
    context = obs.CreateDefaultContext()
    q = np.array([0.1, 0.6, -0.4])
    tau_ext = np.array([1.5, -2.0, 0.7])
    obs.get_q_input_port().FixValue(context, q)
    obs.get_qdot_hat_input_port().FixValue(context, np.zeros(3))
    obs.get_tau_input_port().FixValue(context, model.g(q) - tau_ext)
    obs.get_reference_input_port().FixValue(context, np.zeros(layout.size))
    np.testing.assert_array_equal(obs.get_tau_ext_hat_output_port().Eval(context), np.zeros(3))
    update = obs.AllocateDiscreteVariables()
    obs.CalcForcedDiscreteVariableUpdate(context, update)
    context.SetDiscreteState(update)
    np.testing.assert_allclose(obs.get_tau_ext_hat_output_port().Eval(context),
                               H_PERIOD * gain * tau_ext, rtol=1e-12, atol=1e-12)


def test_momentum_gain_beyond_one_over_h_is_rejected_with_the_field_named():
    text = ("robots:\n- {name: robot1, force_source: momentum, gains: {momentum_gain: 200.0}}\n"
            "- {name: robot2, model: crs_a255, base_xyz: [1.16, 0, 0], base_yaw_deg: 180,"
            " contact_xy: [0.8192, 0], normals: [[1, 0, 0]], home: [0.9, 0, 0.6]}\n")
    with pytest.raises(ScenarioError, match=r"robots\[0\]\.gains\.momentum_gain"):
        load_scenario(data=text)
    ok = load_scenario(data=text.replace("200.0", "100.0"))
    assert ok.robots[0].force_source == "momentum"


@pytest.mark.slow           # 19 s of the paper's run: an end-to-end run (CI's slow subset)
def test_momentum_estimate_follows_the_ground_truth_sensor_in_a_run():
    from drake_coop.experiment.simulate import simulate

    sc = default_scenario()
    for r in sc.robots:
        r.force_source = "momentum"
    result = simulate(sc, t_end=19.0)
    assert result.ok
    for name in ("robot1", "robot2"):
        log = result.logs[name]
        t = log["t"]
        sel = (t > 16.0) & (t < 19.0)           # held, squeeze ramping up 3.2 N/s
        err = log["lambda_hat"][sel] - log["lambda_meas"][sel]
        assert np.sqrt(np.mean(err ** 2)) < 0.5, name   # N, on 3–13 N


def test_momentum_control_block_reads_encoders_and_reference_only():
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run

    sc = default_scenario()
    sc.robots[0].force_source = "momentum"
    exp = build_experiment(plan_run(sc), log=False)
    rs = exp.robots[0]
    inner = {s.get_name() for s in rs.control.GetSystems()}
    assert inner == {"robot1_velocity_observer", "robot1_momentum_observer", "robot1_controller"}
    ports = {rs.control.get_input_port(i).get_name() for i in range(rs.control.num_input_ports())}
    assert ports == {"q", "reference"}            # no plant state, no measured force
    outputs = {rs.control.get_output_port(i).get_name()
               for i in range(rs.control.num_output_ports())}
    assert {"tau_ext_hat", "O_F_ext_hat", "lambda_hat"} <= outputs
