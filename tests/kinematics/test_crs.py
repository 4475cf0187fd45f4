"""The closed-form kinematics of the paper's arms with a controlled point off the pad's centre
(``CrsKinematics(offset=...)``) against Drake's kinematics of the same point of the same
URDF (``p_BoBp_B`` of Drake's Jacobian functions), finite differences for ``J̇``, and the
inverse kinematics' round trip."""

import numpy as np
import pytest
from pydrake.multibody.tree import JacobianWrtVariable

from drake_coop.control.arm_plant import make_arm_controller_plant
from drake_coop.plant.arms import Arm
from drake_coop.scenario import load_scenario

OFFSETS = [np.zeros(3), np.array([-0.002, 0.0, 0.0149]), np.array([0.004, -0.007, 0.011])]


@pytest.fixture(scope="module", params=[0, 1], ids=["a465", "a255"])
def arm(request):
    s = load_scenario()
    a = Arm(s.robots[request.param], s.task)
    from pydrake.math import RigidTransform, RotationMatrix
    plant = make_arm_controller_plant(a.urdf_path, a.base_frame,
                                      RigidTransform(RotationMatrix.MakeZRotation(a.yaw),
                                                     a.p_base))
    return a, plant


def _postures(n):
    rng = np.random.default_rng(11)    # elbow up, in front of the base: the paper's branch
    return np.column_stack([rng.uniform(-1.0, 1.0, n), rng.uniform(0.1, 1.2, n),
                            rng.uniform(0.3, 1.8, n)])


@pytest.mark.parametrize("offset", OFFSETS, ids=["centre", "pad_contact", "general"])
def test_the_offset_point_is_drakes_point_of_the_pad_body(arm, offset):
    a, plant = arm
    kin = a.kinematics.with_offset(offset)
    context = plant.CreateDefaultContext()
    pad = plant.GetFrameByName("pad")
    world = plant.world_frame()
    Q = _postures(6)
    for q in Q:
        plant.SetPositions(context, q)
        p = plant.CalcPointsPositions(context, pad, offset.reshape(3, 1), world)[:, 0]
        J = plant.CalcJacobianTranslationalVelocity(context, JacobianWrtVariable.kV, pad,
                                                    offset, world, world)
        R = pad.CalcRotationMatrixInWorld(context).matrix()
        np.testing.assert_allclose(kin.fk(q), p, rtol=0, atol=1e-14)
        np.testing.assert_allclose(kin.jacobian(q), J, rtol=0, atol=1e-14)
        np.testing.assert_allclose(kin.pad_rotation(q), R, rtol=0, atol=1e-14)
    # The vectorised forms give the same numbers as the one-sample ones.
    np.testing.assert_allclose(kin.fk(Q), [kin.fk(q) for q in Q], rtol=0, atol=1e-15)
    np.testing.assert_allclose(kin.jacobian(Q), [kin.jacobian(q) for q in Q], rtol=0,
                               atol=1e-15)


@pytest.mark.parametrize("offset", OFFSETS[1:], ids=["pad_contact", "general"])
def test_jacobian_dot_is_the_central_difference(arm, offset):
    kin = arm[0].kinematics.with_offset(offset)
    rng = np.random.default_rng(5)
    for q in _postures(5):
        v = rng.normal(size=3)
        e = 1e-6
        fd = (kin.jacobian(q + e * v) - kin.jacobian(q - e * v)) / (2 * e)
        np.testing.assert_allclose(kin.jacobian_dot(q, v), fd, rtol=0, atol=1e-9)
        np.testing.assert_allclose(kin.jacobian_dot(q[None], v[None])[0],
                                   kin.jacobian_dot(q, v), rtol=0, atol=1e-15)


@pytest.mark.parametrize("offset", OFFSETS, ids=["centre", "pad_contact", "general"])
def test_inverse_kinematics_returns_the_posture(arm, offset):
    kin = arm[0].kinematics.with_offset(offset)
    Q = _postures(20)
    np.testing.assert_allclose(kin.ik(kin.fk(Q)), Q, rtol=0, atol=1e-10)
    x = kin.fk(Q[:3])
    xd = np.array([[0.01, -0.02, 0.03]] * 3)
    q, qd, qdd = kin.joint_reference(x, xd, np.zeros((3, 3)))
    np.testing.assert_allclose(np.einsum("kij,kj->ki", kin.jacobian(q), qd), xd, rtol=0,
                               atol=1e-12)


def test_a_zero_offset_is_the_centre_to_the_last_bit(arm):
    centre, zero = arm[0].kinematics, arm[0].kinematics.with_offset(np.zeros(3))
    Q = _postures(8)
    assert (centre.fk(Q) == zero.fk(Q)).all() and (centre.ik(centre.fk(Q)) == zero.ik(
        centre.fk(Q))).all()


def test_a_bad_offset_is_refused_naming_it(arm):
    with pytest.raises(ValueError, match="offset"):
        arm[0].kinematics.with_offset([0.0, 1.0])


def test_the_pads_angular_velocity_is_drakes(arm):
    a, plant = arm
    context = plant.CreateDefaultContext()
    pad = plant.GetFrameByName("pad")
    world = plant.world_frame()
    rng = np.random.default_rng(2)
    Q = _postures(4)
    V = rng.normal(size=(4, 3))
    for q, v in zip(Q, V):
        plant.SetPositions(context, q)
        J = plant.CalcJacobianSpatialVelocity(context, JacobianWrtVariable.kV, pad, np.zeros(3),
                                              world, world)
        np.testing.assert_allclose(a.kinematics.angular_velocity(q, v), J[:3] @ v, rtol=0,
                                   atol=1e-14)
    np.testing.assert_allclose(a.kinematics.angular_velocity(Q, V),
                               [a.kinematics.angular_velocity(q, v) for q, v in zip(Q, V)],
                               rtol=0, atol=1e-15)
