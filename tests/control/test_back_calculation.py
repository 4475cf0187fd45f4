"""Back-calculation anti-windup of the force integral (6) (``anti_windup: back_calculation``)
against independent computations: the constraint Jacobian by finite differences of ``φ``,
``(J_φᵀ)⁺`` in closed form for one constraint, hand-computed ``ΔF̃`` sequences while clipped,
bit-identity with (6) when never clipped, the tracking contraction ``1 − h K_aw``, and the
refusals (API and scenario)."""

import numpy as np
import pytest

from drake_coop.control.anti_windup import (
    back_calculation,
    back_calculation_gains,
    check_gain,
    force_integral_step,
)
from drake_coop.control.block import build_control_block
from drake_coop.control.finger import FingerLaw
from drake_coop.control.momentum import MomentumObserver
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.sources import SensedForce
from drake_coop.plant.arms import Arm, arm_model
from drake_coop.scenario.loading import default_scenario, load_scenario
from drake_coop.scenario.schema import ScenarioError

H = 0.009
K_F = 0.05
LIMITS = np.array([4.0, 4.0, 4.0])
# Commanded torques of five ticks; ticks 2 and 4 exceed LIMITS (a torque equal to its limit
# passes unclipped).
TAUS = [[1.0, 1.0, 1.0], [5.0, 0.0, 0.0], [-4.0, 0.0, 4.0], [0.0, 0.5, -4.5], [0.0, 0.0, 0.0]]


def _reference(lam_d, held=True):
    return np.concatenate([np.zeros(9), [lam_d], [float(held)]])


def _model():
    s = default_scenario()
    arm = Arm(s.robots[0], s.task)
    return arm_model(arm), arm.ik(arm.c)


def _J_fd(model, q, step=1e-6):
    """``J_φ`` (1, n) by central differences of the model's ``φ``."""
    cols = [(model.phi(q + step * e) - model.phi(q - step * e)) / (2 * step)
            for e in np.eye(q.size)]
    return np.column_stack(cols)


def _term(tau, J, gain, limits=LIMITS):
    """The back-calculation term by hand: one constraint, ``(J_φᵀ)⁺ = J_φ / |J_φ|²``."""
    excess = np.array([min(max(t, -l), l) - t for t, l in zip(tau, limits)])
    return gain / K_F * float(J[0] @ excess) / float(J[0] @ J[0])


def test_the_term_is_the_excess_mapped_by_the_transposed_jacobians_pseudo_inverse():
    model, q = _model()
    J = _J_fd(model, q)
    np.testing.assert_allclose(model.J_phi(q), J, rtol=0, atol=1e-7)
    assert back_calculation(np.array(TAUS[0]), LIMITS, J, K_F, 20.0) is None
    for tau in (TAUS[1], TAUS[3]):
        got = back_calculation(np.array(tau), LIMITS, model.J_phi(q), K_F, 20.0)
        assert got.shape == (1,)
        assert got[0] == pytest.approx(_term(tau, J, 20.0), rel=1e-6)
    # Two constraints: (J_φᵀ)⁺ J_φᵀ = I, so an excess along J_φᵀ δ maps back to δ k_F-scaled.
    J2 = np.array([[0.3, -0.1, 0.4], [0.0, 0.5, 0.2]])
    tau = np.array([0.0, 0.0, 10.0])
    excess = np.array([0.0, 0.0, -6.0])
    expected = 2.0 / K_F * np.linalg.solve(J2 @ J2.T, J2 @ excess)
    np.testing.assert_allclose(back_calculation(tau, LIMITS, J2, K_F, 2.0), expected,
                               rtol=1e-12)


def test_the_sensor_loop_follows_the_hand_computed_sequence_while_clipped():
    model, q = _model()
    J, gain = _J_fd(model, q), 30.0
    sf = SensedForce(H, ReferenceLayout(3, 1), anti_windup_limits=LIMITS,
                     anti_windup_gain=gain, model=model, force_gain=K_F)
    ctx = sf.CreateDefaultContext()
    sf.GetInputPort("lambda_sensor").FixValue(ctx, [30.0])
    sf.GetInputPort("reference").FixValue(ctx, _reference(25.0))
    sf.GetInputPort("q").FixValue(ctx, q)
    seen, expected, DF = [], [], 0.0
    for tau in TAUS:
        sf.GetInputPort("tau").FixValue(ctx, tau)
        ctx.SetDiscreteState(sf.EvalUniquePeriodicDiscreteUpdate(ctx))
        seen.append(sf.GetOutputPort("Delta_F_tilde").Eval(ctx)[0])
        DF += H * (5.0 + _term(tau, J, gain))
        expected.append(DF)
    np.testing.assert_allclose(seen, expected, rtol=1e-6, atol=0)
    # Tick 2 clips the base joint, which moves the pad across the normal (J_φ's first column
    # is 0): nothing to map, (6)'s step. Tick 4 clips the elbow: the term moves ΔF̃.
    assert abs(J[0, 0]) < 1e-9 and seen[1] - seen[0] == pytest.approx(0.045, abs=1e-12)
    assert abs(seen[3] - seen[2] - 0.045) > 1e-2
    sf.GetInputPort("reference").FixValue(ctx, _reference(25.0, held=False))
    ctx.SetDiscreteState(sf.EvalUniquePeriodicDiscreteUpdate(ctx))
    assert sf.GetOutputPort("Delta_F_tilde").Eval(ctx)[0] == 0.0    # reset on release


def _momentum_ticks(obs, q, taus, lam_d=20.0):
    """``[ΔF̃, σ]`` after each tick and ``λ̂`` of each tick, an arm at rest at ``q``."""
    ctx = obs.CreateDefaultContext()
    obs.set_initial_state(ctx, q)
    obs.get_q_input_port().FixValue(ctx, q)
    obs.get_qdot_hat_input_port().FixValue(ctx, np.zeros(3))
    obs.get_reference_input_port().FixValue(ctx, _reference(lam_d))
    states, lam = [], []
    for tau in taus:
        obs.get_tau_input_port().FixValue(ctx, tau)
        lam.append(obs.GetOutputPort("lambda_hat").Eval(ctx)[0])
        ctx.SetDiscreteState(obs.EvalUniquePeriodicDiscreteUpdate(ctx))
        states.append(np.concatenate([obs.GetOutputPort("Delta_F_tilde").Eval(ctx),
                                      ctx.get_discrete_state(0).value()]))
    return np.array(states), np.array(lam)


def test_the_momentum_observer_follows_the_hand_computed_sequence_while_clipped():
    model, q = _model()
    J, gain = _J_fd(model, q), 50.0
    taus = [model.g(q) + np.array(t) for t in TAUS]
    limits = np.abs(model.g(q)) + LIMITS
    obs = MomentumObserver(model, ReferenceLayout(3, 1), H, 50.0, anti_windup_limits=limits,
                           anti_windup_gain=gain, force_gain=K_F)
    states, lam = _momentum_ticks(obs, q, taus)
    expected, DF = [], 0.0
    for tau, lam_k in zip(taus, lam):
        DF += H * (lam_k - 20.0 + _term(tau, J, gain, limits))
        expected.append(DF)
    np.testing.assert_allclose(states[:, 0], expected, rtol=1e-6, atol=1e-12)
    # σ integrates the commanded torque as without anti-windup (only ΔF̃ changes).
    plain = _momentum_ticks(MomentumObserver(model, ReferenceLayout(3, 1), H, 50.0), q, taus)
    np.testing.assert_array_equal(states[:, 1:], plain[0][:, 1:])


def test_never_clipped_is_the_papers_integral_to_the_bit():
    rng = np.random.default_rng(5)
    model, q = _model()
    taus = model.g(q) + rng.uniform(-3.0, 3.0, (40, 3))
    plain = MomentumObserver(model, ReferenceLayout(3, 1), H, 50.0)
    back = MomentumObserver(model, ReferenceLayout(3, 1), H, 50.0,
                            anti_windup_limits=np.abs(model.g(q)) + 3.5,
                            anti_windup_gain=1.0 / H, force_gain=K_F)
    np.testing.assert_array_equal(_momentum_ticks(plain, q, taus)[0],
                                  _momentum_ticks(back, q, taus)[0])
    DF, e = np.array([0.3, -0.2]), np.array([1.5, 4.0])
    np.testing.assert_array_equal(force_integral_step(DF, e, True, H, correction=None),
                                  DF + H * e)


@pytest.mark.parametrize("gain", [1.0, 40.0, 1.0 / H])
def test_the_excess_along_the_constraint_shrinks_by_one_minus_h_gain_a_tick(gain):
    """With the torque ``τ0 + k_F J_φᵀ ΔF̃`` ((13)'s ``k_F`` term) clipped at every joint and
    no force error, each tick multiplies the excess's constraint component by ``1 − h K_aw``."""
    J = np.array([[0.2, -0.45, 0.3]])
    limits = np.array([1.0, 1.0, 1.0])
    # Beyond every limit by 10 w (w ⊥ J_φ: no ΔF̃ reaches it) plus a unit excess along J_φ,
    # which the ticks remove: every joint stays clipped.
    w = np.array([1.0, 1.0, 0.15 / 0.18])
    assert abs(float(J[0] @ w)) < 1e-12
    tau0 = limits * np.sign(w) + 10.0 * w + J[0] / np.linalg.norm(J[0])
    DF = np.zeros(1)
    projected = []
    for _ in range(6):
        tau = tau0 + K_F * J.T @ DF
        excess = np.clip(tau, -limits, limits) - tau
        projected.append(float(J[0] @ excess) / float(J[0] @ J[0]))
        DF = force_integral_step(DF, np.zeros(1), True, H,
                                 correction=back_calculation(tau, limits, J, K_F, gain))
        assert np.all(np.abs(tau0 + K_F * J.T @ DF) > limits)
    assert abs(projected[0]) > 0.5
    np.testing.assert_allclose(projected, projected[0] * (1.0 - H * gain) ** np.arange(6),
                               rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("gain, message", [
    (0.0, "anti_windup_gain: a tracking rate in"), (-1.0, "anti_windup_gain: a tracking"),
    (1.0 / H * 1.01, "anti_windup_gain: a tracking"), (True, "anti_windup_gain: a tracking"),
    ("5", "anti_windup_gain: a tracking"), (float("nan"), "anti_windup_gain: a tracking")])
def test_a_bad_gain_is_refused_by_name(gain, message):
    with pytest.raises(ValueError, match=f"^{message}"):
        check_gain(gain, H)


def test_the_gain_may_be_one_over_h():
    assert check_gain(1.0 / H, H) == 1.0 / H
    assert check_gain(1.0 / 0.009, 0.009) == 1.0 / 0.009


def test_the_sources_refuse_a_gain_without_what_it_needs():
    with pytest.raises(ValueError, match="^anti_windup_gain: needs anti_windup_limits"):
        back_calculation_gains(None, 10.0, K_F, H)
    with pytest.raises(ValueError, match="^force_gain: k_F > 0 is required"):
        back_calculation_gains(LIMITS, 10.0, None, H)
    assert back_calculation_gains(LIMITS, None, None, H) is None
    with pytest.raises(ValueError, match="^model: an arm model with J_phi is required"):
        SensedForce(H, ReferenceLayout(3, 1), anti_windup_limits=LIMITS, anti_windup_gain=10.0,
                    force_gain=K_F)


def test_the_block_feeds_q_to_the_sensor_loop_with_back_calculation():
    model, q = _model()
    law = FingerLaw(model, default_scenario().robots[0].gains)
    diagram, _, force, _ = build_control_block("r", law, H, force_source="sensor",
                                               anti_windup_limits=[5.0, 5.0, 5.0],
                                               anti_windup_gain=20.0)
    assert force.HasInputPort("q") and force.HasInputPort("tau")
    context = diagram.CreateDefaultContext()
    diagram.GetInputPort("q").FixValue(context, q)
    np.testing.assert_array_equal(
        force.GetInputPort("q").Eval(force.GetMyContextFromRoot(context)), q)


ROBOT2 = ("- {name: robot2, model: crs_a255, base_xyz: [1.16, 0, 0], base_yaw_deg: 180,"
          " contact_xy: [0.8192, 0], normals: [[1, 0, 0]], home: [0.9, 0, 0.6]}\n")
LIMITED = "actuators: {torque_limits: [9, 9, 9]}"


@pytest.mark.parametrize("entry, message", [
    (f"force_source: momentum, anti_windup: back_calculation, {LIMITED}",
     r"^robots\[0\]\.anti_windup_gain: a tracking rate in \(0, 1/h = [0-9.]+\] 1/s is "
     r"required with anti_windup: back_calculation \(got None\)$"),
    (f"force_source: sensor, anti_windup: back_calculation, anti_windup_gain: 500, {LIMITED}",
     r"^robots\[0\]\.anti_windup_gain: a tracking rate in"),
    (f"force_source: sensor, anti_windup: conditional, anti_windup_gain: 5, {LIMITED}",
     r"^robots\[0\]\.anti_windup_gain: only with anti_windup: back_calculation"),
    ("force_source: momentum, anti_windup: back_calculation, anti_windup_gain: 5",
     r"^robots\[0\]\.anti_windup: back_calculation needs actuators\.torque_limits"),
    (f"force_source: observer, anti_windup_gain: 5, {LIMITED}",
     r"^robots\[0\]\.anti_windup_gain applies to force_source: sensor or momentum only"),
])
def test_a_bad_back_calculation_entry_is_refused_in_one_line_naming_it(entry, message):
    text = "robots:\n- {name: robot1, " + entry + "}\n" + ROBOT2
    with pytest.raises(ScenarioError, match=message) as info:
        load_scenario(data=text)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("force_source", ["sensor", "momentum"])
def test_the_scenario_fields_reach_the_experiments_force_source(force_source):
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run
    from tests.conftest import short_scenario

    scenario = short_scenario()
    for robot in scenario.robots:
        robot.force_source = force_source
    scenario.robots[0].actuators.torque_limits = [30.0, 30.0, 30.0]
    scenario.robots[0].anti_windup = "back_calculation"
    scenario.robots[0].anti_windup_gain = 25.0
    exp = build_experiment(plan_run(scenario), log=False)
    with_option, without = (rs.force_observer for rs in exp.robots)
    assert with_option._back == (scenario.robots[0].gains.k_F, 25.0)
    assert without._back is None
