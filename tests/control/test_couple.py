"""The squeeze's couple in the load split (drake_coop.control.couple) against
independent computations: a moment balance by hand, Drake's forward dynamics of a free box
under the pads' forces, the virtual work of one arm's share, and the mass estimator fed a
static hold that carries the couple."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce, MultibodyPlant
from pydrake.multibody.tree import SpatialInertia, UnitInertia
from pydrake.systems.analysis import Simulator
from pydrake.common.value import AbstractValue

from drake_coop.control import ArmModel, MakeArmControllerPlant
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.object import GRAVITY, LoadFeedforward, MassEstimator
from drake_coop.control.couple import face_distance, squeeze_couple
from drake_coop.scenario.resources import urdf_dir
from tests.control.test_object import _arm

H = 0.009
URDF = str(urdf_dir() / "crs_a465_3dof.urdf")
Q0 = np.array([0.1, 0.3, 1.7])


@pytest.fixture(scope="module")
def model():
    _, plant, arm = _arm()
    return ArmModel.from_plant(MakeArmControllerPlant(URDF, plant, arm), "pad",
                               [[-1.0, 0.0, 0.0]], [0.5, 0.0, 0.4])


def _held(lambda_d=0.0, n=3, m=1):
    return ReferenceLayout(n, m).pack(np.zeros((1, n)), np.zeros((1, n)), np.zeros((1, n)),
                                      np.full((1, m), lambda_d), np.array([1.0]))[0]


def test_the_higher_pad_carries_less_by_the_hand_derived_moment_balance():
    """Pads along x, pad 1 (pushing +x) 3 mm above pad 2, λ = 30 N, ρ = 15 mm pressed 1 mm
    in: the moment about y of the normal pair is λ Δz, the vertical forces' lever the faces'
    distance w = 0.2 − 2 (0.015 − 0.001) = 0.172 m, so f_1,z = −f_2,z = −λ Δz / w."""
    E = np.array([[-0.1, 0.0, 0.002], [0.1, 0.0, -0.001]])
    w = face_distance(E, [1.0, 0.0, 0.0], [0.015, 0.015], [0.001, 0.001])
    assert w == pytest.approx(0.172, abs=1e-12)
    f = squeeze_couple(E, [2.0, 0.0, 0.0], 30.0, w)       # the normal is normalized
    assert f[0] == pytest.approx([0.0, 0.0, -30.0 * 0.003 / 0.172], abs=1e-12)
    assert f[1] == pytest.approx(-f[0], abs=1e-15)
    # Along a path (leading dimension), and zero with the centres at one height.
    path = np.stack([E, E * [1, 1, 0]])
    fp = squeeze_couple(path, [1.0, 0.0, 0.0], [30.0, 30.0], [0.172, 0.172])
    assert fp[0] == pytest.approx(f, abs=1e-15) and np.all(fp[1] == 0.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_free_box_under_the_pads_forces_stays_at_rest(seed):
    """Drake's forward dynamics of a free box (mass m, centre of mass at its centre) under
    gravity and the two pads' forces: each pad's normal force λ n_i on the line through its
    centre E_i (applied at its face point p_i = E_i + (ρ − δ) n_i on that line), and at
    p_i its share of the weight m g / 2 plus its part of the couple. The box's spatial
    acceleration is zero with the couple and not without it."""
    rng = np.random.default_rng(seed)
    m, lam, rho, delta = 0.5, rng.uniform(10, 50), 0.015, rng.uniform(0.0005, 0.002)
    width = 0.19                                             # between the faces
    # The centres' y, z offsets; y symmetric about the centre of mass, so that the weight
    # has no moment about the grasp line (that torsion is the patches' torsional friction's,
    # not the couple's: the couple's own forces have none).
    a, z = rng.uniform(-0.004, 0.004), rng.uniform(-0.004, 0.004, size=2)
    offset = np.array([[a, z[0]], [-a, z[1]]])
    n = np.array([1.0, 0.0, 0.0])
    E = np.array([[-width / 2 - rho + delta, *offset[0]],
                  [width / 2 + rho - delta, *offset[1]]])
    plant = MultibodyPlant(0.0)
    box = plant.AddRigidBody("box", SpatialInertia.MakeFromCentralInertia(
        m, np.zeros(3), m * UnitInertia.SolidBox(width, 0.08, 0.1)))
    plant.Finalize()
    ctx = plant.CreateDefaultContext()
    lever = face_distance(E, n, [rho, rho], [delta, delta])
    assert lever == pytest.approx(width, abs=1e-12)
    couple = squeeze_couple(E, n, lam, lever)

    def acceleration(with_couple):
        forces = []
        for i, sign in enumerate((1.0, -1.0)):
            p = E[i] + (rho - delta) * sign * n
            f = lam * sign * n + np.array([0.0, 0.0, m * GRAVITY / 2])
            if with_couple:
                f = f + couple[i]
            applied = ExternallyAppliedSpatialForce()
            applied.body_index = box.index()
            applied.p_BoBq_B = p                      # the box's frame is the world's here
            applied.F_Bq_W = SpatialForce(np.zeros(3), f)
            forces.append(applied)
        plant.get_applied_spatial_force_input_port().FixValue(
            ctx, AbstractValue.Make(forces))
        return plant.get_generalized_acceleration_output_port().Eval(ctx)

    assert np.abs(acceleration(True)).max() < 1e-9
    assert np.abs(acceleration(False)).max() > 1e-3


def test_one_arms_torque_is_the_virtual_work_of_its_share_and_its_couple(model):
    """τ_ff = J_xᵀ (m_i g ẑ + f_c): by central differences of the pad's position, with
    f_c = −λ Δz / w ẑ from the moment balance (pad 1 2 mm above pad 2, w = 0.19 m)."""
    m_i, lam, dz, w = 0.25, 40.0, 0.002, 0.19
    f_c = squeeze_couple([[-0.1, 0.0, dz], [0.1, 0.0, 0.0]], [1.0, 0.0, 0.0], lam, w)[0]
    ff = LoadFeedforward(model, H, couple=True)
    ctx = ff.CreateDefaultContext()
    ff.get_q_input_port().FixValue(ctx, Q0)
    ff.get_reference_input_port().FixValue(ctx, _held())
    ff.get_acceleration_d_input_port().FixValue(ctx, np.zeros(3))
    ff.get_mass_share_input_port().FixValue(ctx, [m_i])
    ff.get_f_couple_input_port().FixValue(ctx, f_c)
    force = np.array([0.0, 0.0, m_i * GRAVITY - lam * dz / w])
    eps = 1e-6
    expected = [force @ (model.ee_position(Q0 + eps * e) - model.ee_position(Q0 - eps * e))
                / (2 * eps) for e in np.eye(3)]
    tau, f = ff.load(ctx)
    assert np.allclose(f, force, atol=1e-12)
    assert np.allclose(tau, expected, rtol=1e-6, atol=1e-9)
    with pytest.raises(ValueError, match="couple"):
        LoadFeedforward(model, H).get_f_couple_input_port()


def test_the_estimator_takes_the_couple_out_of_the_mass(model):
    """A static hold whose pad carries m_i g plus a couple force: the commanded torque is
    g(q) + J_xᵀ (m_i g ẑ + f_c) (inverse dynamics of the model at rest). With the couple
    fed in, the estimate converges to m_i; without, to m_i + f_c,z / g."""
    m_i, f_c = 0.3, np.array([0.0, 0.0, -0.4])
    tau = model.inverse_dynamics_terms(Q0, np.zeros(3), np.zeros(3)) \
        + model.J_x(Q0).T @ (np.array([0.0, 0.0, m_i * GRAVITY]) + f_c)
    estimates = []
    for couple in (True, False):
        est = MassEstimator(model, H, prior=0.1, prior_std=0.3, couple=couple)
        ctx = est.CreateDefaultContext()
        for port, value in ((est.get_q_input_port(), Q0), (est.get_qdot_o_input_port(),
                            np.zeros(3)), (est.get_qddot_r_hat_input_port(), np.zeros(3)),
                            (est.get_tau_input_port(), tau),
                            (est.get_acceleration_d_input_port(), np.zeros(3)),
                            (est.get_reference_input_port(), _held())):
            port.FixValue(ctx, value)
        if couple:
            est.get_f_couple_input_port().FixValue(ctx, f_c)
        Simulator(est, ctx).AdvanceTo(2.0)
        estimates.append(est.get_mass_share_output_port().Eval(ctx)[0])
    assert estimates[0] == pytest.approx(m_i, rel=1e-3)
    assert estimates[1] == pytest.approx(m_i + f_c[2] / GRAVITY, rel=1e-3)


@pytest.mark.parametrize("kwargs, name", [
    (dict(centres=np.zeros((3, 3)), normal=[1, 0, 0], lam=1.0, lever=0.1), "centres"),
    (dict(centres=np.zeros((2, 3)), normal=[0, 0, 0], lam=1.0, lever=0.1), "normal"),
    (dict(centres=np.zeros((2, 3)), normal=[1, 0, 0], lam=1.0, lever=0.0), "lever"),
    (dict(centres=np.zeros((2, 3)), normal=[1, 0, 0], lam=np.nan, lever=0.1), "lam"),
])
def test_bad_arguments_are_named(kwargs, name):
    with pytest.raises(ValueError, match=name):
        squeeze_couple(**kwargs)
    with pytest.raises(ValueError, match="radii"):
        face_distance(np.zeros((2, 3)), [1, 0, 0], [-0.01, 0.01])
