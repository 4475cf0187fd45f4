"""``object_model.control_point``: the pads' material contact points as what the references
follow across the normal: the point on the pad's surface, its references checked
against the kinematics of the point and the pad's centre (Drake's and the closed form), the
object's desired path unchanged, the rolling correction against its integral, and which
scenarios use it."""

from __future__ import annotations

import numpy as np
import pytest

from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.references import (
    contact_point_reference,
    followed_point,
    rolling_correction,
    start_posture,
)
from drake_coop.scenario.task_path import cartesian_reference
from drake_coop.scenario import load_scenario
from drake_coop.scenario.resources import find_scenario

CONTACT = "plant: {object_mode: contact, object_mass: 0.5, friction: 1.0, time_step: 0.003}\n"


@pytest.fixture(scope="module")
def estimated():
    s = load_scenario(data=CONTACT + "object_model: {mode: estimated}\n")
    return s, plan_run(s)


def controls_contact_point(scenario) -> bool:
    return plan_run(scenario).controls_contact_point


def test_the_default_is_the_contact_point_only_with_an_object_model_held_by_friction():
    assert controls_contact_point(load_scenario(data=CONTACT + "object_model: {mode: known}\n"))
    assert not controls_contact_point(load_scenario(data=CONTACT))          # the paper's
    assert not controls_contact_point(load_scenario(data=CONTACT + "object_model: "
                                                    "{mode: known, control_point: centre}\n"))
    rigid = load_scenario(find_scenario("rigid"))
    rigid.object_model.mode = "estimated"
    assert not controls_contact_point(rigid)         # the ball constraint holds the centre


def test_the_point_is_on_the_pads_surface_facing_the_box_at_the_grasp(estimated):
    s, plan = estimated
    shifts = []
    for i, arm in enumerate(plan.arms):
        p = plan.robots[i].control_point
        kin = arm.kinematics
        q_g = kin.ik(arm.c)
        # At the grasp the point is the pad's centre plus its radius along the inward normal.
        P = kin.with_offset(p.offset).fk(q_g)
        np.testing.assert_allclose(P, arm.c - 0.015 * arm.N[0], rtol=0, atol=1e-14)
        assert np.linalg.norm(p.offset) == pytest.approx(0.015, abs=1e-15)
        shifts.append(p.shift)
    # Opposite shifts: the midpoint of the points' paths is the midpoint of the centres'
    # (the box's desired path, object_position_error's reference).
    np.testing.assert_allclose(shifts[0] + shifts[1], 0.0, atol=1e-15)


def test_references_put_the_contact_point_on_the_path_across_the_normal(estimated):
    s, plan = estimated
    for i, arm in enumerate(plan.arms):
        p = plan.robots[i].control_point
        t = np.linspace(14.0, 30.0, 40)
        x, xd, xdd = cartesian_reference(s.task, arm.robot, t)
        q, qd, qdd = contact_point_reference(arm.kinematics, p, x, xd, xdd)
        # Independent check through Drake's kinematics of the pad body (the arm's model).
        from drake_coop.plant.arms import arm_model
        from drake_coop.control.arm_model import ArmModel
        centre = arm_model(arm, closed_form=False)
        point = ArmModel(centre.plant, arm.ee_frame, arm.N, arm.c, point_offset=p.offset)
        n = arm.N[0]
        T = np.eye(3) - np.outer(n, n)
        for k in range(0, len(t), 7):
            y = T @ point.ee_position(q[k]) + np.outer(n, n) @ centre.ee_position(q[k])
            np.testing.assert_allclose(y, x[k], rtol=0, atol=1e-12)
            Jy = T @ point.J_x(q[k]) + np.outer(n, n) @ centre.J_x(q[k])
            np.testing.assert_allclose(Jy @ qd[k], xd[k], rtol=0, atol=1e-12)
        # q̈_d: the central difference of q̇_d along the path.
        e = 1e-5
        xp, xdp, xddp = cartesian_reference(s.task, arm.robot, t + e)
        xm, xdm, xddm = cartesian_reference(s.task, arm.robot, t - e)
        qdp = contact_point_reference(arm.kinematics, p, xp, xdp, xddp)[1]
        qdm = contact_point_reference(arm.kinematics, p, xm, xdm, xddm)[1]
        np.testing.assert_allclose(qdd, (qdp - qdm) / (2 * e), rtol=0, atol=1e-6)
        # The centre leaves its own path when the pad turns (what the remedy is for).
        assert np.abs(arm.kinematics.fk(q) - x).max() > 1e-3
        np.testing.assert_allclose(followed_point(arm.kinematics, p, q), x, rtol=0, atol=1e-12)


def test_the_rolling_correction_is_the_integral_of_delta_omega_cross_n(estimated):
    s, plan = estimated
    arm = plan.arms[0]
    p = plan.robots[0].control_point
    h = 0.009
    t = 15.0 + h * np.arange(800)
    x, xd, xdd = cartesian_reference(s.task, arm.robot, t)
    q, qd, _ = contact_point_reference(arm.kinematics, p, x, xd, xdd)
    delta = 1e-3 * (1 + np.sin(t))
    c, cd, cdd = rolling_correction(arm.kinematics, p, q, qd, delta, h)
    # Against the pad's turn by finite differences of its orientation (not its ω):
    # δ ω × n, with ω from R(t + h) R(t)ᵀ.
    R = np.array([arm.kinematics.pad_rotation(qk) for qk in q])
    n = -p.normal
    T = np.eye(3) - np.outer(n, n)
    total = np.zeros(3)
    for k in range(len(t) - 1):
        dR = R[k + 1] @ R[k].T
        dtheta = 0.5 * np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]])
        total += T @ (0.5 * (delta[k] + delta[k + 1]) * np.cross(dtheta, n))
    np.testing.assert_allclose(c[-1], total, rtol=1e-3, atol=1e-9)
    assert np.abs(c[-1]).max() > 1e-5           # the pad turns: a correction that matters


def test_the_rest_posture_is_the_references_first_sample(estimated):
    s, plan = estimated
    for i, arm in enumerate(plan.arms):
        t, r = plan_run(s, 0.05).robots[i].samples
        q0 = start_posture(arm, s.task, plan.robots[i].control_point)
        assert (r[0, :3] == q0).all()


def test_the_contact_point_reference_through_drakes_kinematics_is_the_closed_forms(estimated):
    """The same references on the paper's arm's URDF through Drake's kinematics (any 3-joint
    arm: ``DrakePadPoint``) as through the closed form, to the Newton tolerance."""
    from pydrake.math import RigidTransform, RotationMatrix

    from drake_coop.kinematics.drake_arm import DrakeArmKinematics
    from drake_coop.kinematics.pose_task import pad_control
    from drake_coop.scenario.resources import urdf_dir

    s, plan = estimated
    arm = plan.arms[0]
    p = plan.robots[0].control_point
    drake = DrakeArmKinematics(urdf_dir() / "crs_a465_3dof.urdf",
                               RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base),
                               name=arm.name)
    assert pad_control(drake) == "contact"
    t = np.linspace(15.0, 30.0, 12)
    x, xd, xdd = cartesian_reference(s.task, arm.robot, t)
    closed = contact_point_reference(arm.kinematics, p, x, xd, xdd)
    numeric = contact_point_reference(drake, p, x, xd, xdd)
    for a, b, tol in zip(closed, numeric, (1e-10, 1e-9, 1e-8)):
        np.testing.assert_allclose(b, a, rtol=0, atol=tol)
    np.testing.assert_allclose(followed_point(drake, p, numeric[0]), x, rtol=0, atol=1e-12)
    c_closed = rolling_correction(arm.kinematics, p, closed[0], closed[1], 1e-3 + 0 * t, 0.1)
    c_drake = rolling_correction(drake, p, numeric[0], numeric[1], 1e-3 + 0 * t, 0.1)
    np.testing.assert_allclose(c_drake[0], c_closed[0], rtol=0, atol=1e-12)
