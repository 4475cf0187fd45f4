"""Model files of a scenario checked before anything is built.

Each arm's URDF (a shipped ``model`` or a ``.urdf`` path) and each ``controller_model`` must be
a readable regular ``.urdf`` file of at most :data:`MAX_MODEL_BYTES`, parse as XML with a
``<robot>`` root (no DTD: no entity expansion), and load into a single-arm ``MultibodyPlant``
exactly as :class:`~drake_coop.control.arm_model.ArmModel` loads it (``base_frame`` welded to
the world) with a ``SceneGraph`` attached (as in a run), with the ``ee_frame``, the fixed ``sensor_joint`` and between
:data:`MIN_JOINTS` and :data:`MAX_JOINTS` one-degree-of-freedom joints. A failure raises
:class:`~drake_coop.scenario.ScenarioError` with one line naming the field and the path.

The arm must also be physically possible (:func:`physical_problem`, on the file's XML, then on
what Drake loaded): every link's mass finite and ``>= 0`` (0 only with no inertia) and its rotational
inertia about its centre of mass symmetric positive semi-definite with principal moments that
satisfy the triangle inequality (``I_a + I_b >= I_c``: a real body's, within
:data:`INERTIA_TOL` of the largest moment); every moving joint's limits ordered
(``lower <= upper``) and its ``effort`` > 0 where given; every moving joint driven by an
actuator with an effort limit > 0 (Drake makes none for a ``<transmission>``-less joint, nor
for a zero effort), and moving some mass: the mass matrix ``M(q)`` at the joints' mid-range
(0 for an unlimited joint) positive definite. The message names the link or joint and the
attribute.

Paths are resolved by :func:`~drake_coop.scenario.resources.model_urdf_path` (shipped models
and paths relative to the ``urdf/`` folder). A file already checked is not parsed again while its
size and modification time are unchanged.
"""

from __future__ import annotations

import functools
import logging
import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path

from drake_coop.scenario.bounds import one_line
from drake_coop.scenario.resources import controller_urdf_path, model_urdf_path
from drake_coop.scenario.schema import Robot, Scenario, ScenarioError

__all__ = ["INERTIA_TOL", "MAX_MODEL_BYTES", "MAX_JOINTS", "MIN_JOINTS", "check_model_file",
           "check_models", "physical_problem"]

#: Largest model file read (bytes); ours are 6-10 kB.
MAX_MODEL_BYTES = 10_000_000
#: Joints an arm may have (its joint positions, all one-degree-of-freedom).
MIN_JOINTS, MAX_JOINTS = 1, 12
#: Relative tolerance of the inertia checks (of the largest principal moment): URDF inertias
#: are rounded to a few digits.
INERTIA_TOL = 1e-6


def check_models(scenario: Scenario) -> list[int]:
    """The number of joints ``n_i`` of every robot's arm, from checking the simulated and
    the controller's model file of each.

    Parameters
    ----------
    scenario : Scenario
        The scenario whose robots' model files are read.

    Raises
    ------
    ScenarioError
        ``robots[i].model`` (or ``controller_model``, ``base_frame``, ...), the path and the
        problem.
    """
    joints = []
    for i, robot in enumerate(scenario.robots):
        n = check_model_file(model_urdf_path(robot, f"robots[{i}].model"),
                             f"robots[{i}].model", robot, shown=_url(robot.model))
        if robot.controller_model:
            field = f"robots[{i}].controller_model"
            n_c = check_model_file(controller_urdf_path(robot, field), field, robot,
                                   shown=_url(robot.controller_model))
            if n_c != n:
                raise ScenarioError(f"robots[{i}].controller_model has {n_c} joints, the "
                                    f"simulated arm {n}")
        joints.append(n)
    return joints


def _url(value: str) -> str | None:
    """A ``package://`` URL as the messages name it (its file may be a prepared copy)."""
    return value if value.startswith("package://") else None


def check_model_file(path: str | Path, field: str, robot: Robot | None = None,
                     shown: str | None = None) -> int:
    """Check one URDF file for an arm (see the module's docstring).

    ``shown`` names the file in messages (default: its path), e.g. the ``package://`` URL a
    prepared copy comes from.

    Parameters
    ----------
    path : str or Path
        The URDF.
    field : str
        The scenario field naming it (``robots[i].model``).
    robot : Robot or None
        The robot's entry (its frames, joints); None for the defaults.
    shown : str or None
        How messages name the file; None for its path.

    Returns
    -------
    int
        The number of joint positions.

    Raises
    ------
    ScenarioError
        ``"<field>: <path> <problem>"`` (a missing frame or joint also names the field that
        names it).
    """
    robot = robot or Robot()
    path = Path(path)
    shown = one_line(shown or path, 120)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise ScenarioError(f"{field}: {shown} {_why(exc)}") from None
    problem, n = _check_cached(str(path), st.st_mtime_ns, st.st_size, robot.base_frame,
                               robot.ee_frame, robot.sensor_joint)
    if problem:
        where, _, text = problem.partition("|")
        if where:   # a frame or joint named by another field: name that field too
            text += f" ({field.rsplit('.', 1)[0]}.{where})"
        raise ScenarioError(f"{field}: {shown} {text}")
    return n


def _why(exc: OSError) -> str:
    return "not found" if isinstance(exc, FileNotFoundError) else (
        f"cannot be read ({exc.strerror or exc})")


@functools.lru_cache(maxsize=64)
def _check_cached(path: str, mtime_ns: int, size: int, base_frame: str, ee_frame: str,
                  sensor_joint: str) -> tuple[str, int]:
    """``(problem, n)``: the problem with the file ('' if none, ``field|text`` when a named
    frame or joint is at fault) and its joint count; cached per path, mtime, size, names."""
    p = Path(path)
    if not p.is_file():
        return "|is not a regular file", 0
    if p.suffix.lower() != ".urdf":
        return "|must be a .urdf file", 0
    if size > MAX_MODEL_BYTES:
        return f"|is larger than {MAX_MODEL_BYTES} bytes", 0
    try:
        raw = p.read_bytes()
    except OSError as exc:
        return "|" + _why(exc), 0
    if b"<!DOCTYPE" in raw or b"<!ENTITY" in raw:
        return "|must not declare a DTD or entities", 0
    try:
        root = ET.fromstring(raw)
    except ET.ParseError as exc:
        return f"|is not valid XML ({one_line(exc, 80)})", 0
    if root.tag != "robot":
        return (f"|is not a URDF: its root element is <{one_line(root.tag, 40)}>, "
                "not <robot>"), 0
    links = {e.get("name") for e in root.findall("link")}
    for key, frame in (("base_frame", base_frame), ("ee_frame", ee_frame)):
        if frame not in links:
            return f"{key}|has no link named {one_line(frame, 40)!r}", 0
    fixed = {e.get("name") for e in root.findall("joint") if e.get("type") == "fixed"}
    if sensor_joint not in fixed:
        return (f"sensor_joint|has no fixed joint named {one_line(sensor_joint, 40)!r} (the "
                "wrist force sensor's mount)"), 0
    moving = [e for e in root.findall("joint") if e.get("type") in ("revolute", "continuous",
                                                                     "prismatic")]
    if not MIN_JOINTS <= len(moving) <= MAX_JOINTS:
        return f"|has {len(moving)} joints, an arm needs {MIN_JOINTS} to {MAX_JOINTS}", 0
    problem = physical_problem(root)
    if problem:
        return "|" + problem, 0
    return _drake_problem(p, base_frame, ee_frame)


def _number(element, key: str) -> float | None:
    """An attribute as a float; None if absent; NaN if not a number."""
    value = element.get(key)
    if value is None:
        return None
    try:
        return float(value)
    except ValueError:
        return math.nan


def physical_problem(root: ET.Element) -> str:
    """The first physically impossible part of a URDF's arm, or ``''``.

    Parameters
    ----------
    root : xml.etree.ElementTree.Element
        The URDF's ``<robot>`` element.

    Returns
    -------
    str
        e.g. ``link 'l2' has mass -1 kg (<inertial><mass value>): a mass must be >= 0``;
        ``''`` when every link and joint passes (see the module docstring).
    """
    import numpy as np

    for link in root.findall("link"):
        name = one_line(link.get("name"), 40)
        inertial = link.find("inertial")
        if inertial is None:
            continue
        mass_el = inertial.find("mass")
        mass = _number(mass_el, "value") if mass_el is not None else 0.0
        if mass is None or not math.isfinite(mass) or mass < 0:
            return (f"link {name!r} has mass {mass_el.get('value') if mass_el is not None else ''}"
                    " (<inertial><mass value>): a mass must be a number >= 0 kg")
        inertia = inertial.find("inertia")
        if inertia is None:
            continue
        keys = ("ixx", "iyy", "izz", "ixy", "ixz", "iyz")
        v = {k: _number(inertia, k) or 0.0 for k in keys}
        if not all(math.isfinite(x) for x in v.values()):
            return f"link {name!r} has a non-finite <inertia>"
        if mass == 0:
            if any(v.values()):
                return (f"link {name!r} has mass 0 (<inertial><mass value>) and a nonzero "
                        "<inertia>: a massless link has no inertia; give its mass (> 0)")
            continue
        I = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]],
                      [v["ixz"], v["iyz"], v["izz"]]])
        moments = np.linalg.eigvalsh(I)
        tol = INERTIA_TOL * max(abs(moments).max(), 1e-300)
        if moments.min() < -tol:
            return (f"link {name!r} has an <inertia> that is not positive semi-definite "
                    f"(principal moments {', '.join(f'{m:.3g}' for m in moments)} kg·m²)")
        a, b, c = moments
        if a + b < c - tol:
            return (f"link {name!r} has an <inertia> no body has: its principal moments "
                    f"{a:.3g}, {b:.3g}, {c:.3g} kg·m² break the triangle inequality "
                    f"({a:.3g} + {b:.3g} < {c:.3g})")
    for joint in root.findall("joint"):
        if joint.get("type") not in ("revolute", "prismatic", "continuous"):
            continue
        name = one_line(joint.get("name"), 40)
        limit = joint.find("limit")
        if limit is None:
            continue
        lower, upper, effort = (_number(limit, k) for k in ("lower", "upper", "effort"))
        if joint.get("type") != "continuous" and lower is not None and upper is not None \
                and not lower <= upper:
            return (f"joint {name!r} has <limit lower={limit.get('lower')!r} "
                    f"upper={limit.get('upper')!r}>: lower must be <= upper")
        if effort is not None and not effort > 0:
            return (f"joint {name!r} has <limit effort={limit.get('effort')!r}>: an arm's "
                    "joint needs an actuator with effort > 0 (N·m or N)")
    return ""


def _drake_physical_problem(plant) -> str:
    """An actuator with effort > 0 on every moving joint, and ``M(q)`` positive definite at
    the joints' mid-range (see the module docstring); ``''`` if both hold."""
    import numpy as np

    joints = [plant.get_joint(j) for j in plant.GetJointIndices()
              if plant.get_joint(j).num_velocities() == 1]
    driven = {}
    for a in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(a)
        driven[actuator.joint().index()] = actuator
    for joint in joints:
        actuator = driven.get(joint.index())
        if actuator is None:
            return (f"joint {one_line(joint.name(), 40)!r} has no actuator (a <transmission> "
                    "with an <actuator>, and <limit effort> > 0): every joint of an arm is "
                    "driven")
        if not actuator.effort_limit() > 0:
            return (f"joint {one_line(joint.name(), 40)!r}'s actuator has effort limit "
                    f"{actuator.effort_limit():g}: it must be > 0")
    context = plant.CreateDefaultContext()
    lo, hi = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    q = np.where(np.isfinite(lo) & np.isfinite(hi), 0.5 * (lo + hi),
                 np.clip(0.0, lo, hi))
    plant.SetPositions(context, q)
    M = plant.CalcMassMatrix(context)
    scale = max(float(np.abs(np.diag(M)).max()), 1e-300)
    if np.linalg.eigvalsh(M).min() <= 1e-12 * scale or scale <= 1e-12:
        j = int(np.argmin(np.diag(M)))
        name = next((jt.name() for jt in joints if jt.velocity_start() == j), str(j))
        return (f"joint {one_line(name, 40)!r} moves no mass (its mass matrix M(q) is "
                "singular: every link it moves is massless, <inertial><mass value> 0)")
    return ""


def _drake_problem(path: Path, base_frame: str, ee_frame: str) -> tuple[str, int]:
    """Load the file as :class:`~drake_coop.control.arm_model.ArmModel` does, with a
    ``SceneGraph`` attached as a run's plant has (the parser checks the visual geometry and
    materials only then: a material defined twice differently is refused there)."""
    from pydrake.geometry import SceneGraph
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    logger = logging.getLogger("drake")      # Drake's C++ log goes through this logger
    previous = logger.level
    logger.setLevel(logging.CRITICAL)        # warnings would add lines to the one-line error
    try:
        plant = MultibodyPlant(0.0)
        scene_graph = SceneGraph()       # kept alive: the plant points at it
        plant.RegisterAsSourceForSceneGraph(scene_graph)
        Parser(plant).AddModels(str(path))
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(base_frame))
        plant.Finalize()
        plant.GetFrameByName(ee_frame)
        n = plant.num_positions()
        if n != plant.num_velocities() or not MIN_JOINTS <= n <= MAX_JOINTS:
            return (f"|gives {n} joint positions and {plant.num_velocities()} velocities, an "
                    f"arm needs {MIN_JOINTS} to {MAX_JOINTS} one-degree-of-freedom joints"), 0
        problem = _drake_physical_problem(plant)
        if problem:
            return "|" + problem, 0
    except Exception as exc:    # Drake's parser and plant raise RuntimeError / ValueError
        return f"|is not a model Drake can load: {one_line(exc, 120)}", 0
    finally:
        logger.setLevel(previous)
    return "", n
