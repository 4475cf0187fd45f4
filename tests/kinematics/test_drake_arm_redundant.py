"""The redundant arm's reference (R1) of drake_coop.kinematics.drake_arm: its velocity and
acceleration against finite differences of the integrated posture, the task against forward
kinematics, the null-space posture objective's effect and bound.

The arm is the shipped 6-joint ``coop6`` with a position-only task (n = 6 > task_dim = 3: three
redundant directions), so these tests need no description package.
"""

import numpy as np
import pytest
from pydrake.math import RigidTransform

from drake_coop.kinematics.drake_arm import DrakeArmKinematics
from drake_coop.scenario.resources import urdf_dir

CENTER = np.array([0.45, 0.05, 0.55])
RADIUS = 0.06
OMEGA = 2 * np.pi / 2.0          # one lap in 2 s


def circle(t):
    """A circle in the y-z plane, started from rest by a quintic ramp of the angle over 0.5 s
    (then constant speed): x, ẋ, ẍ at the times t."""
    t = np.atleast_1d(np.asarray(t, dtype=float))
    T = 0.5
    s = np.clip(t / T, 0.0, 1.0)
    # θ(t): θ̇ ramps from 0 to OMEGA with a quintic smoothstep, θ its integral.
    ramp = 10 * s**3 - 15 * s**4 + 6 * s**5
    ramp_d = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    ramp_i = T * (2.5 * s**4 - 3 * s**5 + s**6)          # ∫ ramp dt over [0, min(t, T)]
    theta = OMEGA * np.where(t < T, ramp_i, ramp_i + (t - T))
    theta_d = OMEGA * np.where(t < T, ramp, 1.0)
    theta_dd = OMEGA * np.where(t < T, ramp_d, 0.0)
    c, sn = np.cos(theta), np.sin(theta)
    x = CENTER + RADIUS * np.column_stack([0 * t, sn, c - 1])
    xd = RADIUS * np.column_stack([0 * t, c * theta_d, -sn * theta_d])
    xdd = RADIUS * np.column_stack([0 * t, -sn * theta_d**2 + c * theta_dd,
                                    -c * theta_d**2 - sn * theta_dd])
    return x, xd, xdd


@pytest.fixture(scope="module")
def kin():
    k = DrakeArmKinematics(urdf_dir() / "coop6_6dof.urdf", RigidTransform(), name="r")
    assert k.redundant and k.n == 6 and k.task_dim == 3
    return k


Q_NOM = np.array([0.1, 0.5, 1.2, 0.2, -0.4, 0.3])


def test_velocity_and_acceleration_are_the_derivatives_of_the_integrated_posture(kin):
    dt = 1e-3
    t = np.arange(0.0, 1.2 + dt / 2, dt)
    q, qd, qdd = kin.redundant_reference(t, circle, Q_NOM, nullspace_gain=2.0)
    fd_q = (q[2:] - q[:-2]) / (2 * dt)
    fd_qd = (qd[2:] - qd[:-2]) / (2 * dt)
    scale_v, scale_a = np.abs(qd).max(), np.abs(qdd).max()
    assert scale_v > 0.1 and scale_a > 0.1                    # the arm does move
    # Central differences over 1 ms are exact to O(δ²) (~1e-4 of the scale here); a missing
    # term of q̈_d (J̇⁺, or the task feedback's ė) is an error of the order of the scale.
    np.testing.assert_allclose(fd_q, qd[1:-1], rtol=0, atol=1e-4 * scale_v)
    np.testing.assert_allclose(fd_qd, qdd[1:-1], rtol=0, atol=1e-4 * scale_a)


def test_the_end_effector_follows_the_task_and_starts_at_rest(kin):
    t = np.arange(0.0, 2.5, 0.009)
    q, qd, _ = kin.redundant_reference(t, circle, Q_NOM, nullspace_gain=2.0)
    x, _, _ = circle(t)
    np.testing.assert_allclose(kin.fk(q), x, rtol=0, atol=1e-9)
    # The start posture is the nearest to q_nom with E at x(0): no null-space velocity there.
    assert np.abs(qd[0]).max() < 1e-9


def _lap_ends(kin, gain, laps=6):
    h = 0.01          # the lap ends 0.25 + 2k s fall on the grid
    t = np.arange(0.0, 0.5 + 2.0 * laps + h / 2, h)
    q, _, _ = kin.redundant_reference(t, circle, Q_NOM, nullspace_gain=gain)
    # After the ramp (θ = OMEGA (t − 0.25) from t = 0.5 s), a lap ends every 2 s at θ = 2πk.
    ends = [int(round((0.25 + 2.0 * k) / h)) for k in range(1, laps + 1)]
    return q, q[ends]


def test_the_null_space_objective_removes_the_pseudo_inverse_drift(kin):
    """Without the objective (K_n = 0, the pseudo-inverse alone) the posture at the same point
    of the circle drifts from lap to lap; with it, the laps repeat and stay near q_nom."""
    _, free = _lap_ends(kin, 0.0)
    _, held = _lap_ends(kin, 2.0)
    drift_free = np.linalg.norm(np.diff(free, axis=0), axis=1)
    drift_held = np.linalg.norm(np.diff(held, axis=0), axis=1)
    assert drift_free.min() > 1e-3                       # the drift is there without it
    assert drift_held[-1] < 1e-3 * drift_free[-1]        # and gone with it
    assert (np.linalg.norm(held - Q_NOM, axis=1) < np.linalg.norm(free - Q_NOM, axis=1)[-1]).all()


def test_the_null_space_motion_is_bounded(kin):
    q, _ = _lap_ends(kin, 2.0)
    distance = np.linalg.norm(q - Q_NOM, axis=1)
    first, rest = distance[: len(distance) // 3], distance[len(distance) // 3:]
    # After the first two laps the posture's distance to q_nom never exceeds what it reached
    # then (to 1e-6 rad: the laps repeat up to the decay of the start's transient).
    assert rest.max() <= first.max() + 1e-6


def test_the_posture_error_never_grows_while_the_task_holds(kin):
    """With ẋ_d = 0, V = ½|q_nom − q_d|² is non-increasing (V̇ = −K_n (q_nom − q)ᵀ(I − J⁺J)
    (q_nom − q) ≤ 0) and falls to the nearest posture on the task."""
    t = np.arange(0.0, 1.5 + 1e-9, 0.01)
    q_move, _, _ = kin.redundant_reference(t, circle, Q_NOM, nullspace_gain=0.0)
    x_hold = circle(1.5)[0][0]

    def hold(times):
        n = np.size(times)
        return np.tile(x_hold, (n, 1)), np.zeros((n, 3)), np.zeros((n, 3))

    q_nom = q_move[-1] + np.array([0.2, -0.1, 0.1, 0.3, -0.2, 0.2])
    t_hold = np.arange(0.0, 6.0, 0.01)
    q, _, _ = kin.redundant_reference(t_hold, hold, q_nom, nullspace_gain=1.5,
                                      q_start=q_move[-1])
    V = 0.5 * np.sum((q_nom - q) ** 2, axis=1)
    assert (np.diff(V) <= 1e-12).all()
    assert V[-1] < 0.5 * V[0]                                   # it does pull
    q_best = kin.start_posture(x_hold, q_nom)                   # the nearest posture on the task
    np.testing.assert_allclose(q[-1], q_best, atol=1e-3)
    np.testing.assert_allclose(kin.fk(q), np.tile(x_hold, (len(t_hold), 1)), atol=1e-9)


def test_a_reference_that_leaves_the_joint_limits_is_refused_naming_the_joint(kin):
    """The limits are checked along the whole integrated path: a nominal posture beyond
    joint 1's limit (3.054 rad) pulls the posture past it."""
    t = np.arange(0.0, 3.0, 0.05)
    q_nom = Q_NOM.copy()
    q_nom[0] = 4.0
    message = kin.check_redundant_path(t, circle, q_nom, nullspace_gain=3.0)
    assert message.startswith("r: joint joint1 at ") and "outside its limits" in message
    assert "choose q_nominal or nullspace_gain" in message
    assert kin.check_redundant_path(t, circle, Q_NOM, nullspace_gain=3.0) == ""
