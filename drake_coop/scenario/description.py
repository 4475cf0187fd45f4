"""Arms from a robot description package: the URDF a run loads, prepared from the package's.

A robot's ``model`` may be a ``package://`` URL of a maintained description, e.g.
``package://example-robot-data/robots/panda_description/urdf/panda.urdf`` (the optional
``robots`` extra, ``pip install -e ".[robots]"``: the PyPI wheel ``example-robot-data`` holds
no Python module, its data lands in ``site-packages/cmeel.prefix/share/example-robot-data``,
whose ``package.xml`` names the package ``example_robot_descriptions`` while its URDFs say
``package://example-robot-data/...``; :func:`~drake_coop.control.arm_plant.description_packages`
adds Drake's :class:`~pydrake.multibody.parsing.PackageMap` entry by the URDFs' name).

Such a file is not an arm the rest of the package can use as it is: a Panda has a floating
base, two finger joints and no force sensor or pad. :func:`prepared_urdf` writes the URDF every
part of a run loads (the cooperative plant, the controller's model, the kinematics, the model
error's scaled copy, identification), derived from the package's file and the robot's fields:

* ``locked_joints``: each named joint becomes a ``fixed`` joint at the stated position
  (its transmission removed);
* ``tool``: a ``force_sensor`` link welded to ``tool.flange`` by ``flange_sensor_weld`` and a
  ``pad`` link (a compliant-hydroelastic sphere, the end-effector point) welded to the sensor
  by ``sensor_pad_weld`` (:class:`~drake_coop.scenario.schema.Tool`);
* an identified URDF (``drake-coop identify``'s, marked :data:`IDENTIFIED_MARK`) was identified
  on the prepared arm: its locked joints are fixed and its tool is on already, so neither is
  applied again when it is a robot's ``controller_model``;
* actuators: a ``SimpleTransmission`` for every moving joint without one (the Panda's URDF
  has none, and Drake actuates a URDF joint only through one); the joint's effort limit
  stays the actuator's;
* meshes: ``package://`` mesh URLs become absolute paths. Visual meshes stay; Drake 1.51 reads
  ``.obj``, ``.gltf``/``.glb`` (shown in Meshcat) and passes other formats (``.dae``, ``.stl``)
  to Meshcat as files, which it shows when the browser's loader reads them;
* collision geometry of the package's links is **left out**: its meshes are ``.stl`` and a
  discrete ``MultibodyPlant`` makes a convex hull of every collision mesh, which Drake 1.51
  computes for ``.obj``, ``.vtk`` and ``.gltf`` only (it refuses the Panda's ``link0.stl``).
  Only the pads touch anything (the ``contact`` mode's box); the arms' links pass through each
  other and the object;
* materials: a ``<material name=...>`` defined again with another colour or texture (Kinova
  Jaco2's ``carbon_fiber``), which Drake's parser refuses once a ``SceneGraph`` is attached,
  is renamed ``name__2``, ``name__3``, ... (each visual keeps its own colour).

The base is welded where the scenario says (``base_frame`` at ``base_xyz``, ``base_yaw_deg``)
by every loader, which also removes a floating base (the Panda's); a ``world`` link of the
package's file and the joint that welds it (the UR5's) are removed.

The prepared file is written once per source file and fields, atomically, under
``$DRAKE_COOP_CACHE_DIR`` (default ``$XDG_CACHE_HOME/drake_coop/arms``, else
``~/.cache/drake_coop/arms``), named by a hash of its content's inputs.
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from drake_coop.scenario.bounds import one_line
from drake_coop.scenario.schema import Robot, ScenarioError

__all__ = ["IDENTIFIED_MARK", "ROBOTS_EXTRA", "TOOL_NAMES", "cache_dir", "needs_preparation", "prepared_urdf"]

#: The comment an identified URDF starts with (``drake-coop identify``,
#: :func:`~drake_coop.identification.urdf_writer.identified_urdf_text`): it was identified on
#: the prepared arm, its locked joints already fixed and its tool already on, so
#: :func:`prepared_urdf` adds neither again.
IDENTIFIED_MARK = "Identified by drake-coop identify."

#: How to install the descriptions (named in the error when a package URL cannot be found).
ROBOTS_EXTRA = 'pip install -e ".[robots]"'
#: Links and joints a tool adds (a model must not have them already).
TOOL_NAMES = ("force_sensor", "pad", "flange_sensor_weld", "sensor_pad_weld")
_DRAKE = "{http://drake.mit.edu}"
_MOVING = ("revolute", "continuous", "prismatic")
#: Bump when the prepared file's layout changes (part of the cache key).
_VERSION = "5"


def cache_dir() -> Path:
    """Where prepared URDFs are written (see the module's docstring).
    """
    env = os.environ.get("DRAKE_COOP_CACHE_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "drake_coop" / "arms"


def needs_preparation(robot: Robot, value: str) -> bool:
    """Whether the model file ``value`` of ``robot`` is loaded through :func:`prepared_urdf`:
    a URL of a description package (:data:`~drake_coop.control.arm_plant.DESCRIPTION_PACKAGES`),
    locked joints or a tool. Another package's file (on ``ROS_PACKAGE_PATH``) is used as it is.

    Parameters
    ----------
    robot : Robot
        The robot.
    value : str
        Its model file (path or ``package://`` URL).
    """
    from drake_coop.control.arm_plant import DESCRIPTION_PACKAGES

    package = value[len("package://"):].split("/", 1)[0] if value.startswith("package://") else ""
    return package in DESCRIPTION_PACKAGES or bool(robot.locked_joints) or robot.tool is not None


def _where(field: str) -> str:
    """``robots[i].`` from ``robots[i].model`` (empty for a bare field name)."""
    head, dot, _ = field.rpartition(".")
    return head + dot


def _origin(element: ET.Element | None) -> tuple[np.ndarray, np.ndarray]:
    """``(xyz, R)`` of a URDF ``<origin>`` (identity when absent)."""
    from pydrake.math import RollPitchYaw

    if element is None:
        return np.zeros(3), np.eye(3)
    xyz = np.array([float(v) for v in element.get("xyz", "0 0 0").split()])
    rpy = [float(v) for v in element.get("rpy", "0 0 0").split()]
    return xyz, RollPitchYaw(rpy).ToRotationMatrix().matrix()


def _set_origin(joint: ET.Element, xyz: np.ndarray, R: np.ndarray) -> None:
    from pydrake.math import RollPitchYaw, RotationMatrix

    for old in joint.findall("origin"):
        joint.remove(old)
    rpy = RollPitchYaw(RotationMatrix(R)).vector()
    ET.SubElement(joint, "origin", xyz=" ".join(repr(float(v)) for v in xyz),
                  rpy=" ".join(repr(float(v)) for v in rpy))


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _lock(root: ET.Element, name: str, value: float, field: str) -> None:
    """Joint ``name`` becomes fixed at ``value`` (its motion folded into its origin)."""
    joints = {j.get("name"): j for j in root.findall("joint")}
    joint = joints.get(name)
    if joint is None or joint.get("type") not in _MOVING:
        moving = sorted(n for n, j in joints.items() if j.get("type") in _MOVING)
        raise ScenarioError(f"{field}: the model has no moving joint named "
                            f"{one_line(name, 40)!r} (its joints: {', '.join(moving)})")
    limit = joint.find("limit")
    if limit is not None and joint.get("type") != "continuous":
        lo, hi = float(limit.get("lower", "-inf")), float(limit.get("upper", "inf"))
        if not lo <= value <= hi:
            raise ScenarioError(f"{field}[{name}] must be within the joint's limits "
                                f"[{lo:g}, {hi:g}], got {value!r}")
    axis_el = joint.find("axis")
    axis = np.array([float(v) for v in (axis_el.get("xyz", "1 0 0") if axis_el is not None
                                         else "1 0 0").split()])
    xyz, R = _origin(joint.find("origin"))
    if joint.get("type") == "prismatic":
        xyz = xyz + R @ (value * axis / np.linalg.norm(axis))
    else:
        R = R @ _axis_rotation(axis, value)
    for tag in ("axis", "limit", "dynamics", "mimic", "safety_controller", "calibration"):
        for old in joint.findall(tag):
            joint.remove(old)
    joint.set("type", "fixed")
    _set_origin(joint, xyz, R)
    for transmission in root.findall("transmission"):
        if any(j.get("name") == name for j in transmission.findall("joint")):
            root.remove(transmission)


def _add_tool(root: ET.Element, robot: Robot, where: str) -> None:
    tool = robot.tool
    links = {e.get("name") for e in root.findall("link")}
    joints = {e.get("name") for e in root.findall("joint")}
    if tool.flange not in links:
        raise ScenarioError(f"{where}tool.flange: the model has no link named "
                            f"{one_line(tool.flange, 40)!r}")
    taken = [n for n in TOOL_NAMES if n in links or n in joints]
    if taken:
        raise ScenarioError(f"{where}tool: the model already has {', '.join(taken)} (a tool "
                            "adds them); set tool: null and name its own frames")
    ms, mp, r = float(tool.sensor_mass), float(tool.pad_mass), float(tool.pad_radius)
    # The sensor: a solid cylinder (radius 0.035 m, 0.03 m long) above its frame.
    ixx, izz = ms * (3 * 0.035**2 + 0.03**2) / 12, ms * 0.035**2 / 2
    sensor = ET.SubElement(root, "link", name="force_sensor")
    inertial = ET.SubElement(sensor, "inertial")
    ET.SubElement(inertial, "origin", xyz="0 0 0.015")
    ET.SubElement(inertial, "mass", value=repr(ms))
    ET.SubElement(inertial, "inertia", ixx=repr(ixx), ixy="0", ixz="0", iyy=repr(ixx),
                  iyz="0", izz=repr(izz))
    visual = ET.SubElement(sensor, "visual")
    ET.SubElement(visual, "origin", xyz="0 0 0.015")
    ET.SubElement(ET.SubElement(visual, "geometry"), "cylinder", radius="0.035",
                  length="0.03")
    ET.SubElement(ET.SubElement(visual, "material", name="drake_coop_sensor"), "color",
                  rgba="0.2 0.2 0.8 1")
    pad = ET.SubElement(root, "link", name="pad")
    inertial = ET.SubElement(pad, "inertial")
    ET.SubElement(inertial, "mass", value=repr(mp))
    i_pad = repr(0.4 * mp * r * r)
    ET.SubElement(inertial, "inertia", ixx=i_pad, ixy="0", ixz="0", iyy=i_pad, iyz="0",
                  izz=i_pad)
    visual = ET.SubElement(pad, "visual")
    ET.SubElement(ET.SubElement(visual, "geometry"), "sphere", radius=repr(r))
    ET.SubElement(ET.SubElement(visual, "material", name="drake_coop_pad"), "color",
                  rgba="0.1 0.1 0.1 1")
    collision = ET.SubElement(pad, "collision", name="pad_collision")
    ET.SubElement(ET.SubElement(collision, "geometry"), "sphere", radius=repr(r))
    props = ET.SubElement(collision, f"{_DRAKE}proximity_properties")
    ET.SubElement(props, f"{_DRAKE}compliant_hydroelastic")
    for tag, value in (("hydroelastic_modulus", "5e+06"), ("mesh_resolution_hint", "0.005"),
                       ("hunt_crossley_dissipation", "5"), ("mu_dynamic", "1"),
                       ("mu_static", "1")):
        ET.SubElement(props, f"{_DRAKE}{tag}", value=value)
    from pydrake.math import RollPitchYaw

    weld = ET.SubElement(root, "joint", name="flange_sensor_weld", type="fixed")
    ET.SubElement(weld, "parent", link=tool.flange)
    ET.SubElement(weld, "child", link="force_sensor")
    _set_origin(weld, np.asarray(tool.sensor_xyz, dtype=float),
                RollPitchYaw(np.radians(tool.sensor_rpy_deg)).ToRotationMatrix().matrix())
    weld = ET.SubElement(root, "joint", name="sensor_pad_weld", type="fixed")
    ET.SubElement(weld, "parent", link="force_sensor")
    ET.SubElement(weld, "child", link="pad")
    _set_origin(weld, np.asarray(tool.pad_xyz, dtype=float), np.eye(3))


def _actuate(root: ET.Element) -> None:
    """A ``SimpleTransmission`` (an actuator) for every moving joint that has none: Drake makes
    an actuator only from a transmission, and a description's URDF (the Panda's) may have none.
    The joint's ``<limit effort>`` becomes the actuator's effort limit, as Drake reads it."""
    driven = {j.get("name") for t in root.findall("transmission") for j in t.findall("joint")}
    for joint in root.findall("joint"):
        name = joint.get("name")
        if joint.get("type") in _MOVING and name not in driven:
            transmission = ET.SubElement(root, "transmission", type="SimpleTransmission",
                                         name=f"{name}_transmission")
            ET.SubElement(transmission, "joint", name=name)
            ET.SubElement(transmission, "actuator", name=f"{name}_motor")


def _clean(root: ET.Element) -> None:
    """A description package's file made loadable: collision geometry removed; a ``world``
    link and its joints removed (the UR5's: the base is welded where the scenario says); the
    joints' ``safety_controller`` and ``calibration`` removed (Drake ignores them with a
    warning)."""
    for link in root.findall("link"):
        if link.get("name") == "world":
            root.remove(link)
            continue
        for collision in link.findall("collision"):
            link.remove(collision)
    for joint in root.findall("joint"):
        if (joint.find("parent") is not None
                and joint.find("parent").get("link") == "world"):
            root.remove(joint)
            continue
        for tag in ("safety_controller", "calibration"):
            for old in joint.findall(tag):
                joint.remove(old)


def _dedupe_materials(root: ET.Element) -> None:
    """Each material name defined once: a later definition (a ``<material>`` with a ``color`` or
    ``texture``) that differs from the first of its name is renamed ``name__k``; a repeated
    identical definition and a bare reference keep the name."""
    first: dict[str, bytes] = {}
    count: dict[str, int] = {}
    for material in root.iter("material"):
        name = material.get("name")
        if name is None or (material.find("color") is None and material.find("texture") is None):
            continue
        body = b"".join(ET.tostring(child) for child in material)
        if name not in first:
            first[name] = body
        elif body != first[name]:
            count[name] = count.get(name, 1) + 1
            material.set("name", f"{name}__{count[name]}")


def _absolute_meshes(root: ET.Element, resolve, base_dir: Path) -> None:
    """Mesh file names as absolute paths (the prepared file lives elsewhere): ``package://``
    URLs through ``resolve``, relative paths from the source file's folder."""
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        if name.startswith("package://") and resolve is not None:
            mesh.set("filename", str(resolve(name)))
        elif name and "://" not in name and not Path(name).is_absolute():
            mesh.set("filename", str((base_dir / name).resolve()))


class _OncePerPreparedFile(logging.Filter):
    """Passes each distinct Drake log message about a prepared file once per process.

    Every part of a run loads the prepared file again (the plant, the controller's model, the
    kinematics, each posture of ``drake-coop gains``), and Drake's parser warns again at each
    load of what it ignores (the xArm7's joint friction and gear reductions: 14 lines a load,
    420 lines for one ``gains``). The first occurrence of each still reaches the log."""

    def __init__(self) -> None:
        super().__init__()
        self.files: set[str] = set()
        self.seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        text = record.getMessage()
        if not any(f in text for f in self.files):
            return True
        if text in self.seen:
            return False
        self.seen.add(text)
        return True


_ONCE = _OncePerPreparedFile()


def _log_once(path: Path) -> Path:
    """Register ``path`` with the ``drake`` logger's once-per-message filter; returns it."""
    logger = logging.getLogger("drake")
    if _ONCE not in logger.filters:
        logger.addFilter(_ONCE)
    _ONCE.files.add(str(path))
    return path


def prepared_urdf(robot: Robot, source: Path, field: str = "model", resolve=None,
                  from_package: bool = False) -> Path:
    """The URDF a run loads for ``robot`` (see the module's docstring).

    Parameters
    ----------
    robot : Robot
        Its ``locked_joints`` and ``tool``.
    source : Path
        The model file (a package URL already resolved to its file).
    field : str
        The scenario field naming the model (``robots[i].model``), for error messages.
    resolve : callable, optional
        ``package://`` URL → Path for the meshes (the package map of
        :func:`~drake_coop.scenario.resources.resolve_package_url`).
    from_package : bool
        The source is a description package's file: its collision geometry, ``world`` link and
        ignored joint tags are removed (see the module's docstring).

    Returns
    -------
    Path
        The prepared URDF, in :func:`cache_dir` (written once per content).

    Raises
    ------
    ScenarioError
        Naming the field: an unreadable or invalid source, a locked joint the model does not
        have (or a position outside its limits), a tool flange that is not a link.
    """
    where = _where(field)
    try:
        raw = Path(source).read_bytes()
    except OSError as exc:
        raise ScenarioError(f"{field}: {one_line(source, 120)} cannot be read "
                            f"({exc.strerror or exc})") from None
    if b"<!DOCTYPE" in raw or b"<!ENTITY" in raw:
        raise ScenarioError(f"{field}: {one_line(source, 120)} must not declare a DTD or "
                            "entities")
    key = hashlib.sha256(repr((_VERSION, str(source), raw, sorted(robot.locked_joints.items()),
                               robot.tool, from_package)).encode()).hexdigest()[:24]
    out = cache_dir() / f"{Path(source).stem}_{key}.urdf"
    if out.is_file():
        return _log_once(out)
    ET.register_namespace("drake", "http://drake.mit.edu")
    try:
        root = ET.fromstring(raw)
    except ET.ParseError as exc:
        raise ScenarioError(f"{field}: {one_line(source, 120)} is not valid XML "
                            f"({one_line(exc, 80)})") from None
    if root.tag != "robot":
        raise ScenarioError(f"{field}: {one_line(source, 120)} is not a URDF (no <robot> root)")
    if from_package:
        _clean(root)
    _dedupe_materials(root)
    _absolute_meshes(root, resolve, Path(source).parent)
    identified = IDENTIFIED_MARK.encode() in raw[:4096]   # prepared already (see the mark)
    for name, value in ({} if identified else robot.locked_joints).items():
        _lock(root, name, float(value), f"{where}locked_joints")
    if robot.tool is not None and not identified:
        _add_tool(root, robot, where)
    _actuate(root)
    body = ET.tostring(root, encoding="unicode")
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=out.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write('<?xml version="1.0"?>\n<!-- Written by drake_coop from '
                    f'{Path(source).name}: see drake_coop/scenario/description.py -->\n{body}\n')
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return _log_once(out)
