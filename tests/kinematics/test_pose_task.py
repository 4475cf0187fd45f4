"""drake_coop.kinematics.pose_task: which pad control each arm can do, and a pad-body point's
kinematics through Drake against the paper's arms' closed form (an independent computation:
trigonometry of the link lengths against Drake's multibody tree of the URDF)."""

import math
from pathlib import Path

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix

from drake_coop.kinematics.drake_arm import DrakeArmKinematics
from drake_coop.kinematics.pose_task import DrakePadPoint, pad_control, point_kinematics
from drake_coop.plant.arms import Arm
from drake_coop.scenario import paper_robots

URDF = Path(__file__).resolve().parents[2] / "urdf"
CRS_MODELS = ("crs_a465", "crs_a255")
OFFSET = np.array([0.004, -0.007, 0.012])       # a pad-body point off every axis (m)


@pytest.fixture(scope="module", params=[0, 1], ids=["robot1", "robot2"])
def crs(request):
    """(closed-form kinematics of paper robot i, Drake's of the same URDF at the same base)."""
    i = request.param
    arm = Arm(paper_robots()[i])
    X_WB = RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base)
    drake = DrakeArmKinematics(URDF / f"{CRS_MODELS[i]}_3dof.urdf", X_WB, name=arm.name)
    return arm.kinematics, drake


def _postures(closed):
    rng = np.random.default_rng(7)
    low, high = closed.q_min, closed.q_max
    return rng.uniform(0.7 * low + 0.3 * high, 0.3 * low + 0.7 * high, size=(6, 3))


def test_pad_control_follows_what_the_task_holds(crs):
    closed, drake = crs
    assert pad_control(closed) == "contact"          # the paper's 3-joint arms: closed form
    assert pad_control(drake) == "contact"           # any 3-joint arm, Drake's kinematics
    six = DrakeArmKinematics(URDF / "coop6_6dof.urdf", RigidTransform(), name="r")
    assert pad_control(six) == "centre"              # 6 joints, a position-only task
    held = DrakeArmKinematics(URDF / "coop6_6dof.urdf", RigidTransform(),
                              R_d=RotationMatrix.MakeYRotation(math.pi / 2), name="r")
    assert pad_control(held) == "pose"               # 6 joints holding the orientation


def test_a_drake_pad_point_is_the_closed_form_offset_point(crs):
    closed, drake = crs
    point = point_kinematics(drake, OFFSET)
    assert isinstance(point, DrakePadPoint)
    reference = closed.with_offset(OFFSET)
    q = _postures(closed)
    v = np.random.default_rng(8).normal(size=q.shape)
    np.testing.assert_allclose(point.fk(q), reference.fk(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(point.jacobian(q), reference.jacobian(q), rtol=0, atol=1e-12)
    np.testing.assert_allclose(point.jacobian_dot(q, v), reference.jacobian_dot(q, v),
                               rtol=0, atol=1e-11)
    np.testing.assert_allclose(point.angular_velocity(q, v), closed.angular_velocity(q, v),
                               rtol=0, atol=1e-12)
    for qk in q:
        np.testing.assert_allclose(point.pad_rotation(qk), closed.pad_rotation(qk),
                                   rtol=0, atol=1e-12)
    # The inverse kinematics of the point: back to the closed form's posture (same branch).
    np.testing.assert_allclose(point.fk(point.ik(reference.fk(q[:2]))), reference.fk(q[:2]),
                               rtol=0, atol=1e-12)
    # The centre (no offset) is the arm's own end effector.
    np.testing.assert_allclose(point_kinematics(drake).fk(q), closed.fk(q), rtol=0, atol=1e-12)
    assert point_kinematics(closed, OFFSET).offset is not None


def test_a_bad_offset_is_refused_naming_it(crs):
    _, drake = crs
    with pytest.raises(ValueError, match="^offset: 3 finite numbers"):
        DrakePadPoint(drake, [0.0, np.nan, 0.0])
    six = DrakeArmKinematics(URDF / "coop6_6dof.urdf", RigidTransform(), name="six")
    with pytest.raises(ValueError, match="^six: the material point's inverse kinematics"):
        DrakePadPoint(six, OFFSET).ik(np.array([0.5, 0.0, 0.5]))
