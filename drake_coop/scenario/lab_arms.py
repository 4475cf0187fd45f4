"""The arms of ``example-robot-data`` a scenario can name, with the fields that make each one an
arm of this package (``drake-coop arms``, :doc:`/guide/lab_arms`).

Each entry of :data:`LAB_ARMS` gives the robot fields a scenario needs for that arm: its
``package://`` URL, the ``base_frame`` welded to the world, the ``locked_joints`` (a gripper's
fingers) and the ``tool.flange`` the wrist sensor and pad are mounted on. :func:`arm_facts`
prepares the URDF exactly as a run does (:func:`~drake_coop.scenario.resources.model_urdf_path`),
loads it into a ``MultibodyPlant`` with a ``SceneGraph`` attached, and reads from Drake what the
rest of the package uses: the joints, their effort limits (the actuators' limits) and position
limits, and from the URDF what Drake ignores (``mechanicalReduction``).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

from drake_coop.scenario.schema import Robot, ScenarioError, Tool

__all__ = ["ArmFacts", "LAB_ARMS", "LabArm", "SENSOR_RPY_FOR_AXIS", "arm_facts", "lab_arm_robot",
           "tool_axis"]

_ROBOTS = "package://example-robot-data/robots/"


@dataclass(frozen=True)
class LabArm:
    """The fields of one arm of ``example-robot-data`` (see the module's docstring).

    Attributes
    ----------
    title : str
        The arm's maker and name (``Franka Emika Panda``).
    model : str
        Its ``package://`` URL.
    base_frame : str
        The link welded to the palm frame.
    flange : str
        The link the tool is mounted on.
    locked_joints : dict
        Joint name → locked position (rad or m).
    """

    title: str
    model: str
    base_frame: str
    flange: str
    locked_joints: dict = field(default_factory=dict)


#: The arms the package ships (every serial arm of ``example-robot-data`` 6), by short name.
LAB_ARMS: dict[str, LabArm] = {
    "panda": LabArm("Franka Emika Panda", _ROBOTS + "panda_description/urdf/panda.urdf",
                    "panda_link0", "panda_hand",
                    {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}),
    "ur3": LabArm("Universal Robots UR3", _ROBOTS + "ur_description/urdf/ur3_robot.urdf",
                  "base_link", "tool0"),
    "ur5": LabArm("Universal Robots UR5", _ROBOTS + "ur_description/urdf/ur5_robot.urdf",
                  "base_link", "tool0"),
    "ur10": LabArm("Universal Robots UR10", _ROBOTS + "ur_description/urdf/ur10_robot.urdf",
                   "base_link", "tool0"),
    "xarm7": LabArm("UFactory xArm7", _ROBOTS + "xarm_description/urdf/xarm7.urdf",
                    "link_base", "link_eef"),
    "jaco2": LabArm("Kinova Jaco2 (j2s6s200)", _ROBOTS + "kinova_description/robots/kinova.urdf",
                    "base", "j2s6s200_end_effector"),
    "z1": LabArm("Unitree Z1", _ROBOTS + "z1_description/urdf/z1.urdf", "link00", "link06",
                 {"jointGripper": 0.0}),
    "so100": LabArm("SO-ARM100", _ROBOTS + "so_arm_description/urdf/so100.urdf", "base",
                    "gripper", {"gripper": 0.0}),
    "so101": LabArm("SO-ARM101", _ROBOTS + "so_arm_description/urdf/so101.urdf", "base_link",
                    "gripper_frame_link", {"gripper": 0.0}),
}


def lab_arm_robot(name: str) -> Robot:
    """A :class:`~drake_coop.scenario.schema.Robot` with the fields of :data:`LAB_ARMS`
    ``[name]`` (tool with its defaults, ``ee_frame: pad``, ``sensor_joint:
    flange_sensor_weld``); the task's fields (normals, gains, ...) keep their defaults.

    Parameters
    ----------
    name : str
        A key of :data:`LAB_ARMS`.

    Raises
    ------
    ValueError
        An arm not in :data:`LAB_ARMS` (the known ones are named).
    """
    if name not in LAB_ARMS:
        raise ValueError(f"arm must be one of {', '.join(LAB_ARMS)}, got {name!r}")
    arm = LAB_ARMS[name]
    return Robot(name=name, model=arm.model, base_frame=arm.base_frame,
                 locked_joints=dict(arm.locked_joints), tool=Tool(flange=arm.flange),
                 ee_frame="pad", sensor_joint="flange_sensor_weld")


@dataclass
class ArmFacts:
    """What Drake reads from one prepared arm (:func:`arm_facts`).

    Attributes
    ----------
    joints : list[str]
        The moving joints, in the plant's order.
    effort_limits : list[float]
        Each joint actuator's effort limit (N·m or N), as Drake read it from ``<limit effort>``.
    lower, upper : list[float]
        Position limits (rad or m).
    reductions : list[float | None]
        The URDF's ``mechanicalReduction`` per joint (``None`` when the URDF gives none), which
        Drake ignores.
    path : str
        The prepared URDF.
    tool_axis : str
        The flange's axis the tool points along (``+z``, ``+x``, ``-y``, ...): the axis of the
        last moving joint before the flange, in the flange's frame, signed outwards (from that
        joint's parent body towards the flange). The pad sits along the sensor's z
        (``tool.pad_xyz``), so an arm whose tool axis is not ``+z`` needs the sensor turned
        onto it (:data:`SENSOR_RPY_FOR_AXIS`).
    """

    joints: list[str]
    effort_limits: list[float]
    lower: list[float]
    upper: list[float]
    reductions: list[float | None]
    path: str
    tool_axis: str = "+z"


#: ``tool.sensor_rpy_deg`` that turns the sensor's (and the pad's) z onto a flange axis.
SENSOR_RPY_FOR_AXIS = {"+z": [0.0, 0.0, 0.0], "-z": [180.0, 0.0, 0.0],
                       "+x": [0.0, 90.0, 0.0], "-x": [0.0, -90.0, 0.0],
                       "+y": [-90.0, 0.0, 0.0], "-y": [90.0, 0.0, 0.0]}


def tool_axis(plant, flange_body) -> str:
    """The flange's axis the tool points along (see :attr:`ArmFacts.tool_axis`) in a finalized
    ``plant``: the axis of the first moving joint found walking from ``flange_body`` towards
    the base, in the flange's frame, rounded to the nearest coordinate axis and signed from
    that joint's parent body's origin towards the flange's origin (``+`` when they coincide
    along it).

    Parameters
    ----------
    plant : MultibodyPlant
        The arm's finalized plant.
    flange_body : Body
        The flange's body.

    Returns
    -------
    str
        The signed axis, e.g. ``"+z"`` or ``"+x"``.
    """
    import numpy as np

    body, joint = flange_body, None
    while joint is None and body.index() != plant.world_body().index():
        inboard = [plant.get_joint(j) for j in plant.GetJointIndices()
                   if plant.get_joint(j).child_body().index() == body.index()]
        if not inboard:
            break
        if inboard[0].num_velocities() == 1 and hasattr(inboard[0], "revolute_axis"):
            joint = inboard[0]
        body = inboard[0].parent_body()
    if joint is None:
        return "+z"
    context = plant.CreateDefaultContext()
    F = flange_body.body_frame()
    axis = plant.CalcRelativeTransform(context, F, joint.frame_on_child()).rotation().multiply(
        joint.revolute_axis())
    k = int(np.argmax(np.abs(axis)))
    parent = plant.CalcRelativeTransform(context, F, joint.parent_body().body_frame())
    outward = -parent.translation()[k]          # from the parent's origin to the flange's
    sign = axis[k] if abs(outward) < 1e-9 else outward
    return ("+" if sign >= 0 else "-") + "xyz"[k]


def arm_facts(name: str) -> ArmFacts:
    """Prepare arm ``name`` of :data:`LAB_ARMS` as a run does and load it with a ``SceneGraph``.

    Parameters
    ----------
    name : str
        A key of :data:`LAB_ARMS`.

    Returns
    -------
    ArmFacts
        What Drake read.

    Raises
    ------
    ScenarioError
        The package is not installed, or the prepared URDF is not a model Drake can load or
        not a physically possible arm (:func:`~drake_coop.scenario.model_check.check_model_file`;
        one line naming the arm).
    """
    import logging

    from pydrake.geometry import SceneGraph
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    from drake_coop.scenario.resources import model_urdf_path, resolve_package_url

    robot = lab_arm_robot(name)
    path = model_urdf_path(robot, f"arms[{name}].model")
    from drake_coop.scenario.model_check import check_model_file

    check_model_file(path, f"arms[{name}].model", robot, shown=robot.model)   # physics too
    logger = logging.getLogger("drake")
    previous = logger.level
    logger.setLevel(logging.ERROR)        # the parser's warnings (ignored URDF tags)
    try:
        plant = MultibodyPlant(0.0)
        scene_graph = SceneGraph()       # kept alive: the plant points at it
        plant.RegisterAsSourceForSceneGraph(scene_graph)
        Parser(plant).AddModels(str(path))
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(robot.base_frame))
        plant.Finalize()
    except Exception as exc:        # Drake's parser raises RuntimeError / ValueError
        raise ScenarioError(f"arms[{name}]: {robot.model} does not load: "
                            f"{' '.join(str(exc).split())[:160]}") from None
    finally:
        logger.setLevel(previous)
    joints, effort = [], []
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        joints.append(actuator.joint().name())
        effort.append(float(actuator.effort_limit()))
    source = ET.parse(resolve_package_url(robot.model)).getroot()
    reduction = {}
    for transmission in source.findall("transmission"):
        text = transmission.findtext(".//mechanicalReduction")
        for joint in transmission.findall("joint"):
            if text is not None:
                reduction[joint.get("name")] = float(text)
    return ArmFacts(joints=joints, effort_limits=effort,
                    lower=[float(v) for v in plant.GetPositionLowerLimits()],
                    upper=[float(v) for v in plant.GetPositionUpperLimits()],
                    reductions=[reduction.get(j) for j in joints], path=str(path),
                    tool_axis=tool_axis(plant, plant.GetBodyByName(robot.tool.flange)))
