"""Identification against independent references: Drake's own inverse dynamics, closed forms,
finite differences and the simulated truth (never against the estimator itself)."""

import json

import numpy as np
import pytest
from pydrake.multibody.tree import MultibodyForces

from drake_coop.plant.arms import arm_model
from drake_coop.identification.estimate import savgol_kernels, smooth_and_differentiate
from drake_coop.identification.excitation import ExcitationLimits, FourierExcitation
from drake_coop.identification.regressor import (
    Regressor,
    identifiable_basis,
    load_structure,
    pseudo_inertia,
    true_parameters,
)
from drake_coop.identification.report import identify_robot, run_identify
from drake_coop.identification.urdf_writer import identified_urdf_text
from drake_coop.plant.arms import Arm
from drake_coop.scenario.loading import load_scenario


def _states(N=60, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, (N, 3)), rng.uniform(-2, 2, (N, 3)), rng.uniform(-4, 4, (N, 3))


def _drake_torques(plant, q, v, a):
    """H a + C v + D v + g (with reflected rotor inertia) from Drake's plant directly."""
    ctx = plant.CreateDefaultContext()
    out = []
    for k in range(q.shape[0]):
        plant.SetPositions(ctx, q[k])
        plant.SetVelocities(ctx, v[k])
        f = MultibodyForces(plant)
        plant.CalcForceElementsContribution(ctx, f)
        out.append(plant.CalcInverseDynamics(ctx, a[k], f))
    return np.concatenate(out)


@pytest.mark.parametrize("urdf", ["crs_a465_3dof.urdf", "crs_a255_3dof.urdf"])
def test_regressor_times_true_parameters_is_drakes_inverse_dynamics_with_a_payload(urdf):
    s = load_structure(f"urdf/{urdf}", "base_link", payload_mass=0.7)
    q, v, a = _states()
    Y = Regressor(s).matrix(q, v, a)
    np.testing.assert_allclose(Y @ true_parameters(s), _drake_torques(s.plant, q, v, a),
                               rtol=1e-10, atol=1e-10)


def test_coulomb_columns_are_the_smoothed_sign_of_the_velocity():
    s = load_structure("urdf/crs_a465_3dof.urdf", "base_link")
    q, v, a = _states(5)
    R = Regressor(s, coulomb_velocity=0.02)
    theta = np.zeros(s.num_parameters)
    theta[s.joint_slice("coulomb")] = [0.5, 1.0, 2.0]
    np.testing.assert_allclose(R.matrix(q, v, a) @ theta,
                               (np.tanh(v / 0.02) * [0.5, 1.0, 2.0]).ravel())


def test_pseudo_inertia_is_psd_for_a_real_body_and_not_for_an_impossible_one():
    s = load_structure("urdf/crs_a465_3dof.urdf", "base_link")
    theta = true_parameters(s)
    for i in range(3):
        assert np.linalg.eigvalsh(pseudo_inertia(theta[10 * i: 10 * i + 10])).min() > 0
    bad = theta[20:30].copy()
    bad[6] = bad[4] + bad[5] + 0.1        # I_zz beyond I_xx + I_yy: no mass distribution
    assert np.linalg.eigvalsh(pseudo_inertia(bad)).min() < 0


def test_link_masses_of_the_crs_arm_do_not_change_its_joint_torques():
    """Why no link mass of these arms is recovered: each mass can change with some first
    moment and inertia so that no joint torque changes (the mass direction is outside the
    row space of Y), for the waist, upper arm and forearm composite alike."""
    s = load_structure("urdf/crs_a465_3dof.urdf", "base_link", payload_mass=0.5)
    q, v, a = _states(200)
    Y = Regressor(s).matrix(q, v, a)
    scale, V = identifiable_basis(Y)
    for i in range(3):
        e = np.zeros(s.num_parameters)
        e[10 * i] = 1.0                                   # one unit of link i's mass ...
        x = e * scale                                     # (Y / scale) x = Y e
        null = (x - V @ (V.T @ x)) / scale                # ... minus its identifiable part
        assert null[10 * i] > 0.5                         # most of the mass change stays ...
        np.testing.assert_allclose(Y @ null, 0.0, atol=1e-7 * np.abs(Y).max())  # ... unseen


def test_excitation_derivatives_are_the_finite_differences_and_it_starts_and_ends_at_rest():
    rng = np.random.default_rng(1)
    ex = FourierExcitation(np.array([0.1, 0.2, 0.3]), rng.normal(0, 0.2, (3, 5)),
                           rng.normal(0, 0.2, (3, 5)), 5.0, 7.0, 1.0)
    t = np.linspace(0.05, 6.95, 50)
    eps = 1e-5
    q, v, a = ex.evaluate(t)
    qp, vp, _ = ex.evaluate(t + eps)
    qm, vm, _ = ex.evaluate(t - eps)
    np.testing.assert_allclose(v, (qp - qm) / (2 * eps), atol=1e-6)
    np.testing.assert_allclose(a, (vp - vm) / (2 * eps), atol=1e-5)
    for end in (0.0, 7.0):
        q_end, v_end, a_end = (x[0] for x in ex.evaluate(end))
        np.testing.assert_allclose(q_end, ex.q0, atol=1e-12)
        np.testing.assert_allclose(np.r_[v_end, a_end], 0.0, atol=1e-12)


def test_excitation_limits_flag_a_joint_beyond_its_range_and_a_torque_beyond_its_share():
    lim = ExcitationLimits(np.full(2, -1.0), np.full(2, 1.0), np.full(2, 10.0), np.full(2, 5.0),
                           margin=0.1, torque_fraction=0.5)
    z = np.zeros((1, 2))
    assert lim.violation(np.array([[0.9, 0.0]]), z, z) == pytest.approx(1.0)
    assert lim.violation(z, z, np.array([[0.0, 6.0]])) == pytest.approx(1.2)


def test_savitzky_golay_recovers_a_cubics_derivatives_exactly():
    h = 0.009
    t = np.arange(100) * h
    y = (1 + 2 * t - 3 * t ** 2 + 0.5 * t ** 3)[:, None]
    value, d1, d2 = smooth_and_differentiate(y, h, 15, 3)
    tc = t[7:-7]
    np.testing.assert_allclose(value[:, 0], 1 + 2 * tc - 3 * tc ** 2 + 0.5 * tc ** 3, atol=1e-10)
    np.testing.assert_allclose(d1[:, 0], 2 - 6 * tc + 1.5 * tc ** 2, atol=1e-8)
    np.testing.assert_allclose(d2[:, 0], -6 + 3 * tc, atol=1e-6)
    assert savgol_kernels(15, 3).shape == (3, 15)


def test_written_urdf_of_the_true_parameters_has_the_true_dynamics():
    sc = load_scenario("scenarios/paper.yaml")
    arm = Arm(sc.robots[0], sc.task)
    s = load_structure(arm.urdf_path, "base_link", payload_mass=0.4)
    theta = true_parameters(s)
    theta[s.joint_slice("viscous")] = [1.0, 2.0, 3.0]
    theta[s.joint_slice("rotor_inertia")] = [0.5, 0.4, 0.3]
    text = identified_urdf_text(arm.urdf_path.read_text(), s, theta)
    from drake_coop.scenario.description import IDENTIFIED_MARK

    # the mark the scenario's preparation reads (not prepared twice), within its first 4 kB
    assert IDENTIFIED_MARK in text[:4096]
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "x.urdf"
        path.write_text(text)
        model = arm_model(arm, path)
    q, v, a = _states(20)
    got = np.concatenate([model.inverse_dynamics_terms(q[k], v[k], a[k]) for k in range(20)])
    no_coulomb = theta.copy()
    no_coulomb[s.joint_slice("coulomb")] = 0.0
    np.testing.assert_allclose(got, Regressor(s).matrix(q, v, a) @ no_coulomb, rtol=1e-9,
                               atol=1e-9)


@pytest.fixture(scope="module")
def friction_and_payload():
    """Robot 1 of realistic.yaml, 30 % heavy nominal model, with an unknown 0.5 kg payload and
    unknown Coulomb friction: the case the identification must see through."""
    sc = load_scenario("scenarios/realistic.yaml")
    r = sc.robots[0].model_error
    r.mass_scale, r.payload_mass, r.coulomb_friction = 1.3, 0.5, [0.5, 0.8, 0.3]
    return identify_robot(sc, 0, 10.0)


def test_identified_friction_is_the_simulated_truth(friction_and_payload):
    ident = friction_and_payload
    s = ident.structure
    for kind, tol in (("coulomb", 0.08), ("viscous", 0.1)):
        sl = s.joint_slice(kind)
        # N·m and N·m·s/rad; Coulomb within 0.08 N·m of 0.3–0.8, viscous within 4 % of 1.5–2.5
        np.testing.assert_allclose(ident.estimate.theta[sl], ident.theta_true[sl], atol=tol)


def test_identified_forearm_first_moment_carries_the_payload(friction_and_payload):
    """The forearm composite's first moment (mass × centre of mass: what gravity and the
    force observer see) includes the unknown payload: within 2 % of the truth, while the
    nominal model is 10 % off."""
    ident = friction_and_payload
    k = 20 + 3                                            # link3.hz
    assert abs(ident.theta_nominal[k] / ident.theta_true[k] - 1) > 0.08
    assert abs(ident.estimate.theta[k] / ident.theta_true[k] - 1) < 0.02


def test_identified_model_torques_match_the_truth_on_another_trajectory(friction_and_payload):
    v = friction_and_payload.validation
    assert v["torque_error_rms_identified"] < 0.1 * v["torque_error_rms_nominal"]
    assert v["torque_error_rms_identified"] < 0.01 * v["torque_rms"]


def test_identified_parameters_are_physically_consistent(friction_and_payload):
    ident = friction_and_payload
    for i in range(3):
        J = pseudo_inertia(ident.estimate.theta[10 * i: 10 * i + 10])
        assert np.linalg.eigvalsh(J).min() > 0


def test_identify_writes_the_folder_whole_with_an_identified_scenario(tmp_path):
    sc = load_scenario("scenarios/realistic.yaml")
    out = tmp_path / "ident"
    run_identify(sc, out, [1], duration=4.0, log=lambda m: None)
    assert sorted(p.name for p in out.iterdir()) == [
        "identified.yaml", "identify.json", "identify_fit.png", "robot2_identified.urdf"]
    report = json.loads((out / "identify.json").read_text())
    assert set(report["robots"]) == {"robot2"}
    ident = load_scenario(out / "identified.yaml")
    r1, r2 = ident.robots
    assert r1.controller_model == "" and r1.model_error.mass_scale == 1.1   # not identified
    assert r2.controller_model == str((out / "robot2_identified.urdf").resolve())
    assert (r2.model_error.mass_scale, r2.model_error.inertia_scale) == (1.0, 1.0)
    assert [p.name for p in tmp_path.iterdir()] == ["ident"]              # no staging left


@pytest.mark.parametrize("args, message", [
    (["--robots", "3"], "--robots"),
    (["--duration", "500"], "--duration"),
    (["--duration", "nan"], "--duration"),
])
def test_identify_bad_input_exits_2_with_one_line(tmp_path, capsys, args, message):
    from drake_coop.cli import main

    code = main(["identify", "scenarios/realistic.yaml", "--out", str(tmp_path / "o"), *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and message in err


def test_identify_refuses_an_arm_whose_torque_limits_leave_no_excitation(tmp_path, capsys):
    from drake_coop.cli import main

    text = open("scenarios/realistic.yaml").read().replace(
        "torque_limits: [35.0, 35.0, 35.0]", "torque_limits: [0.05, 0.05, 0.05]")
    path = tmp_path / "weak.yaml"
    path.write_text(text)
    code = main(["identify", str(path), "--out", str(tmp_path / "o"), "--robots", "1"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "robot1" in err
    assert not (tmp_path / "o").exists()
