"""The arms in the palm frame: base pose, frames, constraints (2) and kinematics.

The constraints of robot ``i`` (``m_i`` rows) are ``φ_i(q) = N_i (x_i(q) − c_i)``: ``N_i``
the object's outward unit normals at the contact (rows), ``c_i`` the contact point at the
grasp. Then the generalized force ``J_φᵀ λ`` is the Cartesian force ``N_iᵀ λ`` on the end
effector: a positive λ is the object pushing the end effector outwards, i.e. a squeeze. The
paper's Section IV is ``m_i = 1``, ``N_i = (s_i, 0, 0)``: ``φ_i = s_i (x_i − b_i)`` with
``s_1 = −1``, ``s_2 = +1``.

The kinematics are the closed form of the paper's arms (:mod:`drake_coop.kinematics.crs`) or
Drake's for any other arm (:mod:`drake_coop.kinematics.drake_arm`), chosen by
:func:`drake_coop.scenario.reach.robot_kinematics`.
"""

from __future__ import annotations

import math
from functools import cached_property
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from drake_coop.control.arm_model import ArmModel
from drake_coop.control.arm_plant import make_arm_controller_plant
from drake_coop.kinematics.crs import (
    GEOMETRY,
    ArmGeometry,
    CrsKinematics,
    _rot_z,
    urdf_joint_limits,
)
from drake_coop.scenario.reach import has_closed_form, robot_kinematics
from drake_coop.scenario.resources import controller_urdf_path, model_urdf_path
from drake_coop.scenario.schema import Robot, Task

__all__ = ["GEOMETRY", "Arm", "ArmGeometry", "CrsKinematics", "arm_model",
           "shipped_arm_models", "urdf_dir", "urdf_joint_limits"]


def urdf_dir() -> Path:
    """The folder of the robot models: ``$DRAKE_COOP_URDF_DIR``, else the shipped ``urdf/``
    (installed package data or the checkout's folder, see :mod:`drake_coop.scenario.resources`).
    """
    from drake_coop.scenario.resources import urdf_dir as _urdf_dir

    return _urdf_dir()


class Arm:
    """One robot in the palm frame: base pose, constraints (2) and kinematics.

    Parameters
    ----------
    robot : Robot
        The scenario's description of the robot.
    task : Task, optional
        The task (the contact point's height ``circle_top_z − lift_height``); the paper's by
        default.

    Attributes
    ----------
    N : ndarray, shape (m, 3)
        The object's outward unit normals at the contact (rows): ``φ = N (x − c)``.
    c : ndarray, shape (3,)
        The contact point at the grasp.
    closed_form : bool
        Whether the closed-form kinematics apply (the paper's arms, default frames,
        position-only reference); otherwise :attr:`kinematics` is Drake's.
    """

    def __init__(self, robot: Robot, task: Task | None = None):
        task = task or Task()
        self.robot = robot
        self.name = robot.name
        self.geometry = GEOMETRY.get(robot.model)
        self.closed_form = has_closed_form(robot)
        self.p_base = np.asarray(robot.base_xyz, dtype=float)
        self.yaw = math.radians(robot.base_yaw_deg)
        N = np.atleast_2d(np.asarray(robot.normals, dtype=float))
        self.N = N / np.linalg.norm(N, axis=1, keepdims=True)
        self.m = self.N.shape[0]
        self.c = np.array([float(robot.contact_xy[0]), float(robot.contact_xy[1]),
                           task.circle_top_z - task.lift_height])
        #: Outward normal of the first constraint (the squeeze direction).
        self.normal = self.N[0]
        self.base_frame = robot.base_frame
        self.ee_frame = robot.ee_frame
        self.sensor_joint = robot.sensor_joint

    @property
    def b(self) -> float:
        """x of the contact point (the paper's ``b_i``)."""
        return float(self.c[0])

    @property
    def s(self) -> float:
        """x component of the first normal (the paper's ``s_i = ±1``)."""
        return float(self.N[0, 0])

    @cached_property
    def urdf_path(self) -> Path:
        """The simulated arm's URDF (resolved once)."""
        return model_urdf_path(self.robot)

    @cached_property
    def controller_urdf_path(self) -> Path:
        """The controller's own model of the arm (defaults to the simulated one; resolved
        once)."""
        if not self.robot.controller_model:
            return self.urdf_path
        return controller_urdf_path(self.robot)

    @cached_property
    def kinematics(self):
        """Forward kinematics, joint references and path checks:
        :class:`~drake_coop.kinematics.crs.CrsKinematics` for the paper's arms,
        :class:`~drake_coop.kinematics.drake_arm.DrakeArmKinematics` otherwise."""
        return robot_kinematics(self.robot)

    @property
    def R_base(self) -> np.ndarray:
        """Rotation of the base in the palm frame (about z by the yaw)."""
        return _rot_z(self.yaw)

    @property
    def q_min(self) -> np.ndarray:
        """Lower joint limits (rad), from the URDF (as the kinematics read them)."""
        return self.kinematics.q_min

    @property
    def q_max(self) -> np.ndarray:
        """Upper joint limits (rad), from the URDF (as the kinematics read them)."""
        return self.kinematics.q_max

    # ------------------------------------------------------------------ kinematics
    def fk(self, q: np.ndarray) -> np.ndarray:
        """End-effector point E in the palm frame, for q of shape (..., n).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (..., n), rad.

        Returns
        -------
        numpy.ndarray
            E (..., 3), m, palm frame.
        """
        return self.kinematics.fk(q)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Translational Jacobian ∂E/∂q (closed form of the paper's arms), shape (..., 3, 3).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (..., 3), rad.

        Returns
        -------
        numpy.ndarray
            ∂E/∂q (..., 3, 3), m/rad.
        """
        return self._crs.jacobian(q)

    def jacobian_dot(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Time derivative of :meth:`jacobian` along v (closed form), shape (..., 3, 3).

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
        return self._crs.jacobian_dot(q, v)

    def ik(self, p: np.ndarray) -> np.ndarray:
        """Closed-form inverse kinematics of the paper's arms (the elbow-up branch).

        Parameters
        ----------
        p : numpy.ndarray
            Points of E (..., 3), m, palm frame.

        Returns
        -------
        numpy.ndarray
            Joint positions (..., 3), rad.
        """
        return self._crs.ik(p)

    def reach_ratio(self, p: np.ndarray) -> np.ndarray:
        """Shoulder-to-point distance over the full reach (closed form).

        Parameters
        ----------
        p : numpy.ndarray
            Points (..., 3), m, palm frame.

        Returns
        -------
        numpy.ndarray
            The ratio (...,), 1 at full stretch.
        """
        return self._crs.reach_ratio(p)

    @property
    def _crs(self) -> CrsKinematics:
        if not self.closed_form:
            raise ValueError(f"{self.name}: no closed-form kinematics for model "
                             f"{self.robot.model!r}; use arm.kinematics")
        return self.kinematics

    # ------------------------------------------------------------------ constraint (2)
    def phi(self, q: np.ndarray) -> np.ndarray:
        """Constraint (2): ``φ = N (x(q) − c)`` (m), shape (..., m).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (..., n), rad.

        Returns
        -------
        numpy.ndarray
            ``φ`` (..., m), m.
        """
        return (self.fk(q) - self.c) @ self.N.T

    def J_phi(self, q: np.ndarray) -> np.ndarray:
        """Constraint Jacobian ``J_φ = N ∂x/∂q`` (closed form), shape (..., m, 3).

        Parameters
        ----------
        q : numpy.ndarray
            Joint positions (..., 3), rad.

        Returns
        -------
        numpy.ndarray
            ``J_φ`` (..., m, 3), m/rad.
        """
        return self.N @ self.jacobian(q)


def arm_model(arm: Arm, urdf: str | Path | None = None, closed_form: bool | None = None
              ) -> ArmModel:
    """The controller's model of a scenario's arm (:class:`~drake_coop.control.ArmModel`).

    Parameters
    ----------
    arm : Arm
        The robot (base pose, frames, constraint normals and contact point).
    urdf : str or Path, optional
        The model to use; defaults to ``arm.controller_urdf_path``.
    closed_form : bool, optional
        Use the closed-form kinematics of :mod:`drake_coop.kinematics.crs` for ``φ``, ``J_φ`` and
        ``J̇_φ``; default: when the arm has them and the controller's URDF is the simulated
        model (``controller_model`` unset; scaled masses and inertias keep the geometry).
    """
    path = Path(urdf) if urdf is not None else arm.controller_urdf_path
    X_WB = RigidTransform(RotationMatrix.MakeZRotation(arm.yaw), arm.p_base)
    plant = make_arm_controller_plant(path, arm.base_frame, X_WB)
    use = (arm.closed_form and not arm.robot.controller_model if closed_form is None
           else bool(closed_form))
    if use and not arm.closed_form:
        raise ValueError(f"closed_form: {arm.name} ({arm.robot.model!r}) has no closed-form "
                         "kinematics")
    return ArmModel(plant, arm.ee_frame, arm.N, arm.c,
                    closed_form=arm.kinematics if use else None)


def shipped_arm_models() -> dict[str, tuple[str, str, str | None]]:
    """Every robot model of the shipped scenarios, once, from the first scenario using it.

    The scenarios are read in :func:`~drake_coop.scenario.resources.shipped_scenarios`'
    order (by name); those that need the lab arms' descriptions are left out when the
    ``robots`` extra is not installed (any other refusal is raised).

    Returns
    -------
    dict[str, tuple[str, str, str or None]]
        ``robot.model -> (URDF path, base frame name, sensor joint name or None)``, in the
        order first met.
    """
    from drake_coop.scenario.description import ROBOTS_EXTRA
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.resources import shipped_scenarios
    from drake_coop.scenario.schema import ScenarioError

    seen: dict[str, tuple[str, str, str | None]] = {}
    for path in shipped_scenarios().values():
        try:
            scenario = load_scenario(path)
        except ScenarioError as error:      # a scenario that needs the robots extra, only
            if ROBOTS_EXTRA not in str(error):
                raise
            continue
        for robot in scenario.robots:
            if robot.model not in seen:
                arm = Arm(robot, scenario.task)
                seen[robot.model] = (str(arm.urdf_path), arm.base_frame, robot.sensor_joint)
    return seen
