"""The closed-loop estimators (IDIM-IV, DIDIM) against independent references: the closed form
of the instrumental-variable solution and the plim of least squares on a constructed regression,
Drake's own inverse dynamics and simulation, and the simulated truth."""

import numpy as np
import pytest
from pydrake.multibody.tree import MultibodyForces

from drake_coop.identification.estimate import Estimate
from drake_coop.identification.instrumental import (
    ModelDynamics,
    estimate_parameters_didim,
    iv_solution,
    simulate_tracking,
)
from drake_coop.identification.regressor import (
    Regressor,
    load_structure,
    true_parameters,
)
from drake_coop.identification.report import (
    ESTIMATORS,
    closed_loop,
    identify_robot,
)
from drake_coop.identification.setup import IdentifyInputError
from drake_coop.scenario.loading import load_scenario


def test_iv_is_the_closed_form_and_removes_the_bias_that_least_squares_has():
    """y = X β + e with e correlated with X (X = Z Π + v c, e = ρ v + w): least squares
    converges to β + (ΠᵀΠ + c cᵀ)⁻¹ c ρ (closed form), the IV solution to β; and the IV
    solution is (ZᵀX)⁻¹Zᵀy."""
    rng = np.random.default_rng(7)
    N = 200_000
    beta = np.array([1.5, -0.7])
    Pi = np.array([[1.0, 0.3], [0.2, 0.8]])
    c, rho = np.array([0.8, -0.5]), 0.9
    Z = rng.normal(size=(N, 2))
    v = rng.normal(size=N)
    X = Z @ Pi + np.outer(v, c)
    y = X @ beta + rho * v + 0.3 * rng.normal(size=N)
    iv = iv_solution(X, Z, y)
    np.testing.assert_allclose(iv, np.linalg.solve(Z.T @ X, Z.T @ y), rtol=1e-9)
    ols = np.linalg.lstsq(X, y, rcond=None)[0]
    plim = beta + np.linalg.solve(Pi.T @ Pi + np.outer(c, c), c * rho)
    se = 1.0 / np.sqrt(N)                          # unit-scale regressors and noise
    assert np.max(np.abs(plim - beta)) > 100 * se  # the bias is real ...
    np.testing.assert_allclose(ols, plim, atol=10 * se)     # ... least squares has it ...
    np.testing.assert_allclose(iv, beta, atol=10 * se)      # ... the IV solution does not


def test_model_dynamics_of_the_true_parameters_are_drakes_dynamics_of_the_arm():
    """M a + bias of :class:`ModelDynamics` (composite bodies set from θ, mass matrix and
    bias term) equals Drake's inverse dynamics of the URDF's own plant (its bodies, rotor
    inertia and joint damping), with a payload."""
    s = load_structure("urdf/crs_a465_3dof.urdf", "base_link", payload_mass=0.7)
    theta = true_parameters(s)
    dyn = ModelDynamics(s, theta)
    rng = np.random.default_rng(3)
    ref = load_structure("urdf/crs_a465_3dof.urdf", "base_link", payload_mass=0.7).plant
    ctx = ref.CreateDefaultContext()
    for _ in range(10):
        q, v, a = rng.uniform(-1, 1, 3), rng.uniform(-2, 2, 3), rng.uniform(-4, 4, 3)
        M, bias = dyn.terms(q, v)
        ref.SetPositions(ctx, q)
        ref.SetVelocities(ctx, v)
        f = MultibodyForces(ref)
        ref.CalcForceElementsContribution(ctx, f)
        np.testing.assert_allclose(M @ a + bias, ref.CalcInverseDynamics(ctx, a, f),
                                   rtol=1e-9, atol=1e-9)


@pytest.fixture(scope="module")
def paper_two_seconds():
    """Robot 1 of paper.yaml identified from 2 s of excitation (the MAP estimate) and its
    closed loop: ``(identification, loop)``, computed once for the tests that read them
    (none changes them)."""
    sc = load_scenario("scenarios/paper.yaml")
    ident = identify_robot(sc, 0, 2.0)
    return ident, closed_loop(sc, 0, ident.excitation, _nominal(sc, 0), ident.data)


def test_the_simulated_closed_loop_follows_drakes_simulation_of_the_experiment(
        paper_two_seconds):
    """The instruments' closed loop (true parameters, the experiment's law, gains and
    feedforward) against the recorded experiment on Drake's discrete plant with ideal
    encoders: same positions within 2e-4 rad, same commanded torques within 1 % of their
    range (different integrators: semi-implicit Euler against SAP)."""
    ident, loop = paper_two_seconds
    sim = simulate_tracking(ModelDynamics(ident.structure, ident.theta_true), loop.q_d,
                            loop.v_d, loop.feedforward, loop.kp, loop.kv, loop.h,
                            loop.substeps, loop.torque_limits, loop.encoder_delay)
    np.testing.assert_allclose(sim.q, ident.data.q_true, atol=2e-4)
    span = np.ptp(ident.data.tau, axis=0)
    assert np.max(np.abs(sim.tau - ident.data.tau) / span) < 0.01


def _nominal(sc, i):
    from drake_coop.plant.arms import Arm
    from drake_coop.plant.model_error import controller_arm_model

    return controller_arm_model(Arm(sc.robots[i], sc.task), sc.robots[i].model_error)


def test_didim_on_noiseless_closed_loop_data_finds_the_exact_torques(paper_two_seconds):
    """Data of the model's own closed loop (true parameters, no noise, no filter): DIDIM
    started from a 30 % heavy model converges (the simulated torques change by < 1e-8) to
    parameters whose torques along the trajectory are the truth's within 1e-4 of their RMS,
    and on 50 random states within 1e-3 (measured 7.7e-5: directions a 2 s trajectory hardly
    excites, and the pseudo-inertia margin ``PSD_MARGIN``), where the MAP estimate from the
    filtered measurements of the same 2 s is 2.7e-2 off (test below)."""
    ident, loop = paper_two_seconds
    s = ident.structure
    theta_true = ident.theta_true
    truth = simulate_tracking(ModelDynamics(s, theta_true), loop.q_d, loop.v_d,
                              loop.feedforward, loop.kp, loop.kv, loop.h, loop.substeps)
    start_theta = theta_true * 1.3
    start = Estimate(theta=start_theta, theta_ls=start_theta, residual_rms=np.zeros(3),
                     condition_number=1.0, rank=22, samples=0, solver="none")
    reg = Regressor(s)
    est = estimate_parameters_didim(reg, truth.tau, start_theta, loop, iterations=40,
                                    tol=1e-8, start=start)
    assert est.changes[-1] < 1e-8

    def relative_error(q, v, a):
        Y = reg.matrix(q, v, a)
        tau = Y @ theta_true
        return np.sqrt(np.mean((Y @ est.theta - tau) ** 2)) / np.sqrt(np.mean(tau ** 2))

    assert relative_error(truth.q, truth.v, truth.a) < 1e-4
    rng = np.random.default_rng(5)
    assert relative_error(rng.uniform(-1, 1, (50, 3)), rng.uniform(-2, 2, (50, 3)),
                          rng.uniform(-4, 4, (50, 3))) < 1e-3


@pytest.fixture(scope="module")
def two_seconds():
    """Robot 1 of realistic.yaml (10 % heavy nominal model, quantized encoders, torque
    limits) with 2 s of excitation, by the MAP and the DIDIM estimates."""
    sc = load_scenario("scenarios/realistic.yaml")
    return {e: identify_robot(sc, 0, 2.0, estimator=e) for e in ("map_sdp", "didim")}


def test_didim_from_two_seconds_is_near_the_truth_where_the_filtered_map_is_not(two_seconds):
    """With 2 s of excitation the filter that differentiates the encoder readings distorts
    the MAP estimate's regressor (forearm first moment 6.7 % low, measured); DIDIM
    differentiates nothing: within 1 % of the simulated truth, and its torques on another
    trajectory ten times closer to the truth's than the MAP estimate's."""
    k = 23                                        # link3.hz
    m, d = two_seconds["map_sdp"], two_seconds["didim"]
    assert abs(m.estimate.theta[k] / m.theta_true[k] - 1) > 0.03
    assert abs(d.estimate.theta[k] / d.theta_true[k] - 1) < 0.01
    assert (d.validation["torque_error_rms_identified"]
            < 0.1 * m.validation["torque_error_rms_identified"])
    assert d.validation["torque_error_rms_identified"] < 0.01 * d.validation["torque_rms"]


def test_closed_loop_estimates_are_physically_consistent(two_seconds):
    from drake_coop.identification.regressor import pseudo_inertia

    ident = two_seconds["didim"]
    s = ident.structure
    for i in range(len(s.links)):
        assert np.linalg.eigvalsh(pseudo_inertia(ident.estimate.theta[10 * i: 10 * i + 10])
                                  ).min() > 0
    for kind in ("rotor_inertia", "viscous", "coulomb"):
        assert np.all(ident.estimate.theta[s.joint_slice(kind)] >= -1e-9)


def test_an_unknown_estimator_is_refused_by_name():
    sc = load_scenario("scenarios/paper.yaml")
    assert ESTIMATORS == ("map_sdp", "idim_iv", "didim")
    with pytest.raises(IdentifyInputError, match="estimator must be one of"):
        identify_robot(sc, 0, 2.0, estimator="ols")


def test_idim_iv_from_ten_seconds_matches_the_truth():
    """IDIM-IV (instruments from the simulated closed loop) on robot 2 of realistic.yaml,
    10 s: the forearm first moment within 1 % of the simulated truth, the torques on
    another trajectory within 1 % of their RMS and ten times closer than the nominal's."""
    sc = load_scenario("scenarios/realistic.yaml")
    ident = identify_robot(sc, 1, 10.0, estimator="idim_iv")
    k = 23
    assert abs(ident.estimate.theta[k] / ident.theta_true[k] - 1) < 0.01
    v = ident.validation
    assert v["torque_error_rms_identified"] < 0.01 * v["torque_rms"]
    assert v["torque_error_rms_identified"] < 0.1 * v["torque_error_rms_nominal"]
    assert len(ident.estimate.history) >= 2


def test_a_failed_iteration_keeps_the_last_solved_iterate(monkeypatch, paper_two_seconds):
    """When the solver fails on an iteration's program, DIDIM stops with the previous
    iterate (here the second program fails: the estimate is the first DIDIM iterate, the
    same as a run limited to one iteration) and says why."""
    import drake_coop.identification.instrumental as instrumental

    ident, loop = paper_two_seconds
    reg = Regressor(ident.structure)
    one = estimate_parameters_didim(reg, ident.data.tau, ident.theta_nominal, loop,
                                    iterations=1, start=ident.estimate)
    calls = []
    original = instrumental.physically_consistent_map

    def second_fails(*args):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("the identification program failed: kIterationLimit")
        return original(*args)

    monkeypatch.setattr(instrumental, "physically_consistent_map", second_fails)
    est = estimate_parameters_didim(reg, ident.data.tau, ident.theta_nominal, loop,
                                    iterations=5, tol=0.0, start=ident.estimate)
    assert "kIterationLimit" in est.stopped and len(est.history) == 2
    np.testing.assert_array_equal(est.theta, one.theta)
    assert one.stopped == ""
