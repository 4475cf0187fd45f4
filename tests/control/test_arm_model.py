"""The controller model's kinematics: ``J̇_φ`` in closed form from the geometric Jacobian
against forward-mode AutoDiff and central differences, the plain-float row at ``m = 1``, and
one kinematics evaluation per tick."""

import numpy as np
import pytest

from bench.seven_joint import write_seven_joint_urdf
from drake_coop.control.arm_model import ArmModel
from drake_coop.control.arm_plant import make_arm_controller_plant
from drake_coop.control.finger import FingerLaw
from drake_coop.control.reference_layout import Reference
from drake_coop.control.params import Gains
from drake_coop.plant.arms import Arm, arm_model
from drake_coop.scenario import load_scenario
from drake_coop.scenario.resources import find_scenario


@pytest.fixture(scope="module")
def seven(tmp_path_factory):
    plant = make_arm_controller_plant(write_seven_joint_urdf(tmp_path_factory.mktemp("arm")),
                                      "base_link")
    return ArmModel(plant, "pad", [[1.0, 0.0, 0.0], [0.0, 0.3, 1.0]], [0.5, 0.0, 0.5])


def _models(seven):
    six = load_scenario(find_scenario("six_joint"))
    paper = load_scenario()
    return [seven, arm_model(Arm(six.robots[0], six.task)),
            arm_model(Arm(paper.robots[0], paper.task), closed_form=False)]


def test_the_shipped_arms_and_ours_are_serial_chains(seven):
    assert all(m.serial_chain and not m.closed_form for m in _models(seven))


def test_J_phi_dot_is_autodiffs_and_the_central_difference(seven):
    rng = np.random.default_rng(3)
    for model in _models(seven):
        for _ in range(5):
            q, d = rng.uniform(-1.5, 1.5, model.n), rng.normal(size=model.n)
            J, Jd = model.J_phi_and_derivative(q, d)
            J_ad, Jd_ad = model.J_phi_and_derivative_autodiff(q, d)
            np.testing.assert_allclose(J, J_ad, rtol=0, atol=1e-13)
            np.testing.assert_allclose(Jd, Jd_ad, rtol=0, atol=1e-12 * max(1, np.abs(Jd_ad).max()))
            e = 1e-6
            fd = (model.J_phi(q + e * d) - model.J_phi(q - e * d)) / (2 * e)
            np.testing.assert_allclose(Jd, fd, rtol=0, atol=1e-8 * max(1, np.abs(fd).max()))
            # J̇_φ q̇ (what Drake's bias acceleration gives) is one product of it.
            scale = max(1, np.abs(Jd_ad @ d).max())
            np.testing.assert_allclose(Jd @ d, Jd_ad @ d, rtol=0, atol=1e-12 * scale)


def test_the_autodiff_fallback_is_the_central_difference(seven):
    """What a model that is not a serial chain of one-velocity joints uses."""
    model = ArmModel(seven.plant, "pad", [1.0, 0.0, 0.2], [0.0, 0.0, 0.0])
    model.serial_chain = False
    rng = np.random.default_rng(0)
    q, d = rng.uniform(-1, 1, model.n), rng.normal(size=model.n)
    e = 1e-6
    fd = (model.J_phi(q + e * d) - model.J_phi(q - e * d)) / (2 * e)
    np.testing.assert_allclose(model.J_phi_and_derivative(q, d)[1], fd, atol=1e-8)
    np.testing.assert_allclose(model.constraint_row_dot(q, d), fd[0], atol=1e-8)


def test_the_plain_float_row_is_phi_and_its_derivative(seven):
    rng = np.random.default_rng(4)
    q, d = rng.uniform(-1, 1, 7), rng.normal(size=7)
    phi, row = seven.constraint_row(q)
    assert phi == pytest.approx(seven.phi(q)[0], abs=1e-15)
    np.testing.assert_allclose(row, seven.J_phi(q)[0], atol=1e-15)
    e = 1e-6
    fd = (seven.J_phi(q + e * d) - seven.J_phi(q - e * d))[0] / (2 * e)
    np.testing.assert_allclose(seven.constraint_row_dot(q, d), fd, atol=1e-8)


class _Counting:
    """The model's plant, counting its Jacobian evaluations."""

    def __init__(self, plant):
        self._plant, self.count = plant, 0

    def CalcJacobianSpatialVelocity(self, *args):
        self.count += 1
        return self._plant.CalcJacobianSpatialVelocity(*args)

    def __getattr__(self, name):
        return getattr(self._plant, name)


@pytest.mark.parametrize("m", [1, 2])
def test_one_kinematics_evaluation_per_tick_and_both_paths_agree(seven, m):
    normals = [[1.0, 0.0, 0.0], [0.0, 0.3, 1.0]][:m]
    model = ArmModel(seven.plant, "pad", normals, [0.5, 0.0, 0.5])
    law = FingerLaw(model, Gains(K_R=[50.0] * 7))
    assert law.fast == (m == 1)
    counting = _Counting(model.plant)
    model.plant = counting
    rng = np.random.default_rng(5)
    out = []
    for k in range(3):
        q = rng.uniform(-1, 1, 7)
        q_hat, qdot_hat_o = q + 1e-3, rng.normal(size=7) * 0.1
        ref = Reference(q + 2e-3, rng.normal(size=7) * 0.1, rng.normal(size=7) * 0.1,
                        np.full(m, 10.0), True)
        DF = np.full(m, 0.2)
        qdot_hat, qdot_o = law.observer_derivative(q, q_hat, qdot_hat_o)
        lam = law.force_estimate(q, q_hat, qdot_o, ref, DF)
        terms = law.control(q, q_hat, qdot_hat, qdot_o, lam, DF, ref)
        assert counting.count == k + 1          # one evaluation per tick, shared
        out.append((q, q_hat, qdot_hat, qdot_o, lam, DF, ref, terms))
    if m == 1:      # the plain-float path equals the NumPy path on the same doubles' math
        law.fast = False
        for q, q_hat, qdot_hat, qdot_o, lam, DF, ref, terms in out:
            np.testing.assert_allclose(law.force_estimate(q, q_hat, qdot_o, ref, DF), lam,
                                       rtol=1e-10)
            general = law.control(q, q_hat, qdot_hat, qdot_o, lam, DF, ref)
            for key in ("tau", "qdot_r", "qddot_r_hat"):
                np.testing.assert_allclose(terms[key], general[key], rtol=1e-10, atol=1e-10)


def test_coulomb_compensation_is_the_smoothed_sign_added_to_the_inverse_dynamics(seven):
    F_c = np.array([1.0, 2.0, 0.5, 0.8, 0.3, 0.2, 0.1])
    with_friction = ArmModel(seven.plant, "pad", [1.0, 0.0, 0.0], [0.5, 0.0, 0.5],
                             coulomb=F_c, coulomb_velocity=0.05)
    plain = ArmModel(seven.plant, "pad", [1.0, 0.0, 0.0], [0.5, 0.0, 0.5])
    rng = np.random.default_rng(8)
    q, v, a = rng.uniform(-1, 1, 7), rng.uniform(-0.2, 0.2, 7), rng.normal(size=7)
    np.testing.assert_allclose(with_friction.inverse_dynamics_terms(q, v, a)
                               - plain.inverse_dynamics_terms(q, v, a),
                               [f * np.tanh(x / 0.05) for f, x in zip(F_c, v)], atol=1e-12)
    np.testing.assert_array_equal(plain.friction_torque(v), np.zeros(7))
    for bad in ([1.0] * 6, [-1.0] * 7):
        with pytest.raises(ValueError, match="coulomb"):
            ArmModel(seven.plant, "pad", [1.0, 0.0, 0.0], [0.5, 0.0, 0.5], coulomb=bad)
    with pytest.raises(ValueError, match="coulomb_velocity"):
        ArmModel(seven.plant, "pad", [1.0, 0.0, 0.0], [0.5, 0.0, 0.5], coulomb=F_c,
                 coulomb_velocity=0.0)


# ------------------------------------------------------------ a controlled point off the frame


OFFSET = np.array([0.004, -0.007, 0.011])


def _offset_models(seven):
    """The same arms controlling the pad-body point OFFSET: Drake's kinematics (a 7-joint and
    the paper's arm) and the closed form of the paper's arm."""
    paper = load_scenario()
    arm = Arm(paper.robots[0], paper.task)
    centre = arm_model(arm)
    drake = ArmModel(seven.plant, "pad", seven.N, seven.c, point_offset=OFFSET)
    paper_drake = ArmModel(centre.plant, arm.ee_frame, arm.N, arm.c, point_offset=OFFSET)
    paper_closed = ArmModel(centre.plant, arm.ee_frame, arm.N, arm.c,
                            closed_form=arm.kinematics, point_offset=OFFSET)
    return drake, paper_drake, paper_closed


def test_the_offset_point_is_drakes_fixed_offset_frame(seven):
    """Against an independent construction: a FixedOffsetFrame at the offset added to the
    arm's plant before Finalize, whose origin and Jacobian Drake computes."""
    from pydrake.math import RigidTransform
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import FixedOffsetFrame, JacobianWrtVariable

    paper = load_scenario()
    arm = Arm(paper.robots[0], paper.task)
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(arm.urdf_path))
    from pydrake.math import RotationMatrix
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(arm.base_frame),
                     RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base))
    frame = plant.AddFrame(FixedOffsetFrame("P", plant.GetFrameByName("pad"),
                                            RigidTransform(OFFSET)))
    plant.Finalize()
    context = plant.CreateDefaultContext()
    _, paper_drake, paper_closed = _offset_models(seven)
    rng = np.random.default_rng(8)
    for _ in range(5):
        q = np.array([rng.uniform(-1, 1), rng.uniform(0.1, 1.2), rng.uniform(0.3, 1.8)])
        plant.SetPositions(context, q)
        p = frame.CalcPoseInWorld(context).translation()
        J = plant.CalcJacobianTranslationalVelocity(context, JacobianWrtVariable.kV, frame,
                                                    np.zeros(3), plant.world_frame(),
                                                    plant.world_frame())
        for model in (paper_drake, paper_closed):
            np.testing.assert_allclose(model.ee_position(q), p, rtol=0, atol=1e-14)
            np.testing.assert_allclose(model.J_x(q), J, rtol=0, atol=1e-14)
            np.testing.assert_allclose(model.phi(q), arm.N @ (p - arm.c), rtol=0, atol=1e-14)
            phi, row = model.constraint_row(q)
            np.testing.assert_allclose([phi], model.phi(q), rtol=0, atol=1e-14)
            np.testing.assert_allclose(row, arm.N[0] @ J, rtol=0, atol=1e-14)


def test_the_offset_points_jacobian_and_its_derivative_are_finite_differences(seven):
    rng = np.random.default_rng(4)
    for model in _offset_models(seven):
        for _ in range(4):
            q = rng.uniform(0.2, 1.2, model.n)
            d = rng.normal(size=model.n)
            e = 1e-6
            fd_x = np.column_stack([(model.ee_position(q + e * u) - model.ee_position(q - e * u))
                                    / (2 * e) for u in np.eye(model.n)])
            np.testing.assert_allclose(model.J_x(q), fd_x, rtol=0, atol=1e-9)
            J, Jd = model.J_phi_and_derivative(q, d)
            fd = (model.J_phi(q + e * d) - model.J_phi(q - e * d)) / (2 * e)
            np.testing.assert_allclose(Jd, fd, rtol=0, atol=1e-8 * max(1, np.abs(fd).max()))
            np.testing.assert_allclose(Jd, model.J_phi_and_derivative_autodiff(q, d)[1],
                                       rtol=0, atol=1e-12)
            if model.m == 1:
                np.testing.assert_allclose(model.constraint_row_dot(q, d), Jd[0], rtol=0,
                                           atol=1e-12)


def test_a_zero_offset_is_the_frames_origin_and_a_bad_one_is_refused(seven):
    paper = load_scenario()
    arm = Arm(paper.robots[1], paper.task)
    centre = arm_model(arm)
    zero = ArmModel(centre.plant, arm.ee_frame, arm.N, arm.c, closed_form=arm.kinematics,
                    point_offset=np.zeros(3))
    q = np.array([0.1, 0.5, 1.0])
    assert (zero.ee_position(q) == centre.ee_position(q)).all()
    assert zero.constraint_row(q) == centre.constraint_row(q)
    with pytest.raises(ValueError, match="point_offset"):
        ArmModel(seven.plant, "pad", seven.N, seven.c, point_offset=[0.0, np.nan, 0.0])
