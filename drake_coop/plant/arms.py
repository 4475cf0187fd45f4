"""The two arms: geometry, base pose, constraint plane and closed-form kinematics.

Both arms are reduced to waist yaw (joint 1, about z), shoulder pitch (joint 2, about y) and
elbow pitch (joint 3, about y), with the wrist locked straight and lumped into the last link.
At ``q = 0`` the arm points straight up; a positive ``q2`` leans the upper arm forward (towards
the base's +x), a positive ``q3`` bends the forearm further forward ("elbow up" postures).

The end-effector point E is the centre of the spherical contact pad, at distance ``L3`` from
the elbow along the forearm: forearm + wrist-to-flange + force sensor + pad radius.

Closed-form forward kinematics, Jacobian, its time derivative and inverse kinematics live here
(NumPy, vectorised); tests check them against the MultibodyPlant built from the URDF files.

The constraint of the paper (Section IV) is ``phi_i(q) = s_i (x_i(q) - b_i)`` with ``s_i`` the x
component of the object's outward normal at contact i (``s_1 = -1``, ``s_2 = +1``). Then the
generalized force ``J_phi^T λ`` is the Cartesian force ``λ s_i e_x`` on the end effector: a
positive λ is the object pushing the end effector outwards, i.e. a squeeze.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from drake_coop.scenario.schema import Robot


def urdf_dir() -> Path:
    """Folder of the robot models: ``$DRAKE_COOP_URDF_DIR``, else the shipped ``urdf/``
    (installed package data or the checkout's folder, see :mod:`drake_coop.scenario.resources`)."""
    from drake_coop.scenario.resources import urdf_dir as _urdf_dir

    return _urdf_dir()


@dataclass(frozen=True)
class ArmGeometry:
    """Kinematic lengths of a 3-joint arm (m) and its joint limits (rad).

    Attributes
    ----------
    h1 : float
        Base plate to shoulder axis.
    L2 : float
        Shoulder to elbow (upper arm).
    L_forearm : float
        Elbow to wrist.
    L_flange : float
        Wrist to tool flange (wrist locked straight).
    L_sensor : float
        Force-sensor body length (flange to pad base).
    r_pad : float
        Radius of the spherical contact pad.
    q_min, q_max : tuple[float, float, float]
        Joint limits.
    """

    h1: float
    L2: float
    L_forearm: float
    L_flange: float
    L_sensor: float
    r_pad: float
    q_min: tuple[float, float, float]
    q_max: tuple[float, float, float]

    @property
    def L3(self) -> float:
        """Elbow to end-effector point (pad centre)."""
        return self.L_forearm + self.L_flange + self.L_sensor + self.r_pad


_DEG = math.pi / 180.0

#: Published lengths (CRS manuals) plus our sensor and pad.
GEOMETRY: dict[str, ArmGeometry] = {
    "crs_a465": ArmGeometry(
        h1=0.3302, L2=0.3048, L_forearm=0.3302, L_flange=0.0762, L_sensor=0.03, r_pad=0.015,
        q_min=(-175 * _DEG, -90 * _DEG, -110 * _DEG), q_max=(175 * _DEG, 90 * _DEG, 110 * _DEG)),
    "crs_a255": ArmGeometry(
        h1=0.254, L2=0.254, L_forearm=0.254, L_flange=0.051, L_sensor=0.03, r_pad=0.015,
        q_min=(-175 * _DEG, -90 * _DEG, -110 * _DEG), q_max=(175 * _DEG, 90 * _DEG, 110 * _DEG)),
}


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class Arm:
    """One robot in the palm frame: geometry, base pose and constraint.

    Parameters
    ----------
    robot : Robot
        The scenario's description of the robot.
    """

    def __init__(self, robot: Robot):
        self.robot = robot
        self.name = robot.name
        self.geometry = GEOMETRY[robot.model]
        self.p_base = np.asarray(robot.base_xyz, dtype=float)
        self.yaw = math.radians(robot.base_yaw_deg)
        self.R_base = _rot_z(self.yaw)
        self.b = float(robot.plane_b)
        self.s = float(robot.normal_sign)
        #: Outward normal of the object at this contact (palm frame).
        self.normal = np.array([self.s, 0.0, 0.0])

    @property
    def urdf_path(self) -> Path:
        """The simulated arm's URDF."""
        return urdf_dir() / f"{self.robot.model}_3dof.urdf"

    @property
    def controller_urdf_path(self) -> Path:
        """The controller's own model of the arm (defaults to the simulated one)."""
        if not self.robot.controller_model:
            return self.urdf_path
        p = Path(self.robot.controller_model)
        return p if p.is_absolute() else urdf_dir() / p

    # ------------------------------------------------------------------ forward kinematics
    def fk(self, q: np.ndarray) -> np.ndarray:
        """End-effector point E in the palm frame, for q of shape (..., 3)."""
        g = self.geometry
        q = np.asarray(q, dtype=float)
        q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
        r = g.L2 * np.sin(q2) + g.L3 * np.sin(q2 + q3)
        z = g.h1 + g.L2 * np.cos(q2) + g.L3 * np.cos(q2 + q3)
        local = np.stack([r * np.cos(q1), r * np.sin(q1), z], axis=-1)
        return local @ self.R_base.T + self.p_base

    def _terms(self, q: np.ndarray):
        """sin q1, cos q1 and the planar terms r = L2 s2 + L3 s23, a = ∂r/∂q2, b = ∂r/∂q3,
        e = L3 s23 shared by the Jacobian and its derivative."""
        g = self.geometry
        q = np.asarray(q, dtype=float)
        q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
        b = g.L3 * np.cos(q2 + q3)
        e = g.L3 * np.sin(q2 + q3)
        r = g.L2 * np.sin(q2) + e
        a = g.L2 * np.cos(q2) + b
        return np.sin(q1), np.cos(q1), r, a, b, e

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Translational Jacobian ∂E/∂q in the palm frame, shape (..., 3, 3)."""
        s1, c1, r, a, b, e = self._terms(q)
        zero = np.zeros_like(s1)
        J = np.stack([
            np.stack([-r * s1, a * c1, b * c1], axis=-1),
            np.stack([r * c1, a * s1, b * s1], axis=-1),
            np.stack([zero, -r, -e], axis=-1),
        ], axis=-2)
        return self.R_base @ J

    def jacobian_dot(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Time derivative of :meth:`jacobian` along joint velocity v, shape (..., 3, 3)."""
        s1, c1, r, a, b, e = self._terms(q)
        v = np.asarray(v, dtype=float)
        v1, v2, v3 = v[..., 0], v[..., 1], v[..., 2]
        q2 = np.asarray(q, dtype=float)[..., 1]
        rd = a * v2 + b * v3
        ad = -self.geometry.L2 * np.sin(q2) * v2 - e * (v2 + v3)
        bd = -e * (v2 + v3)
        ed = b * (v2 + v3)
        zero = np.zeros_like(s1)
        Jd = np.stack([
            np.stack([-rd * s1 - r * c1 * v1, ad * c1 - a * s1 * v1, bd * c1 - b * s1 * v1],
                     axis=-1),
            np.stack([rd * c1 - r * s1 * v1, ad * s1 + a * c1 * v1, bd * s1 + b * c1 * v1],
                     axis=-1),
            np.stack([zero, -rd, -ed], axis=-1),
        ], axis=-2)
        return self.R_base @ Jd

    # ------------------------------------------------------------------ inverse kinematics
    def local_point(self, p: np.ndarray) -> np.ndarray:
        """A palm-frame point expressed in the base frame."""
        return (np.asarray(p, dtype=float) - self.p_base) @ self.R_base

    def reach_ratio(self, p: np.ndarray) -> np.ndarray:
        """Shoulder-to-point distance over the arm's full reach ``L2 + L3``."""
        g = self.geometry
        lp = self.local_point(p)
        d = np.hypot(np.hypot(lp[..., 0], lp[..., 1]), lp[..., 2] - g.h1)
        return d / (g.L2 + g.L3)

    def ik(self, p: np.ndarray) -> np.ndarray:
        """Closed-form inverse kinematics, the branch of the paper's postures.

        The branch: the arm faces the point (``q1 = atan2(y, x)`` in the base frame) with the
        elbow up (``q3 > 0``). Raises ``ValueError`` for a point out of reach.

        Parameters
        ----------
        p : ndarray, shape (..., 3)
            End-effector points in the palm frame.

        Returns
        -------
        ndarray, shape (..., 3)
            Joint positions.
        """
        g = self.geometry
        lp = self.local_point(p)
        x, y, z = lp[..., 0], lp[..., 1], lp[..., 2]
        q1 = np.arctan2(y, x)
        r = np.hypot(x, y)
        dz = z - g.h1
        c3 = (r * r + dz * dz - g.L2 ** 2 - g.L3 ** 2) / (2 * g.L2 * g.L3)
        if np.any(np.abs(c3) > 1.0):
            raise ValueError(f"{self.name}: point out of reach of the arm")
        q3 = np.arccos(c3)
        q2 = np.arctan2(r, dz) - np.arctan2(g.L3 * np.sin(q3), g.L2 + g.L3 * np.cos(q3))
        return np.stack([q1, q2, q3], axis=-1)

    # ------------------------------------------------------------------ constraint (2)
    def phi(self, q: np.ndarray) -> np.ndarray:
        """Constraint (2) of Section IV: ``phi = s (x(q) - b)`` (m)."""
        return self.s * (self.fk(q)[..., 0] - self.b)

    def J_phi(self, q: np.ndarray) -> np.ndarray:
        """Constraint row ``J_phi = ∂phi/∂q``, shape (..., 1, 3)."""
        return self.s * self.jacobian(q)[..., 0:1, :]
