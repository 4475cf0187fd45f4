"""The public control API (``drake_coop.control``) the pydrake way: a user's own plant, default
contexts, ``FixValue``, ``Eval``, forced updates, against closed forms written out here."""

from __future__ import annotations

import re

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

import drake_coop.control as api
from drake_coop.control import (
    AddCooperativeController,
    ArmModel,
    Controller,
    DifferenceVelocity,
    FingerLaw,
    ForceObserver,
    Gains,
    MakeArmControllerPlant,
    MeasuredVelocity,
    NoForceEstimate,
    SensedForce,
    VelocityObserver,
)
from drake_coop.scenario.resources import urdf_dir

H = 0.009
URDF = str(urdf_dir() / "crs_a465_3dof.urdf")
URDF6 = str(urdf_dir() / "coop6_6dof.urdf")
Q0 = np.array([0.0, 0.3, 1.7])
GAINS = Gains()


def _user_plant(urdf=URDF, sampled=False, n_arms=2):
    """A user's plant: ``n_arms`` arms facing each other on the x axis, nothing else."""
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
    if not sampled:
        plant.SetUseSampledOutputPorts(False)
    arms = []
    for i in range(n_arms):
        x, yaw = (-0.65, 0.0) if i % 2 == 0 else (0.65, np.pi)
        (arm,) = Parser(plant, f"arm{i + 1}").AddModels(urdf)
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link", arm),
                         RigidTransform(RotationMatrix.MakeZRotation(yaw), [x, 0.0, 0.1 * i]))
        arms.append(arm)
    plant.Finalize()
    return builder, plant, arms


@pytest.fixture(scope="module")
def law():
    builder, plant, arms = _user_plant(n_arms=1)
    model = ArmModel.from_plant(MakeArmControllerPlant(URDF, plant, arms[0]), "pad",
                                [[-1.0, 0.0, 0.0]], [0.0, 0.0, 0.43])
    return FingerLaw(model, GAINS)


def _pydrake_ports(system) -> tuple[list[str], list[str]]:
    """Input and output port names listed in the class's ``.. pydrake_system::`` block."""
    doc = type(system).__doc__
    block = doc.split(".. pydrake_system::")[1]
    names = {}
    for kind in ("input_ports", "output_ports"):
        part = re.search(kind + r":\n((?:\s+- \w+\n)*)", block)
        names[kind] = re.findall(r"- (\w+)", part.group(1)) if part else []
    return names["input_ports"], names["output_ports"]


def _systems(law):
    return [VelocityObserver(law.n, law.Lambda, law.k_d, H), ForceObserver(law, H), Controller(law, H),
            MeasuredVelocity(3), DifferenceVelocity(3, H), SensedForce(H, law.layout),
            NoForceEstimate(law.layout)]


def test_every_public_name_is_exported_and_documented():
    for name in api.__all__:
        obj = getattr(api, name)
        assert obj.__doc__ and len(obj.__doc__.strip()) > 20, name


def test_pydrake_system_block_lists_every_port_in_order(law):
    for system in _systems(law):
        inputs, outputs = _pydrake_ports(system)
        assert inputs == [system.get_input_port(i).get_name()
                          for i in range(system.num_input_ports())], type(system).__name__
        assert outputs == [system.get_output_port(i).get_name()
                           for i in range(system.num_output_ports())], type(system).__name__


def test_every_port_has_its_get_port_accessor(law):
    for system in _systems(law):
        for i in range(system.num_input_ports()):
            port = system.get_input_port(i)
            accessor = getattr(system, f"get_{port.get_name()}_input_port")
            assert accessor().get_index() == port.get_index()
        for i in range(system.num_output_ports()):
            port = system.get_output_port(i)
            accessor = getattr(system, f"get_{port.get_name()}_output_port")
            assert accessor().get_index() == port.get_index()


def test_velocity_observer_forced_update_is_one_euler_step_of_15_16(law):
    obs = VelocityObserver(law.n, law.Lambda, law.k_d, H)
    ctx = obs.CreateDefaultContext()
    q, q_hat, v_o = Q0, Q0 - [1e-3, -2e-3, 5e-4], np.array([0.1, -0.2, 0.3])
    qddot_r = np.array([0.5, 0.0, -0.4])
    obs.set_initial_state(ctx, q_hat, v_o)
    obs.get_q_input_port().FixValue(ctx, q)
    obs.get_qddot_r_hat_input_port().FixValue(ctx, qddot_r)
    z = q - q_hat
    L, kd = GAINS.Lambda, GAINS.k_d
    xd = obs.AllocateDiscreteVariables()
    obs.CalcForcedDiscreteVariableUpdate(ctx, xd)
    np.testing.assert_allclose(xd.get_vector(0).CopyToVector(),
                               q_hat + H * (v_o + (L + kd) * z), rtol=1e-14)
    np.testing.assert_allclose(xd.get_vector(1).CopyToVector(),
                               v_o + H * (qddot_r + kd * L * z), rtol=1e-14)


def test_force_observer_forced_update_integrates_the_force_error_while_held(law):
    obs = ForceObserver(law, H)
    ctx = obs.CreateDefaultContext()
    ref = np.concatenate([Q0, np.zeros(6), [7.0], [1.0]])
    for port, value in ((obs.get_q_input_port(), Q0), (obs.get_q_hat_input_port(), Q0),
                        (obs.get_qdot_o_input_port(), np.array([0.0, 0.01, -0.02])),
                        (obs.get_reference_input_port(), ref)):
        port.FixValue(ctx, value)
    ctx.SetDiscreteState(0, [0.3])
    lam = obs.get_lambda_hat_output_port().Eval(ctx)
    xd = obs.AllocateDiscreteVariables()
    obs.CalcForcedDiscreteVariableUpdate(ctx, xd)
    np.testing.assert_allclose(xd.get_vector(0).CopyToVector(), 0.3 + H * (lam - 7.0),
                               rtol=1e-14)


def test_force_observer_forced_update_resets_the_integral_in_free_motion(law):
    obs = ForceObserver(law, H)
    ctx = obs.CreateDefaultContext()
    for port, value in ((obs.get_q_input_port(), Q0), (obs.get_q_hat_input_port(), Q0),
                        (obs.get_qdot_o_input_port(), np.zeros(3)),
                        (obs.get_reference_input_port(),
                         np.concatenate([Q0, np.zeros(6), [7.0], [0.0]]))):
        port.FixValue(ctx, value)
    ctx.SetDiscreteState(0, [0.3])
    assert obs.get_lambda_hat_output_port().Eval(ctx)[0] == 0.0
    xd = obs.AllocateDiscreteVariables()
    obs.CalcForcedDiscreteVariableUpdate(ctx, xd)
    assert xd.get_vector(0).GetAtIndex(0) == 0.0


def test_controller_forced_update_latches_gravity_torque_at_rest(law):
    """At rest on the reference in free motion, (13) is g(q): checked against the finite
    differences of the controller plant's potential energy, ``g = ∂V/∂q``."""
    ctrl = Controller(law, H)
    ctx = ctrl.CreateDefaultContext()
    zero = np.zeros(3)
    for port, value in ((ctrl.get_q_input_port(), Q0), (ctrl.get_q_hat_input_port(), Q0),
                        (ctrl.get_qdot_hat_input_port(), zero),
                        (ctrl.get_qdot_o_input_port(), zero),
                        (ctrl.get_lambda_hat_input_port(), [0.0]),
                        (ctrl.get_Delta_F_tilde_input_port(), [0.0]),
                        (ctrl.get_reference_input_port(),
                         np.concatenate([Q0, zero, zero, [0.0], [0.0]]))):
        port.FixValue(ctx, value)
    xd = ctrl.AllocateDiscreteVariables()
    ctrl.CalcForcedDiscreteVariableUpdate(ctx, xd)
    plant = law.model.plant
    pc = plant.CreateDefaultContext()
    eps, g = 1e-6, np.zeros(3)
    for j in range(3):
        V = []
        for sign in (1.0, -1.0):
            plant.SetPositions(pc, Q0 + sign * eps * np.eye(3)[j])
            V.append(plant.CalcPotentialEnergy(pc))
        g[j] = (V[0] - V[1]) / (2 * eps)
    np.testing.assert_allclose(xd.get_vector(0).CopyToVector(), g, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(ctrl.get_tau_output_port().Eval(ctx), zero)  # not yet latched


def test_observer_starts_at_the_first_measured_q_without_set_initial_state():
    """The silent-wrong case first reported: left out, q̂(0) was 0 (a 111 N squeeze for 24 N)."""
    builder, plant, arms = _user_plant(n_arms=1)
    block = AddCooperativeController(
        builder, plant, arms[0], gains=GAINS, period=H, controller_model=URDF, ee_frame="pad",
        normals=[1.0, 0.0, 0.0], contact_point=[0.0, 0.0, 0.43])
    ref = builder.AddSystem(ConstantVectorSource(
        np.concatenate([Q0, np.zeros(6), [0.0], [0.0]])))
    builder.Connect(ref.get_output_port(), block.reference_input)
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(ctx), arms[0], Q0)
    obs = block.velocity_source
    assert np.all(obs.get_q_hat_output_port().Eval(obs.GetMyContextFromRoot(ctx)) == 0.0)
    sim.Initialize()
    np.testing.assert_array_equal(
        obs.get_q_hat_output_port().Eval(obs.GetMyContextFromRoot(ctx)), Q0)


def test_a_given_initial_state_is_kept_by_initialize():
    builder, plant, arms = _user_plant(n_arms=1)
    block = AddCooperativeController(
        builder, plant, arms[0], gains=GAINS, period=H, controller_model=URDF, ee_frame="pad",
        normals=[1.0, 0.0, 0.0], contact_point=[0.0, 0.0, 0.43])
    builder.Connect(builder.AddSystem(ConstantVectorSource(np.zeros(11))).get_output_port(),
                    block.reference_input)
    sim = Simulator(builder.Build())
    ctx = sim.get_mutable_context()
    block.set_initial_state(ctx, Q0 + 0.01)
    sim.Initialize()
    obs = block.velocity_source
    np.testing.assert_array_equal(
        obs.get_q_hat_output_port().Eval(obs.GetMyContextFromRoot(ctx)), Q0 + 0.01)


def test_difference_velocity_starts_at_rest_from_the_first_q():
    dv = DifferenceVelocity(3, H)
    ctx = dv.CreateDefaultContext()
    dv.get_q_input_port().FixValue(ctx, Q0)
    assert np.all(dv.get_qdot_hat_output_port().Eval(ctx) == Q0 / H)   # q(−1) = 0: a jump
    sim = Simulator(dv, ctx)
    sim.Initialize()
    np.testing.assert_array_equal(dv.get_qdot_hat_output_port().Eval(sim.get_context()),
                                  np.zeros(3))


@pytest.mark.parametrize("field, gains, match", [
    ("K_R", Gains(K_R=[120.0, 120.0]), "K_R: 3 diagonal entries"),
    ("K_R", Gains(K_R=[120.0, -1.0, 120.0]), "K_R: every entry"),
    ("Lambda", Gains(Lambda=0.0), "Lambda: must be finite and > 0"),
    ("xi_matrix", Gains(xi_matrix=[[1e-5, 0.0], [0.0, 1e-5]]), "xi_matrix: an 1x1 matrix"),
    ("xi_matrix", Gains(xi_matrix=[[-1e-5]]), "xi_matrix: must be symmetric positive"),
])
def test_wrong_gains_are_refused_naming_the_gain(law, field, gains, match):
    with pytest.raises(ValueError, match=match):
        FingerLaw(law.model, gains)


@pytest.mark.parametrize("period", [0.0, -0.009, float("nan")])
def test_a_bad_period_is_refused_naming_period(law, period):
    for make in (lambda h: VelocityObserver(law.n, law.Lambda, law.k_d, h),
                 lambda h: ForceObserver(law, h), lambda h: Controller(law, h)):
        with pytest.raises(ValueError, match="^period: "):
            make(period)


@pytest.mark.parametrize("normals, match", [
    ([[1.0, 0.0]], "normals: 1 to 3 rows of 3"),
    ([[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], "normals: the 2 rows must be linearly independent"),
    ([[0.0, 0.0, 0.0]], "normals: a row is zero"),
])
def test_bad_normals_are_refused_naming_normals(normals, match):
    builder, plant, arms = _user_plant(n_arms=1)
    with pytest.raises(ValueError, match=match):
        AddCooperativeController(builder, plant, arms[0], gains=GAINS, period=H,
                                 controller_model=URDF, ee_frame="pad", normals=normals,
                                 contact_point=[0.0, 0.0, 0.4])


def test_a_plant_with_sampled_output_ports_is_refused_with_what_to_call():
    builder, plant, arms = _user_plant(sampled=True, n_arms=1)
    with pytest.raises(ValueError, match=r"SetUseSampledOutputPorts\(False\)"):
        AddCooperativeController(builder, plant, arms[0], gains=GAINS, period=H,
                                 controller_model=URDF, ee_frame="pad", normals=[1, 0, 0],
                                 contact_point=[0.0, 0.0, 0.4])


def test_add_wires_q_from_the_plant_and_tau_to_its_actuation():
    builder, plant, arms = _user_plant(n_arms=2)
    blocks = [AddCooperativeController(
        builder, plant, arm, gains=GAINS, period=H, controller_model=URDF, ee_frame="pad",
        normals=[s, 0.0, 0.0], contact_point=[0.0, 0.0, 0.43])
        for arm, s in zip(arms, (-1.0, 1.0))]
    for block in blocks:
        builder.ExportInput(block.reference_input)
    diagram = builder.Build()
    ctx = diagram.CreateDefaultContext()
    pc = plant.GetMyMutableContextFromRoot(ctx)
    for i, arm in enumerate(arms):
        plant.SetPositions(pc, arm, Q0 + 0.01 * i)
        diagram.get_input_port(i).FixValue(ctx, np.zeros(11))
    for i, (block, arm) in enumerate(zip(blocks, arms)):
        q = block.q_input.Eval(block.system.GetMyContextFromRoot(ctx))
        np.testing.assert_array_equal(q, Q0 + 0.01 * i)
        tau = np.full(3, 1.5 + i)
        block.controller.GetMyMutableContextFromRoot(ctx).SetDiscreteState(0, tau)
        np.testing.assert_array_equal(plant.get_actuation_input_port(arm).Eval(pc), tau)


def test_add_builds_a_six_joint_arm_with_two_constraints_and_a_xi_matrix():
    builder, plant, arms = _user_plant(urdf=URDF6, n_arms=1)
    gains = Gains(K_R=[60.0] * 6, xi_matrix=[[1e-5, 0.0], [0.0, 2e-5]])
    block = AddCooperativeController(
        builder, plant, arms[0], gains=gains, period=H, controller_model=URDF6,
        ee_frame="pad", normals=[[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
        contact_point=[0.0, 0.0, 0.4])
    assert (block.law.n, block.law.m) == (6, 2)
    assert block.reference_input.size() == 3 * 6 + 2 + 1
    assert block.lambda_hat_output.size() == 2


def test_add_refuses_a_gain_list_of_the_wrong_length_at_construction():
    builder, plant, arms = _user_plant(urdf=URDF6, n_arms=1)
    with pytest.raises(ValueError, match="^K_R: 6 diagonal entries"):
        AddCooperativeController(builder, plant, arms[0], gains=Gains(), period=H,
                                 controller_model=URDF6, ee_frame="pad", normals=[1, 0, 0],
                                 contact_point=[0.0, 0.0, 0.4])
