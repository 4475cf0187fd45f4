r"""Closed-form kinematics of the paper's two arms (CRS A465 and A255, 3 joints).

Both arms are reduced to waist yaw (joint 1, about z), shoulder pitch (joint 2, about y) and
elbow pitch (joint 3, about y), with the wrist locked straight and lumped into the last link.
At ``q = 0`` the arm points straight up; a positive ``q2`` leans the upper arm forward (towards
the base's +x), a positive ``q3`` bends the forearm further forward ("elbow up" postures). The
end-effector point E is the centre of the spherical contact pad, at distance ``L3`` from the
elbow along the forearm: forearm + wrist-to-flange + force sensor + pad radius.

:class:`CrsKinematics` holds the forward kinematics, Jacobian, its time derivative and inverse
kinematics (NumPy, vectorised; tests check them against the MultibodyPlant built from the URDF
files), behind the same interface as :class:`~drake_coop.kinematics.drake_arm.DrakeArmKinematics`
(``n``, ``q_min``, ``q_max``, ``fk``, ``joint_reference``, ``check_path``). Like that module,
it imports nothing of the scenario, so the scenario's checks can use both.

The controlled point may be any point fixed in the pad body instead of its centre E
(``offset`` ``o``, in the pad frame, which is link 3's frame: ``R = R_z(q1) R_y(q2 + q3)``
in the base frame, the wrist locked straight). With ``o = (o_x, o_y, o_z)`` the point is
``P = E + R o``; in the base frame, with ``θ = q2 + q3``, ``A = L3 + o_z``,

.. math::
    e = A \sin\theta + o_x \cos\theta, \quad b = A \cos\theta - o_x \sin\theta,
    \quad r = L_2 \sin q_2 + e,

    P_{local} = (r \cos q_1 - o_y \sin q_1,\ r \sin q_1 + o_y \cos q_1,\
                 h_1 + L_2 \cos q_2 + b)

(``∂e/∂θ = b``, ``∂b/∂θ = −e``, as with ``o = 0``), and the inverse kinematics is the
centre's with the forearm ``L' = √(A² + o_x²)`` turned by ``γ = atan2(o_x, A)`` and the waist
turned by ``atan2(o_y, r)``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class ArmGeometry:
    """Kinematic lengths of a 3-joint arm (m) (its joint limits are the URDF's).

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
    """

    h1: float
    L2: float
    L_forearm: float
    L_flange: float
    L_sensor: float
    r_pad: float

    @property
    def L3(self) -> float:
        """Elbow to end-effector point (pad centre)."""
        return self.L_forearm + self.L_flange + self.L_sensor + self.r_pad


#: Published lengths (CRS manuals) plus our sensor and pad.
GEOMETRY: dict[str, ArmGeometry] = {
    "crs_a465": ArmGeometry(
        h1=0.3302, L2=0.3048, L_forearm=0.3302, L_flange=0.0762, L_sensor=0.03, r_pad=0.015),
    "crs_a255": ArmGeometry(
        h1=0.254, L2=0.254, L_forearm=0.254, L_flange=0.051, L_sensor=0.03, r_pad=0.015),
}


def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def urdf_joint_limits(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper limits of the URDF's one-degree-of-freedom joints, in file order (the
    order of Drake's joint positions); a continuous joint or a missing bound is unlimited.

    Parameters
    ----------
    path : Path
        The URDF file.

    Returns
    -------
    lower, upper : numpy.ndarray
        The limits, one per revolute (rad), continuous (±inf) or prismatic (m) joint.
    """
    lo, hi = [], []
    for joint in ET.parse(path).getroot().findall("joint"):
        if joint.get("type") not in ("revolute", "continuous", "prismatic"):
            continue
        limit = joint.find("limit")
        free = joint.get("type") == "continuous" or limit is None
        lo.append(-math.inf if free or limit.get("lower") is None else float(limit.get("lower")))
        hi.append(math.inf if free or limit.get("upper") is None else float(limit.get("upper")))
    return np.array(lo), np.array(hi)


class CrsKinematics:
    """Closed-form kinematics of one of the paper's arms at its base pose.

    Parameters
    ----------
    geometry : ArmGeometry
        The arm's lengths (:data:`GEOMETRY`).
    p_base : ndarray, shape (3,)
        Base position in the palm frame (m).
    yaw : float
        Base rotation about the palm z axis (rad).
    q_min, q_max : ndarray, shape (3,)
        Joint limits (rad), from the URDF (:func:`urdf_joint_limits`).
    name : str
        The robot's name, for messages.
    offset : array_like, shape (3,), optional
        The controlled point's offset from the pad's centre E, fixed in the pad body (its
        frame, m): the kinematics are those of ``P = E + R_pad(q) o`` (module docstring).
        Default: E itself.
    """

    def __init__(self, geometry: ArmGeometry, p_base: np.ndarray, yaw: float,
                 q_min: np.ndarray, q_max: np.ndarray, name: str = "robot", offset=None):
        o = np.zeros(3) if offset is None else np.asarray(offset, dtype=float)
        if o.shape != (3,) or not np.all(np.isfinite(o)):
            raise ValueError(f"offset: 3 finite numbers are required (m, pad frame), got "
                             f"{np.shape(offset)}")
        self.offset = o
        self._ox, self._oy = float(o[0]), float(o[1])
        self._A = geometry.L3 + float(o[2])          # the forearm to P, along it
        #: The forearm from the elbow to P: its length ``L'`` and angle ``γ`` off the forearm.
        self._L3p = math.hypot(self._A, self._ox)
        self._gamma = math.atan2(self._ox, self._A)
        self.geometry = geometry
        self.p_base = np.asarray(p_base, dtype=float)
        self.yaw = float(yaw)
        self.R_base = _rot_z(self.yaw)
        self.q_min = np.asarray(q_min, dtype=float)
        self.q_max = np.asarray(q_max, dtype=float)
        self.name = name
        self.n = 3

    def with_offset(self, offset) -> "CrsKinematics":
        """The same arm controlling the pad-body point ``offset`` (pad frame, m).

        Parameters
        ----------
        offset : array_like
            The controlled point in the pad body's frame (3,), m.

        Returns
        -------
        CrsKinematics
            A new kinematics with the same geometry, base pose, limits and name.
        """
        return CrsKinematics(self.geometry, self.p_base, self.yaw, self.q_min, self.q_max,
                             self.name, offset)

    def angular_velocity(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The pad's angular velocity in the palm frame, ``R_base (q̇1 e_z + (q̇2 + q̇3)
        R_z(q1) e_y)``.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (..., 3), rad.
        v : numpy.ndarray
            Joint velocities (..., 3), rad/s.

        Returns
        -------
        numpy.ndarray
            The angular velocity (..., 3), rad/s, palm frame.
        """
        q = np.asarray(q, dtype=float)
        v = np.asarray(v, dtype=float)
        w23 = v[..., 1] + v[..., 2]
        local = np.stack([-np.sin(q[..., 0]) * w23, np.cos(q[..., 0]) * w23, v[..., 0]],
                         axis=-1)
        return local @ self.R_base.T

    def pad_rotation(self, q: np.ndarray) -> np.ndarray:
        """The pad frame's orientation in the palm frame, ``R_base R_z(q1) R_y(q2 + q3)``.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (3,) of one sample, rad.

        Returns
        -------
        numpy.ndarray
            The rotation matrix (3, 3).
        """
        q1, q2, q3 = np.asarray(q, dtype=float).tolist()
        c1, s1 = math.cos(q1), math.sin(q1)
        ct, st = math.cos(q2 + q3), math.sin(q2 + q3)
        return self.R_base @ np.array([[c1 * ct, -s1, c1 * st], [s1 * ct, c1, s1 * st],
                                       [-st, 0.0, ct]])

    # ------------------------------------------------------------------ forward kinematics
    def fk(self, q: np.ndarray) -> np.ndarray:
        """End-effector point E in the palm frame.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (..., n), rad.

        Returns
        -------
        numpy.ndarray
            The point E (..., 3), m, palm frame.
        """
        g = self.geometry
        A, ox, oy = self._A, self._ox, self._oy
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:            # one sample: plain floats (NumPy's per-call cost dominates)
            q1, q2, q3 = q.tolist()
            s23, c23 = math.sin(q2 + q3), math.cos(q2 + q3)
            r = g.L2 * math.sin(q2) + A * s23 + ox * c23
            z = g.h1 + g.L2 * math.cos(q2) + A * c23 - ox * s23
            s1, c1 = math.sin(q1), math.cos(q1)
            return self.R_base @ np.array([r * c1 - oy * s1, r * s1 + oy * c1, z]) \
                + self.p_base
        q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
        s23, c23 = np.sin(q2 + q3), np.cos(q2 + q3)
        r = g.L2 * np.sin(q2) + A * s23 + ox * c23
        z = g.h1 + g.L2 * np.cos(q2) + A * c23 - ox * s23
        s1, c1 = np.sin(q1), np.cos(q1)
        local = np.stack([r * c1 - oy * s1, r * s1 + oy * c1, z], axis=-1)
        return local @ self.R_base.T + self.p_base

    def _terms(self, q: np.ndarray):
        """sin q1, cos q1 and the planar terms r = L2 s2 + e, a = ∂r/∂q2, b = ∂r/∂q3,
        e = A s23 + o_x c23 shared by the Jacobian and its derivative (``A = L3``, ``o = 0``
        for the centre)."""
        g = self.geometry
        A, ox = self._A, self._ox
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:            # one sample: plain floats
            q1, q2, q3 = q.tolist()
            s23, c23 = math.sin(q2 + q3), math.cos(q2 + q3)
            b, e = A * c23 - ox * s23, A * s23 + ox * c23
            return (math.sin(q1), math.cos(q1), g.L2 * math.sin(q2) + e,
                    g.L2 * math.cos(q2) + b, b, e)
        q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2]
        s23, c23 = np.sin(q2 + q3), np.cos(q2 + q3)
        b = A * c23 - ox * s23
        e = A * s23 + ox * c23
        r = g.L2 * np.sin(q2) + e
        a = g.L2 * np.cos(q2) + b
        return np.sin(q1), np.cos(q1), r, a, b, e

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Translational Jacobian ∂E/∂q in the palm frame.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (..., 3), rad.

        Returns
        -------
        numpy.ndarray
            The Jacobian (..., 3, 3), m/rad.
        """
        s1, c1, r, a, b, e = self._terms(q)
        oy = self._oy
        if np.ndim(q) == 1:
            return self.R_base @ np.array([[-r * s1 - oy * c1, a * c1, b * c1],
                                           [r * c1 - oy * s1, a * s1, b * s1],
                                           [0.0, -r, -e]])
        zero = np.zeros_like(s1)
        J = np.stack([
            np.stack([-r * s1 - oy * c1, a * c1, b * c1], axis=-1),
            np.stack([r * c1 - oy * s1, a * s1, b * s1], axis=-1),
            np.stack([zero, -r, -e], axis=-1),
        ], axis=-2)
        return self.R_base @ J

    def jacobian_dot(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Time derivative of :meth:`jacobian` along joint velocity v.

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (..., 3), rad.
        v : numpy.ndarray
            Joint velocities (..., 3), rad/s.

        Returns
        -------
        numpy.ndarray
            J̇ (..., 3, 3), m/(rad·s).
        """
        s1, c1, r, a, b, e = self._terms(q)
        oy = self._oy
        v = np.asarray(v, dtype=float)
        if np.ndim(q) == 1 and v.ndim == 1:
            v1, v2, v3 = v.tolist()
            rd = a * v2 + b * v3
            ad = -self.geometry.L2 * math.sin(float(q[1])) * v2 - e * (v2 + v3)
            bd = -e * (v2 + v3)
            ed = b * (v2 + v3)
            return self.R_base @ np.array([
                [-rd * s1 - r * c1 * v1 + oy * s1 * v1, ad * c1 - a * s1 * v1,
                 bd * c1 - b * s1 * v1],
                [rd * c1 - r * s1 * v1 - oy * c1 * v1, ad * s1 + a * c1 * v1,
                 bd * s1 + b * c1 * v1],
                [0.0, -rd, -ed]])
        v1, v2, v3 = v[..., 0], v[..., 1], v[..., 2]
        q2 = np.asarray(q, dtype=float)[..., 1]
        rd = a * v2 + b * v3
        ad = -self.geometry.L2 * np.sin(q2) * v2 - e * (v2 + v3)
        bd = -e * (v2 + v3)
        ed = b * (v2 + v3)
        zero = np.zeros_like(s1)
        Jd = np.stack([
            np.stack([-rd * s1 - r * c1 * v1 + oy * s1 * v1, ad * c1 - a * s1 * v1,
                      bd * c1 - b * s1 * v1], axis=-1),
            np.stack([rd * c1 - r * s1 * v1 - oy * c1 * v1, ad * s1 + a * c1 * v1,
                      bd * s1 + b * c1 * v1], axis=-1),
            np.stack([zero, -rd, -ed], axis=-1),
        ], axis=-2)
        return self.R_base @ Jd

    # ------------------------------------------------------------------ inverse kinematics
    def local_point(self, p: np.ndarray) -> np.ndarray:
        """A palm-frame point expressed in the base frame.

        Parameters
        ----------
        p : numpy.ndarray
            Points (..., 3) in the palm frame, m.

        Returns
        -------
        numpy.ndarray
            The same points (..., 3) in the arm's base frame, m.
        """
        return (np.asarray(p, dtype=float) - self.p_base) @ self.R_base

    def reach_ratio(self, p: np.ndarray) -> np.ndarray:
        """Shoulder-to-point distance over the arm's full reach ``L2 + L3``.

        Parameters
        ----------
        p : numpy.ndarray
            Points (..., 3) in the palm frame, m.

        Returns
        -------
        numpy.ndarray
            The ratio (...,), dimensionless: 1 at full stretch.
        """
        g = self.geometry
        lp = self.local_point(p)
        r = np.sqrt(np.maximum(lp[..., 0] ** 2 + lp[..., 1] ** 2 - self._oy ** 2, 0.0))
        d = np.hypot(r, lp[..., 2] - g.h1)
        return d / (g.L2 + self._L3p)

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
        L3 = self._L3p
        lp = self.local_point(p)
        x, y, z = lp[..., 0], lp[..., 1], lp[..., 2]
        rho2 = x * x + y * y
        if np.any(rho2 < self._oy ** 2):
            raise ValueError(f"{self.name}: point out of reach of the arm")
        if self._oy:
            r = np.sqrt(rho2 - self._oy ** 2)
            q1 = np.arctan2(y, x) - np.arctan2(self._oy, r)
        else:
            r, q1 = np.hypot(x, y), np.arctan2(y, x)
        dz = z - g.h1
        c3 = (r * r + dz * dz - g.L2 ** 2 - L3 ** 2) / (2 * g.L2 * L3)
        if np.any(np.abs(c3) > 1.0):
            raise ValueError(f"{self.name}: point out of reach of the arm")
        q3 = np.arccos(c3)
        q2 = np.arctan2(r, dz) - np.arctan2(L3 * np.sin(q3), g.L2 + L3 * np.cos(q3))
        return np.stack([q1, q2, q3 - self._gamma], axis=-1)

    def joint_reference(self, x: np.ndarray, xd: np.ndarray, xdd: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``q_d = IK(x_d)``, ``q̇_d = J⁻¹ ẋ_d``, ``q̈_d = J⁻¹ (ẍ_d − J̇ q̇_d)``.

        Parameters
        ----------
        x, xd, xdd : numpy.ndarray
            The Cartesian reference of E (..., 3) in the palm frame: position (m), velocity (m/s),
            acceleration (m/s²).

        Returns
        -------
        q_d, qdot_d, qddot_d : numpy.ndarray
            The joint reference (..., 3): rad, rad/s, rad/s².
        """
        q = self.ik(x)
        J = self.jacobian(q)
        qd = np.linalg.solve(J, xd[..., None])[..., 0]
        Jd = self.jacobian_dot(q, qd)
        qdd = np.linalg.solve(J, (xdd - (Jd @ qd[..., None])[..., 0])[..., None])[..., 0]
        return q, qd, qdd

    def check_path(self, x: np.ndarray, t: np.ndarray | None = None, margin: float = 0.97
                   ) -> str:
        """Why the Cartesian points ``x`` are not all reachable, or ``''``: within ``margin`` of the
        full reach, away from the inner singularity, joints within limits.

        Parameters
        ----------
        x : numpy.ndarray
            Points of E (K, 3) in the palm frame, m.
        t : numpy.ndarray or None
            Their times (K,), s, for the message; None numbers the samples.
        margin : float
            The largest allowed distance/reach ratio.

        Returns
        -------
        str
            ``''`` if every point is reachable, else one line naming the first point that is not.
        """
        g = self.geometry
        t = np.arange(len(x), dtype=float) if t is None else t
        ratio = self.reach_ratio(x)
        inner = abs(self._L3p - g.L2) / (g.L2 + self._L3p)
        worst = int(np.argmax(ratio))
        if ratio[worst] > margin or ratio.min() < inner + 0.05:
            bad = worst if ratio[worst] > margin else int(np.argmin(ratio))
            return (f"target {np.round(x[bad], 3).tolist()} at t = {t[bad]:.2f} s is out of reach "
                    f"(distance/reach = {ratio[bad]:.3f}, allowed {inner + 0.05:.3f} to "
                    f"{margin})")
        q = self.ik(x)
        out = (q < self.q_min) | (q > self.q_max)
        if out.any():
            row, j = np.argwhere(out)[0]
            return (f"target at t = {t[row]:.2f} s needs joint{j + 1} = "
                    f"{math.degrees(q[row, j]):.1f} deg, outside its limits "
                    f"[{math.degrees(self.q_min[j]):.0f}, {math.degrees(self.q_max[j]):.0f}] deg")
        return ""
