"""Each robot's kinematics, chosen from its scenario entry, and the reachability check.

The paper's arms (``crs_a465``, ``crs_a255`` with their default frames and a position-only
reference) get their closed form (:class:`~drake_coop.kinematics.crs.CrsKinematics`); any other arm
gets Drake's (:class:`~drake_coop.kinematics.drake_arm.DrakeArmKinematics`: its URDF, frames,
orientation reference ``ee_rpy_deg`` and IK seed ``q_seed``). Both kinematics modules import
nothing of the scenario, so this module, the scenario's validation and the plant's
:class:`~drake_coop.plant.arms.Arm` share them without an import cycle.
"""

from __future__ import annotations

import math

import numpy as np

from drake_coop.scenario.resources import model_urdf_path
from drake_coop.scenario.schema import Robot, Scenario, ScenarioError
from drake_coop.scenario.task_path import cartesian_reference


def has_closed_form(robot: Robot) -> bool:
    """Whether the robot is one of the paper's arms, used as the paper uses it.

    Parameters
    ----------
    robot : Robot
        The robot.

    Returns
    -------
    bool
        True for the paper's arms at their base frame.
    """
    from drake_coop.kinematics.crs import GEOMETRY

    return (robot.model in GEOMETRY and robot.base_frame == "base_link"
            and robot.ee_frame == "pad" and robot.ee_rpy_deg is None
            and not robot.locked_joints and robot.tool is None)


def robot_kinematics(robot: Robot):
    """The kinematics of ``robot`` at its base pose (``n``, ``q_min``, ``q_max``, ``fk``,
    ``joint_reference``, ``check_path``): closed form or Drake's, see the module's docstring.

    Parameters
    ----------
    robot : Robot
        The robot.
    """
    p_base = np.asarray(robot.base_xyz, dtype=float)
    yaw = math.radians(robot.base_yaw_deg)
    urdf = model_urdf_path(robot)
    if has_closed_form(robot):
        from drake_coop.kinematics.crs import GEOMETRY, CrsKinematics, urdf_joint_limits

        return CrsKinematics(GEOMETRY[robot.model], p_base, yaw, *urdf_joint_limits(urdf),
                             name=robot.name)
    from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

    from drake_coop.kinematics.drake_arm import DrakeArmKinematics

    R_d = None
    if robot.ee_rpy_deg is not None:
        R_d = RollPitchYaw(np.radians(robot.ee_rpy_deg)).ToRotationMatrix()
    q_seed = None if robot.q_seed is None else np.asarray(robot.q_seed, dtype=float)
    return DrakeArmKinematics(urdf, RigidTransform(RotationMatrix.MakeZRotation(yaw), p_base),
                              base_frame=robot.base_frame, ee_frame=robot.ee_frame, R_d=R_d,
                              q_seed=q_seed, name=robot.name)


def _fields_to_check(i: int) -> str:
    return (f"check robots[{i}].model, home, base_xyz, base_yaw_deg, contact_xy, q_nominal and "
            "task.circle_top_z, circle_radius, lift_height, pregrasp_distance")


def check_reachable(scenario: Scenario) -> None:
    """Raise :class:`ScenarioError` if a target of the task is out of an arm's reach.

    Every Cartesian target (sampled every 0.05 s) must be reachable with the joints within
    their limits, away from singular postures (Assumption 1), see the kinematics'
    ``check_path``; a redundant arm's reference (integrated on that grid) must stay within
    the limits, ``check_redundant_path``.

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    """
    task = scenario.task
    t = np.arange(0.0, task.t_end + 1e-9, 0.05)
    for i, robot in enumerate(scenario.robots):
        kin = robot_kinematics(robot)
        if getattr(kin, "redundant", False):
            problem = kin.check_redundant_path(
                t, lambda tt, r=robot: cartesian_reference(task, r, tt), robot.q_nominal,
                robot.nullspace_gain)
        else:
            x, _, _ = cartesian_reference(task, robot, t)
            problem = kin.check_path(x, t)
        if problem:
            problem = problem.removeprefix(f"{robot.name}: ")
            raise ScenarioError(f"robots[{i}] ({robot.name}): {problem}; {_fields_to_check(i)}")
