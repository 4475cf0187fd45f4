"""Each LeafSystem alone, one behaviour per test (in the style of pydrake's systems tests).

Inputs are fixed with ``FixValue``; outputs and one discrete update are compared with the
equations written out here.
"""

import numpy as np
import pytest

from drake_coop.plant.arms import arm_model
from drake_coop.control.controller import Controller
from drake_coop.control.finger import FingerLaw
from drake_coop.control.observers import ForceObserver, VelocityObserver
from drake_coop.control.sources import MeasuredVelocity
from drake_coop.plant.arms import Arm
from drake_coop.scenario import paper_robots

H = 0.009
ROBOT = paper_robots()[0]
G = ROBOT.gains


@pytest.fixture(scope="module")
def law():
    return FingerLaw(arm_model(Arm(ROBOT)), G)


@pytest.fixture(scope="module")
def posture():
    arm = Arm(ROBOT)
    q = arm.ik([arm.b, 0.01, 0.56])
    return q


def _reference(q_d, held, lam_d=12.0, moving=True):
    qdot_d = np.array([0.01, -0.02, 0.03]) if moving else np.zeros(3)
    qddot_d = np.array([0.1, 0.0, -0.1]) if moving else np.zeros(3)
    return np.concatenate([q_d, qdot_d, qddot_d, [lam_d], [float(held)]])


def _update(system, context):
    """The state after the system's periodic discrete update at the context's time (all its
    discrete state groups, concatenated)."""
    values = system.EvalUniquePeriodicDiscreteUpdate(context)
    return np.concatenate([values.get_vector(i).CopyToVector()
                           for i in range(values.num_groups())])


def test_velocity_observer_outputs_follow_15_and_8(law, posture):
    obs = VelocityObserver(law.n, law.Lambda, law.k_d, H)
    ctx = obs.CreateDefaultContext()
    q_hat, qdot_hat_o = posture - 1e-3, np.array([0.1, -0.2, 0.3])
    obs.set_initial_state(ctx, q_hat, qdot_hat_o)
    obs.GetInputPort("q").FixValue(ctx, posture)
    obs.GetInputPort("qddot_r_hat").FixValue(ctx, np.zeros(3))
    z = posture - q_hat
    np.testing.assert_allclose(obs.GetOutputPort("q_hat").Eval(ctx), q_hat)
    np.testing.assert_allclose(obs.GetOutputPort("qdot_hat").Eval(ctx),
                               qdot_hat_o + (G.Lambda + G.k_d) * z)
    np.testing.assert_allclose(obs.GetOutputPort("qdot_o").Eval(ctx), qdot_hat_o + G.k_d * z)


def test_velocity_observer_update_is_an_euler_step_of_15_16(law, posture):
    obs = VelocityObserver(law.n, law.Lambda, law.k_d, H)
    ctx = obs.CreateDefaultContext()
    q_hat, qdot_hat_o = posture + 2e-3, np.array([0.05, 0.0, -0.1])
    qddot_r = np.array([0.3, -0.1, 0.2])
    obs.set_initial_state(ctx, q_hat, qdot_hat_o)
    obs.GetInputPort("q").FixValue(ctx, posture)
    obs.GetInputPort("qddot_r_hat").FixValue(ctx, qddot_r)
    z = posture - q_hat
    expected = np.concatenate([q_hat + H * (qdot_hat_o + G.Lambda * z + G.k_d * z),
                               qdot_hat_o + H * (qddot_r + G.k_d * G.Lambda * z)])
    np.testing.assert_allclose(_update(obs, ctx), expected, rtol=0, atol=1e-15)


def test_force_observer_estimate_is_22(law, posture):
    fo = ForceObserver(law, H)
    ctx = fo.CreateDefaultContext()
    DF = 0.7
    ctx.SetDiscreteState(0, [DF])
    q_hat = posture - np.array([1e-4, 2e-4, -1e-4])
    qdot_o = np.array([0.01, 0.02, -0.03])
    ref = _reference(posture + 1e-3, held=True)
    for name, value in (("q", posture), ("q_hat", q_hat), ("qdot_o", qdot_o),
                        ("reference", ref)):
        fo.GetInputPort(name).FixValue(ctx, value)
    model = law.model
    J = model.J_phi(posture)[0]
    Jp = J / (J @ J)
    Q = np.eye(3) - np.outer(Jp, J)
    qdot_r = (Q @ (ref[3:6] - G.Lambda * (q_hat - ref[0:3]))
              + Jp * (-G.beta * model.phi(posture) + G.xi * DF))
    expected = (Jp @ np.diag(G.K_R) @ (qdot_o - qdot_r) - G.k_F * DF) / (1 + G.zeta) + ref[9]
    assert fo.GetOutputPort("lambda_hat").Eval(ctx)[0] == pytest.approx(expected, abs=1e-12)
    # ΔF̃ integrates Δλ̃ = λ̂ − λ_d.
    assert _update(fo, ctx)[0] == pytest.approx(DF + H * (expected - ref[9]), abs=1e-14)


def test_force_observer_is_silent_and_reset_in_free_motion(law, posture):
    fo = ForceObserver(law, H)
    ctx = fo.CreateDefaultContext()
    ctx.SetDiscreteState(0, [3.0])
    for name, value in (("q", posture), ("q_hat", posture), ("qdot_o", np.ones(3)),
                        ("reference", _reference(posture, held=False))):
        fo.GetInputPort(name).FixValue(ctx, value)
    assert fo.GetOutputPort("lambda_hat").Eval(ctx)[0] == 0.0
    assert _update(fo, ctx)[0] == 0.0
    assert fo.GetOutputPort("Delta_F_tilde").Eval(ctx)[0] == 3.0   # state until the update


def _controller_context(law, posture, t):
    ctrl = Controller(law, H, tau0=np.array([1.0, 2.0, 3.0]))
    ctx = ctrl.CreateDefaultContext()
    ctx.SetTime(t)
    for name, value in (("q", posture), ("q_hat", posture), ("qdot_hat", np.zeros(3)),
                        ("qdot_o", np.zeros(3)), ("lambda_hat", [12.0]),
                        ("Delta_F_tilde", [0.0]),
                        ("reference", _reference(posture, True, moving=False))):
        ctrl.GetInputPort(name).FixValue(ctx, value)
    return ctrl, ctx


def test_controller_latches_the_law_of_the_tick_at_its_update(law, posture):
    """Before the tick's update the port holds the previous torque (τ0 here); the periodic
    unrestricted update at t_k latches (13) at the tick's inputs, with the tick index."""
    from pydrake.systems.analysis import Simulator

    ctrl, ctx = _controller_context(law, posture, 5 * H)
    np.testing.assert_array_equal(ctrl.GetOutputPort("tau").Eval(ctx), [1.0, 2.0, 3.0])
    tau = ctrl.next_tau(ctx).copy()
    qddot = ctrl.terms(ctx)["qddot_r_hat"].copy()
    # At rest on the reference with λ̂ = λ_d, (13) reduces to g(q) − J_φᵀ λ_d (+ the β term).
    model = law.model
    np.testing.assert_allclose(
        tau, model.g(posture) - model.J_phi(posture)[0] * 12.0, rtol=0, atol=1e-6)
    sim = Simulator(ctrl, ctx)
    sim.AdvanceTo(5 * H + H / 2)
    np.testing.assert_array_equal(ctrl.GetOutputPort("tau").Eval(ctx), tau)
    np.testing.assert_array_equal(ctrl.GetOutputPort("qddot_r_hat").Eval(ctx), qddot)
    assert ctrl.latched_tick(ctx) == 5


def test_controller_holds_the_latched_torque_between_ticks(law, posture):
    ctrl, ctx = _controller_context(law, posture, 5 * H + 0.003)
    np.testing.assert_array_equal(ctrl.GetOutputPort("tau").Eval(ctx), [1.0, 2.0, 3.0])


def test_measured_velocity_baseline_passes_the_plant_state_on():
    mv = MeasuredVelocity(3)
    ctx = mv.CreateDefaultContext()
    mv.GetInputPort("state").FixValue(ctx, [1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    np.testing.assert_array_equal(mv.GetOutputPort("q_hat").Eval(ctx), [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(mv.GetOutputPort("qdot_o").Eval(ctx), [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(mv.GetOutputPort("qdot_hat").Eval(ctx), [0.1, 0.2, 0.3])


def test_controller_in_free_motion_is_13_with_identity_projection_and_no_force(law, posture):
    """Before the grasp (13) has ``Q = I``, ``J⁺ = 0``, ``J_φ = 0``: written out here with the
    model's H, C, D, g evaluated one by one (the law takes one inverse-dynamics call)."""
    model = law.model
    q_hat = posture + np.array([1e-3, -2e-3, 5e-4])
    qdot_hat, qdot_o = np.array([0.02, -0.01, 0.03]), np.array([0.01, 0.0, -0.02])
    ref = law.layout.unpack(_reference(posture - 1e-3, held=False))
    terms = law.control(posture, q_hat, qdot_hat, qdot_o, np.array([7.0]), np.array([0.4]),
                        ref)
    qdot_r = ref.qdot_d - G.Lambda * (q_hat - ref.q_d)
    qddot_r = ref.qddot_d - G.Lambda * (qdot_hat - ref.qdot_d)
    tau = (model.H(posture) @ qddot_r + model.Cv(posture, qdot_r) + model.D @ qdot_r
           + model.g(posture) - np.diag(G.K_R) @ (qdot_o - qdot_r))
    np.testing.assert_allclose(terms["qdot_r"], qdot_r, rtol=0, atol=1e-15)
    np.testing.assert_allclose(terms["qddot_r_hat"], qddot_r, rtol=0, atol=1e-14)
    np.testing.assert_allclose(terms["tau"], tau, rtol=1e-12, atol=1e-12)
    assert terms["Delta_lambda_tilde"].tolist() == [0.0]
