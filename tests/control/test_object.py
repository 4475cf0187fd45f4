"""The object-aware blocks (drake_coop.control.object) against independent computations:
the virtual work of a held weight (finite differences of the pad's height), the lever rule,
Newton–Euler on the grasp's forces, Coulomb's cone, a simulated payload, and the constraint
with a moved contact point."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import SpatialInertia, UnitInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Demultiplexer

from drake_coop.control import ArmModel, FingerLaw, Gains, MakeArmControllerPlant
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.object import (
    GRAVITY,
    CompressedReference,
    ContactStiffness,
    LoadFeedforward,
    MassEstimator,
    ObjectModel,
    ObjectStateEstimator,
    grasp_matrix,
    internal_part,
    load_distribution,
    mass_shares,
    max_squeeze,
    object_wrench,
    squeeze_for_grasp,
)
from drake_coop.scenario.resources import urdf_dir

H = 0.009
URDF = str(urdf_dir() / "crs_a465_3dof.urdf")
Q0 = np.array([0.1, 0.3, 1.7])


def _arm(time_step=1e-3, payload=None):
    """One arm welded at the origin; ``payload`` (kg): a point mass welded at the pad."""
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=time_step)
    plant.SetUseSampledOutputPorts(False)
    (arm,) = Parser(plant, "arm").AddModels(URDF)
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link", arm))
    if payload:
        body = plant.AddRigidBody("payload", arm, SpatialInertia(
            payload, np.zeros(3), UnitInertia.SolidSphere(0.01)))
        plant.WeldFrames(plant.GetFrameByName("pad", arm), body.body_frame())
    plant.Finalize()
    return builder, plant, arm


@pytest.fixture(scope="module")
def model():
    _, plant, arm = _arm()
    return ArmModel.from_plant(MakeArmControllerPlant(URDF, plant, arm), "pad",
                               [[-1.0, 0.0, 0.0]], [0.5, 0.0, 0.4])


def _held_reference(n=3, m=1, held=True, lambda_d=0.0):
    return ReferenceLayout(n, m).pack(np.zeros((1, n)), np.zeros((1, n)), np.zeros((1, n)),
                                      np.full((1, m), lambda_d), np.array([float(held)]))[0]


# ------------------------------------------------------------------ grasp and load split
def test_load_distribution_applies_the_wrench_and_has_no_internal_part():
    rng = np.random.default_rng(1)
    obj = ObjectModel(mass=0.7, com=[0.01, 0.0, 0.0], inertia=np.diag([1e-3, 2e-3, 3e-3]),
                      grasp_points=[[-0.1, 0, 0], [0.1, 0, 0]],
                      grasp_normals=[[1, 0, 0], [-1, 0, 0]])
    a, w, alpha = rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
    f = load_distribution(obj, a, w, alpha)
    # Newton–Euler written out: the contact forces' resultant and moment about the CoM.
    r = obj.grasp_points - obj.com
    force = f.sum(axis=0)
    moment = sum(np.cross(ri, fi) for ri, fi in zip(r, f))
    assert np.allclose(force, 0.7 * (a + [0, 0, GRAVITY]))
    # Two point contacts cannot apply a moment about their common line (x): only y, z.
    expected = obj.inertia @ alpha + np.cross(w, obj.inertia @ w)
    assert np.allclose(moment[1:], expected[1:])
    # Minimum norm: no part along the squeeze direction (equal and opposite along x).
    squeeze = np.array([1.0, 0, 0, -1.0, 0, 0]) / np.sqrt(2)
    assert abs(f.reshape(-1) @ squeeze) < 1e-12
    assert np.allclose(internal_part(obj, f), 0.0, atol=1e-12)
    assert np.allclose(internal_part(obj, [[5, 0, 0], [-5, 0, 0]]), [[5, 0, 0], [-5, 0, 0]])


def test_mass_shares_follow_the_lever_rule():
    p1, p2, c = -0.1, 0.12, 0.03
    obj = ObjectModel(mass=2.0, com=[c, 0, 0], grasp_points=[[p1, 0, 0], [p2, 0, 0]],
                      grasp_normals=[[1, 0, 0], [-1, 0, 0]])
    m1 = 2.0 * (p2 - c) / (p2 - p1)
    assert np.allclose(mass_shares(obj), [m1, 2.0 - m1])


def test_grasp_matrix_maps_forces_to_resultant_and_moment():
    points = np.array([[0.1, 0.2, 0.3], [-0.2, 0.1, 0.0]])
    f = np.array([[1.0, -2.0, 0.5], [0.3, 0.1, -1.0]])
    w = grasp_matrix(points, [0.05, 0.0, 0.1]) @ f.reshape(-1)
    r = points - [0.05, 0.0, 0.1]
    assert np.allclose(w[:3], f.sum(axis=0))
    assert np.allclose(w[3:], np.cross(r[0], f[0]) + np.cross(r[1], f[1]))


def test_object_wrench_is_newton_euler():
    obj = ObjectModel(mass=1.5, inertia=np.diag([0.1, 0.2, 0.3]))
    w = object_wrench(obj, [0.1, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 2.0])
    assert np.allclose(w, [0.15, 0.0, 1.5 * GRAVITY, 0.0, 0.0, 0.6])


@pytest.mark.parametrize("field, kwargs", [
    ("mass", dict(mass=-1.0)), ("mass", dict(mass=0.0)), ("mass", dict(mass=float("nan"))),
    ("inertia", dict(mass=1.0, inertia=-np.eye(3))),
    ("grasp_normals", dict(mass=1.0, grasp_normals=[[0, 0, 0], [1, 0, 0]])),
])
def test_object_model_rejects_bad_fields_naming_them(field, kwargs):
    with pytest.raises(ValueError, match=field):
        ObjectModel(**kwargs)


# ------------------------------------------------------------------ feedforward
def test_feedforward_of_a_static_hold_is_the_virtual_work_of_the_weight(model):
    """τ_ff = J_xᵀ [0, 0, m_i g]: the gradient of the held weight's potential m_i g z(q),
    here by central differences of the model's pad height."""
    m_i = 0.37
    ff = LoadFeedforward(model, H)
    ctx = ff.CreateDefaultContext()
    ff.get_q_input_port().FixValue(ctx, Q0)
    ff.get_reference_input_port().FixValue(ctx, _held_reference())
    ff.get_acceleration_d_input_port().FixValue(ctx, np.zeros(3))
    ff.get_mass_share_input_port().FixValue(ctx, [m_i])
    eps = 1e-6
    expected = np.array([m_i * GRAVITY * (model.ee_position(Q0 + eps * e)[2]
                                          - model.ee_position(Q0 - eps * e)[2]) / (2 * eps)
                         for e in np.eye(3)])
    sim = Simulator(ff, ctx)
    sim.AdvanceTo(0.0)      # the tick at t = 0 latches
    assert np.allclose(ff.get_tau_ff_output_port().Eval(ctx), expected, rtol=1e-6, atol=1e-9)
    assert np.allclose(ff.get_f_load_output_port().Eval(ctx), [0, 0, m_i * GRAVITY])


def test_a_negative_mass_estimate_is_never_fed_forward(model):
    """A share estimated below zero (the stand still carrying the object at the grasp) feeds
    no load forward, as a zero share does; a positive one its own."""
    ff = LoadFeedforward(model, H)
    ctx = ff.CreateDefaultContext()
    ff.get_q_input_port().FixValue(ctx, Q0)
    ff.get_acceleration_d_input_port().FixValue(ctx, [0.0, 0.0, 0.3])
    ff.get_reference_input_port().FixValue(ctx, _held_reference(held=True))
    ff.get_mass_share_input_port().FixValue(ctx, [-0.057])
    tau, f = ff.load(ctx)
    assert np.array_equal(f, np.zeros(3)) and np.array_equal(tau, np.zeros(3))
    ff.get_mass_share_input_port().FixValue(ctx, [0.1])
    assert np.allclose(ff.load(ctx)[1], [0.0, 0.0, 0.1 * (0.3 + GRAVITY)])


def test_feedforward_is_zero_in_free_motion_and_follows_the_acceleration(model):
    ff = LoadFeedforward(model, H)
    ctx = ff.CreateDefaultContext()
    ff.get_q_input_port().FixValue(ctx, Q0)
    ff.get_acceleration_d_input_port().FixValue(ctx, [0.2, -0.1, 0.5])
    ff.get_mass_share_input_port().FixValue(ctx, [0.25])
    ff.get_reference_input_port().FixValue(ctx, _held_reference(held=False))
    assert np.allclose(ff.load(ctx)[0], 0.0)
    ff.get_reference_input_port().FixValue(ctx, _held_reference(held=True))
    tau, f = ff.load(ctx)
    assert np.allclose(f, 0.25 * np.array([0.2, -0.1, 0.5 + GRAVITY]))
    # Virtual work of that force along a joint displacement, by finite differences.
    eps = 1e-6
    fd = [f @ (model.ee_position(Q0 + eps * e) - model.ee_position(Q0 - eps * e)) / (2 * eps)
          for e in np.eye(3)]
    assert np.allclose(tau, fd, rtol=1e-6)


def test_feedforward_with_friction_passes_no_more_than_the_cone_at_the_commanded_squeeze(model):
    """With ``friction = μ`` the force across the constraint normal is at most ``μ λ_d``
    (checked against the normal ``n`` of the model, independently of the block's projector):
    below the limit the force is the unlimited one; above it its normal part is kept and its
    tangential part has length μ λ_d, in the same direction."""
    mu, m_i, a = 0.5, 1.0, np.array([0.3, -0.2, 0.4])
    free = LoadFeedforward(model, H)
    ff = LoadFeedforward(model, H, friction=mu)
    n = np.asarray(model.N, dtype=float)[0]
    n = n / np.linalg.norm(n)
    f_free = m_i * (a - np.array([0.0, 0.0, -GRAVITY]))
    f_t_free = f_free - (f_free @ n) * n
    for lambda_d in (0.0, 2.0, 0.9 * np.linalg.norm(f_t_free) / mu, 100.0):
        outs = []
        for block in (free, ff):
            ctx = block.CreateDefaultContext()
            block.get_q_input_port().FixValue(ctx, Q0)
            block.get_reference_input_port().FixValue(ctx, _held_reference(lambda_d=lambda_d))
            block.get_acceleration_d_input_port().FixValue(ctx, a)
            block.get_mass_share_input_port().FixValue(ctx, [m_i])
            outs.append(block.load(ctx))
        (tau0, f0), (tau, f) = outs
        f_t = f - (f @ n) * n
        assert np.isclose(f @ n, f0 @ n)                                  # normal part kept
        assert np.linalg.norm(f_t) <= mu * lambda_d + 1e-12               # inside the cone
        if np.linalg.norm(f_t_free) <= mu * lambda_d:
            assert np.allclose(f, f0) and np.allclose(tau, tau0)
        else:
            assert np.isclose(np.linalg.norm(f_t), mu * lambda_d)
            if lambda_d > 0:
                assert np.allclose(f_t / np.linalg.norm(f_t), f_t_free / np.linalg.norm(f_t_free))
        assert np.allclose(tau, model.J_x(Q0).T @ f)
    with pytest.raises(ValueError, match="friction"):
        LoadFeedforward(model, H, friction=-0.1)


# ------------------------------------------------------------------ squeeze selection
def test_squeeze_is_the_least_inside_every_friction_cone():
    rng = np.random.default_rng(7)
    normals = np.array([[1.0, 0, 0], [-1.0, 0, 0]])
    for _ in range(200):
        loads = rng.normal(scale=5.0, size=(2, 3))
        mu = rng.uniform(0.2, 1.2)
        lam, ok = squeeze_for_grasp(loads, normals, mu, margin=1.0)
        assert ok
        fn = np.sum(loads * normals, axis=1)
        ft = np.linalg.norm(loads - fn[:, None] * normals, axis=1)
        normal_force = lam + fn
        assert np.all(ft <= mu * normal_force + 1e-9)            # inside every cone
        if lam > 0:                                                # and the least
            assert np.any(ft > mu * (lam - 1e-6 + fn))
        # A margin scales it.
        lam2, _ = squeeze_for_grasp(loads, normals, mu, margin=1.5)
        assert np.isclose(lam2, max(0.0, 1.5 * np.max(ft / mu - fn)))


def test_squeeze_for_a_hanging_weight_and_the_torque_limit():
    # 2 kg split over two pads, μ = 0.5: each pad carries m g / 2 tangentially.
    loads = np.array([[0, 0, GRAVITY], [0, 0, GRAVITY]])
    normals = [[1, 0, 0], [-1, 0, 0]]
    lam, ok = squeeze_for_grasp(loads, normals, 0.5, margin=1.5)
    assert ok and np.isclose(lam, 1.5 * GRAVITY / 0.5)
    lam, ok = squeeze_for_grasp(loads, normals, 0.5, margin=1.5, lambda_max=20.0)
    assert not ok and lam == 20.0
    for bad in (dict(mu=0.0), dict(mu=-1.0), dict(margin=0.5)):
        args = dict(mu=0.5, margin=1.5) | bad
        with pytest.raises(ValueError, match=next(iter(bad))):
            squeeze_for_grasp(loads, normals, **args)


def test_max_squeeze_against_a_scan():
    rng = np.random.default_rng(3)
    for _ in range(50):
        j, other = rng.normal(size=3), rng.normal(scale=5, size=3)
        lim = np.abs(other) + rng.uniform(1, 20, size=3)
        lam = max_squeeze(j, lim, other)
        grid = np.linspace(0, 200, 200001)
        ok = np.all(np.abs(other[None, :] - grid[:, None] * j[None, :]) <= lim, axis=1)
        assert np.isclose(lam, grid[ok].max() if lam < 200 else lam, atol=2e-3)


# ------------------------------------------------------------------ compliant contact
def test_contact_stiffness_inverse_and_checks():
    k = ContactStiffness(1.6e7, 2.0)
    assert np.isclose(k.compression(32.0), np.sqrt(32.0 / 1.6e7))
    assert np.allclose(k.force(k.compression([0.0, 5.0, 32.0])), [0.0, 5.0, 32.0])
    assert k.compression(-3.0) == 0.0
    with pytest.raises(ValueError, match="a:"):
        ContactStiffness(0.0)
    with pytest.raises(ValueError, match="exponent"):
        ContactStiffness(1e5, 5.0)
    with pytest.raises(ValueError, match="integral_time"):
        ContactStiffness(1e5, 1.0, 0.0)
    # dδ/dλ by a central difference; 1 N floor below.
    lam, eps = 20.0, 1e-4
    fd = (k.compression(lam + eps) - k.compression(lam - eps)) / (2 * eps)
    assert np.isclose(k.compliance(lam), fd, rtol=1e-6)
    assert k.compliance(0.0) == k.compliance(1.0)


def test_the_spheres_law_is_drakes_linear_pressure_field_integrated():
    """``radius``: against a quadrature of ``p = E (1 − ρ/r)`` over the contact disc of a
    sphere pressed ``δ`` into a rigid face (what Drake's hydroelastic sphere carries)."""
    E, r = 5e6, 0.015
    k = ContactStiffness(np.pi * E, 2.0, radius=r)
    for delta in (2e-4, 1e-3, 1.8e-3, 5e-3):
        s = np.linspace(0.0, np.sqrt(r * r - (r - delta) ** 2), 20001)
        p = E * (1.0 - np.sqrt((r - delta) ** 2 + s * s) / r)
        quad = np.sum(0.5 * (p[1:] * s[1:] + p[:-1] * s[:-1]) * np.diff(s)) * 2 * np.pi
        assert k.force(delta) == pytest.approx(quad, rel=1e-6)
    lam = np.array([0.0, 0.3, 14.0, 32.0, 50.0])
    np.testing.assert_allclose(k.force(k.compression(lam)), lam, rtol=1e-12, atol=1e-12)
    assert np.all(k.compression(lam[1:]) > ContactStiffness(np.pi * E, 2.0).compression(lam[1:]))
    eps = 1e-4
    fd = (k.compression(40.0 + eps) - k.compression(40.0 - eps)) / (2 * eps)
    assert k.compliance(40.0) == pytest.approx(fd, rel=1e-6)
    with pytest.raises(ValueError, match="radius"):
        ContactStiffness(1e5, 1.0, radius=0.01)


def test_the_spheres_law_of_one_force_inverts_the_law_as_the_array_path_does():
    """One force (the controller's ``λ_d`` every tick) takes the float path of
    :meth:`ContactStiffness.compression`: the law's inverse (``force``) to 1e-12, and the
    array path's value for the same forces (two at a time) to 4 ulp (the two paths do the
    same IEEE operations in the same order, so they agree bit for bit; the test does not rely
    on it)."""
    k = ContactStiffness(np.pi * 5e6, 2.0, radius=0.015)
    lam = np.array([0.0, 1e-9, 0.3, 14.0, 32.0, 50.0, 400.0])
    single = np.array([k.compression(np.array([x]))[0] for x in lam])
    assert k.compression(np.array([32.0])).shape == (1,)
    np.testing.assert_allclose(k.force(single), lam, rtol=1e-12, atol=1e-12)
    pairs = np.array([k.compression(np.array([x, x]))[0] for x in lam])
    np.testing.assert_allclose(single, pairs, rtol=1e-15, atol=0.0)
    # beyond the hemisphere: r itself (the function returns its radius, no arithmetic)
    assert k.compression(np.array([1e9]))[0] == 0.015


def _exact_sphere_root(t: Fraction, r: Fraction) -> Fraction:
    """The root of ``δ² − 2δ³/(3r) = t`` in ``[0, r]`` by bisection in exact rationals (to
    2⁻⁹⁰ r): independent of the floating-point Newton steps under test."""
    lo, hi = Fraction(0), r
    for _ in range(90):
        mid = (lo + hi) / 2
        if mid * mid - 2 * mid ** 3 / (3 * r) < t:
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2


def test_the_spheres_root_at_and_near_its_double_root_is_the_exact_root_on_any_cpu():
    """At ``λ = a r²/3`` the law's slope vanishes (a double root at ``δ = r``): a force there
    or beyond gives exactly ``r`` (no arithmetic); just below it the Newton steps (on
    ``u = 1 − δ/r``) converge to the exact root of the law. The tolerance is the problem's
    own error bound: ``s = 1 − 3λ/(a r²)`` carries a rounding of a few ulp of 1 (8 ε), which
    moves the root by ``r · 8ε / (6u)`` (``du/ds = 1/(6u(1 − u))``), plus 8 ulp of ``r``
    for the last steps."""
    r = 0.015
    k = ContactStiffness(np.pi * 5e6, 2.0, radius=r)
    cap = k.a * r * r / 3.0
    eps = np.finfo(float).eps
    assert k.compression(cap) == r and k.compression(np.array([cap, 2 * cap]))[0] == r
    forces = [cap * (1 - x) for x in (1e-15, 1e-12, 1e-9, 1e-6, 1e-3, 0.3, 0.5, 0.5000001,
                                      0.7, 0.99)] + [np.nextafter(cap, 0.0), 1e-6, 32.0]
    single = np.array([float(k.compression(x)) for x in forces])
    array = k.compression(np.array(forces))
    for lam, d_one, d_array in zip(forces, single, array):
        t = Fraction(float(lam)) / Fraction(k.a)
        exact = float(_exact_sphere_root(t, Fraction(r)))
        u = max(1.0 - exact / r, 1e-300)
        bound = r * 8 * eps / (6 * u) + 8 * eps * r
        assert abs(d_one - exact) <= bound, (lam, d_one, exact)
        assert abs(d_array - exact) <= bound, (lam, d_array, exact)
        assert 0.0 <= d_one <= r


def test_law_with_a_compliant_contact_is_the_law_with_the_contact_point_pressed_in():
    """p_d = −δ(λ_d): the same as the paper's law whose contact point c is moved by δ along
    the outward normal's opposite (φ = N (x − c) grows by δ) — an independent model — with
    ξ raised by β c(λ_d)/T_i, c = dδ/dλ = √(λ/a)/(2λ) written out here."""
    _, plant, arm = _arm()
    arm_plant = MakeArmControllerPlant(URDF, plant, arm)
    stiff = ContactStiffness(1.6e7, 2.0)
    lam_d = 27.0
    delta = float(stiff.compression(lam_d))
    N = np.array([-1.0, 0.0, 0.0])
    c = np.array([0.5, 0.0, 0.4])
    compliant = FingerLaw(ArmModel.from_plant(arm_plant, "pad", [N], c), Gains(),
                          contact_stiffness=stiff)
    gains = Gains()
    xi_c = gains.beta * np.sqrt(lam_d / 1.6e7) / (2 * lam_d) / stiff.integral_time
    moved = FingerLaw(ArmModel.from_plant(arm_plant, "pad", [N], c - delta * N),
                      Gains(xi=gains.xi + xi_c))
    layout = compliant.layout
    rng = np.random.default_rng(0)
    q, q_hat = Q0, Q0 + 1e-3 * rng.normal(size=3)
    qdot_hat, qdot_o = 0.01 * rng.normal(size=3), 0.01 * rng.normal(size=3)
    ref = layout.unpack(layout.pack(Q0[None] + 0.01, 0.02 * np.ones((1, 3)),
                                    0.03 * np.ones((1, 3)), [[lam_d]], np.array([1.0]))[0])
    DF = np.array([0.3])
    assert np.allclose(compliant.force_estimate(q, q_hat, qdot_o, ref, DF),
                       moved.force_estimate(q, q_hat, qdot_o, ref, DF), rtol=1e-12)
    a = compliant.control(q, q_hat, qdot_hat, qdot_o, np.array([25.0]), DF, ref)
    b = moved.control(q, q_hat, qdot_hat, qdot_o, np.array([25.0]), DF, ref)
    assert np.allclose(a["tau"], b["tau"], rtol=1e-10)
    with pytest.raises(TypeError, match="contact_stiffness"):
        FingerLaw(compliant.model, Gains(), contact_stiffness=3.0)


# ------------------------------------------------------------------ mass estimator
def test_mass_estimator_finds_a_simulated_payload(model):
    """An arm holding a payload (a point mass welded at its pad in the simulated plant,
    unknown to the controller's model) still under Drake's inverse-dynamics PID; the
    estimator reads q, v (as q̇_o), zero q̈̂_r and the commanded τ."""
    payload = 0.42
    builder, plant, arm = _arm(time_step=1e-3, payload=payload)
    ctrl_plant = MakeArmControllerPlant(URDF, plant, arm)
    pid = builder.AddSystem(InverseDynamicsController(
        ctrl_plant, kp=[400.0] * 3, ki=[200.0] * 3, kd=[40.0] * 3,
        has_reference_acceleration=False))
    builder.Connect(plant.get_state_output_port(arm), pid.get_input_port_estimated_state())
    desired = builder.AddSystem(ConstantVectorSource(np.concatenate([Q0, np.zeros(3)])))
    builder.Connect(desired.get_output_port(), pid.get_input_port_desired_state())
    builder.Connect(pid.get_output_port_control(), plant.get_actuation_input_port(arm))
    demux = builder.AddSystem(Demultiplexer([3, 3]))
    builder.Connect(plant.get_state_output_port(arm), demux.get_input_port(0))
    est = builder.AddSystem(MassEstimator(model, H, prior=0.1, prior_std=0.3))
    builder.Connect(demux.get_output_port(0), est.get_q_input_port())
    builder.Connect(demux.get_output_port(1), est.get_qdot_o_input_port())
    zeros = builder.AddSystem(ConstantVectorSource(np.zeros(3)))
    builder.Connect(zeros.get_output_port(), est.get_qddot_r_hat_input_port())
    builder.Connect(zeros.get_output_port(), est.get_acceleration_d_input_port())
    builder.Connect(pid.get_output_port_control(), est.get_tau_input_port())
    held = builder.AddSystem(ConstantVectorSource(_held_reference()))
    builder.Connect(held.get_output_port(), est.get_reference_input_port())
    diagram = builder.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    plant.SetPositions(plant.GetMyMutableContextFromRoot(ctx), arm, Q0)
    sim.AdvanceTo(3.0)
    m_hat = est.get_mass_share_output_port().Eval(est.GetMyContextFromRoot(ctx))[0]
    assert abs(m_hat - payload) < 0.01 * payload


def test_mass_estimator_checks_its_arguments(model):
    for kwargs, name in ((dict(prior=-1.0, prior_std=0.1), "prior"),
                         (dict(prior=0.1, prior_std=0.0), "prior_std"),
                         (dict(prior=0.1, prior_std=0.1, forgetting=1.5), "forgetting")):
        with pytest.raises(ValueError, match=name):
            MassEstimator(model, H, **kwargs)


def test_contact_jacobian_is_the_jacobian_of_the_offset_point(model):
    """J_c of E + r (r fixed in the pad body, given in the world at q) against central
    differences of that body-fixed point's position, from the plant's own pad pose."""
    plant, ctx = model.plant, model.plant.CreateDefaultContext()
    r = np.array([0.015, 0.0, 0.0])
    plant.SetPositions(ctx, Q0)
    X = model.ee_frame.CalcPoseInWorld(ctx)
    r_E = X.rotation().inverse() @ r                     # the point, in the pad's frame
    eps = 1e-6
    cols = []
    for e in np.eye(3):
        pts = []
        for sgn in (1, -1):
            plant.SetPositions(ctx, Q0 + sgn * eps * e)
            pts.append(model.ee_frame.CalcPoseInWorld(ctx) @ r_E)
        cols.append((pts[0] - pts[1]) / (2 * eps))
    from drake_coop.control.object import contact_jacobian
    assert np.allclose(contact_jacobian(model, Q0, r), np.array(cols).T, atol=1e-8)
    assert np.array_equal(contact_jacobian(model, Q0, None), model.J_x(Q0))


# ------------------------------------------------------------------ the shared object-state block
POINTS = np.array([[-0.15, 0.0, 0.0], [0.15, 0.0, 0.0]])
INWARD = np.array([[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])


def _shared(**kwargs):
    args = dict(grasp_points=POINTS, grasp_normals=INWARD,
                layouts=[ReferenceLayout(3, 1), ReferenceLayout(3, 1)], period=H, mu=0.5,
                margin=1.5, grasp_window=(0.0, 100.0), ramp=1.0, rate=1.0, rise_rate=20.0)
    return ObjectStateEstimator(**(args | kwargs))


def _fix(block, context, shares, held=True, a=(0.0, 0.0, 0.0), lambda_d=7.0):
    ref = ReferenceLayout(3, 1).pack(np.full((1, 3), 0.2), np.full((1, 3), 0.3),
                                     np.full((1, 3), 0.4), [[lambda_d]],
                                     np.array([float(held)]))[0]
    for i, m in enumerate(shares):
        block.get_mass_share_input_port(i).FixValue(context, [m])
        block.get_reference_input_port(i).FixValue(context, ref)
    block.get_acceleration_d_input_port().FixValue(context, np.asarray(a, dtype=float))
    return ref


def test_shared_block_gives_back_the_mass_and_the_centre_of_mass_of_the_lever_rule():
    """An object of mass m with its centre of mass at c on the grasp line: the lever rule
    (written out here) gives the shares; the block sums them to m and puts the centre of
    mass back at c; the minimum-norm split of that estimated object is the shares again
    (the shared feedforward would add nothing)."""
    block = _shared()
    context = block.CreateDefaultContext()
    rng = np.random.default_rng(5)
    for _ in range(20):
        m, x = rng.uniform(0.1, 2.0), rng.uniform(-0.1, 0.1)
        d = POINTS[1, 0] - POINTS[0, 0]
        shares = [m * (POINTS[1, 0] - x) / d, m * (x - POINTS[0, 0]) / d]
        _fix(block, context, shares)
        assert block.get_total_mass_output_port().Eval(context)[0] == pytest.approx(m)
        assert np.allclose(block.get_com_output_port().Eval(context), [x, 0, 0], atol=1e-12)
        back = mass_shares(ObjectModel(m, [x, 0, 0], np.zeros((3, 3)), POINTS, INWARD))
        assert np.allclose(back, shares, atol=1e-12)


def test_shared_squeeze_holds_the_true_load_inside_every_cone_with_the_margin():
    """Shares of a 1.2 kg box whose centre of mass is 4 cm off the middle, a static hold and
    an acceleration: the squeeze the block settles on, held long enough, against the cone
    inequality at the true load (each pad's share m_i (a − g), normals ±x) written out:
    λ = margin · max_i(|t_i|/μ − n_i·f_i)."""
    block = _shared(rate=50.0, rise_rate=50.0)
    m, x = 1.2, 0.04
    shares = np.array([m * (0.15 - x) / 0.3, m * (x + 0.15) / 0.3])
    for a in ([0.0, 0.0, 0.0], [0.3, -0.2, 0.5]):
        context = block.CreateDefaultContext()
        ref = _fix(block, context, shares, a=a)
        simulator = Simulator(block, context)
        simulator.AdvanceTo(2.0)
        lam = float(block.get_squeeze_output_port().Eval(context)[0])
        a = np.asarray(a)
        # Along the normals the minimum-norm split shares the x force equally.
        f = np.array([[m * a[0] / 2, mi * a[1], mi * (a[2] + GRAVITY)] for mi in shares])
        fn = np.sum(f * INWARD, axis=1)
        t = np.linalg.norm(f - fn[:, None] * INWARD, axis=1)
        assert lam == pytest.approx(1.5 * np.max(t / 0.5 - fn), rel=1e-9)
        assert np.all(t <= 0.5 * (lam + fn))                      # inside every cone
        # The references pass through with λ_d = s(t) λ (s = 1 here), the rest unchanged.
        out = block.get_reference_output_port(1).Eval(context)
        assert out[9] == pytest.approx(lam) and np.array_equal(np.delete(out, 9),
                                                               np.delete(ref, 9))


def test_shared_squeeze_falls_at_its_rate_never_below_the_hold_and_ramps_at_the_grasp():
    block = _shared(rate=1.0, rise_rate=20.0, grasp_window=(1.0, 30.0), lambda_min=0.0)
    context = block.CreateDefaultContext()
    hold = lambda m: m / 2 * GRAVITY / 0.5                        # one pad's m g/2 over μ
    _fix(block, context, [0.75, 0.75], held=True)                 # a +50 % prior of 1 kg
    simulator = Simulator(block, context)
    simulator.Initialize()
    assert block.get_squeeze_output_port().Eval(context)[0] == pytest.approx(1.5 * hold(1.5))
    # Before the grasp window the reference carries no squeeze; half way up the ramp, half.
    simulator.AdvanceTo(0.5)
    assert block.get_reference_output_port(0).Eval(context)[9] == 0.0
    # The estimate falls to the truth: the squeeze falls by 1 N/s (one tick: r h), down to
    # margin × the hold of the truth, not below.
    _fix(block, context, [0.5, 0.5])
    lam0 = float(block.get_squeeze_output_port().Eval(context)[0])
    simulator.AdvanceTo(0.5 + 100 * H + 1e-9)
    lam1 = float(block.get_squeeze_output_port().Eval(context)[0])
    assert lam0 - lam1 == pytest.approx(100 * H * 1.0, rel=1e-6)
    simulator.AdvanceTo(20.0)
    assert block.get_squeeze_output_port().Eval(context)[0] == pytest.approx(1.5 * hold(1.0))
    # The estimate jumps up: the squeeze rises at 20 N/s but is never below the hold of the
    # estimated load (margin 1) at any tick.
    _fix(block, context, [2.0, 2.0])
    lam = []
    for k in range(1, 130):
        simulator.AdvanceTo(20.0 + k * H + 1e-9)
        lam.append(float(block.get_squeeze_output_port().Eval(context)[0]))
    assert lam[0] == pytest.approx(hold(4.0))                     # the floor, at once
    assert np.allclose(np.diff(lam[:5]), 20.0 * H)                # then the rise rate
    assert lam[-1] == pytest.approx(1.5 * hold(4.0))
    # The envelope: λ_d = s(t) λ with s the 1 s ramps inside the window.
    assert block.envelope(1.25) == 0.25 and block.envelope(29.5) == 0.5
    assert block.envelope(0.9) == 0.0 and block.envelope(15.0) == 1.0


@pytest.mark.parametrize("kwargs, name", [
    (dict(grasp_points=POINTS[:1], grasp_normals=INWARD[:1]), "grasp_points"),
    (dict(layouts=[ReferenceLayout(3, 1)]), "layouts"),
    (dict(mu=0.0), "mu"),
    (dict(margin=0.9), "margin"),
    (dict(grasp_window=(5.0, 5.0)), "grasp_window"),
    (dict(rate=0.0), "rate"),
    (dict(rise_rate=-1.0), "rise_rate"),
    (dict(force_weights=[[1.0, 2.0], [1.0]]), "force_weights"),
])
def test_shared_block_rejects_bad_arguments_naming_them(kwargs, name):
    with pytest.raises(ValueError, match=name):
        _shared(**kwargs)


def test_compressed_reference_puts_the_pad_delta_inside_along_the_normal(model):
    """The pressed-in q_d's forward kinematics (the plant's) against x(q_d) + δ(λ_d) n, to
    second order in δ; not held: unchanged."""
    stiff = ContactStiffness(1.57e7, 2.0)
    block = CompressedReference(model, stiff, [1.0, 0.0, 0.0])
    context = block.CreateDefaultContext()
    layout = ReferenceLayout(3, 1)
    for lam, held in ((30.0, 1.0), (5.0, 1.0), (30.0, 0.0)):
        r = layout.pack(Q0[None], np.full((1, 3), 0.1), np.full((1, 3), 0.2), [[lam]],
                        np.array([held]))[0]
        block.get_reference_input_port().FixValue(context, r)
        out = block.get_compressed_reference_output_port().Eval(context)
        assert np.array_equal(out[3:], r[3:])
        delta = float(np.sqrt(lam / 1.57e7)) * held
        moved = model.ee_position(out[:3]) - model.ee_position(Q0)
        assert np.allclose(moved, [delta, 0.0, 0.0], atol=50 * delta ** 2 + 1e-12)
    # Following the pad's material point P (2 cm off the centre in the pad's frame) across
    # the normal and the centre E along it: y = T P + n nᵀ E moves by δ n.
    offset = np.array([0.004, 0.0, 0.02])
    point = ArmModel(model.plant, model.ee_frame.name(), model.N, model.c,
                     point_offset=offset)
    block = CompressedReference(model, stiff, [1.0, 0.0, 0.0], point_offset=offset)
    context = block.CreateDefaultContext()
    r = layout.pack(Q0[None], np.zeros((1, 3)), np.zeros((1, 3)), [[30.0]], np.array([1.0]))[0]
    block.get_reference_input_port().FixValue(context, r)
    q1 = block.get_compressed_reference_output_port().Eval(context)[:3]
    T = np.diag([0.0, 1.0, 1.0])
    y = lambda q: T @ point.ee_position(q) + (np.eye(3) - T) @ model.ee_position(q)
    delta = float(np.sqrt(30.0 / 1.57e7))
    error = y(q1) - y(Q0) - [delta, 0.0, 0.0]
    # Against the centre's block, whose pressing moves P across the normal (first order).
    q_centre = CompressedReference(model, stiff, [1.0, 0.0, 0.0]).compressed(r)[:3]
    across = np.linalg.norm((y(q_centre) - y(Q0))[1:])
    assert across > 1e-5 and np.linalg.norm(error) < min(0.25 * across, 2 * delta ** 2)
    with pytest.raises(ValueError, match="inward"):
        CompressedReference(model, stiff, [0.0, 0.0, 0.0])
    with pytest.raises(TypeError, match="stiffness"):
        CompressedReference(model, 3.0, [1.0, 0.0, 0.0])
