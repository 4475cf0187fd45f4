"""Model files of a scenario checked before anything is built.

Each arm's URDF (``urdf/<model>_3dof.urdf``) and each ``controller_model`` must be a readable
regular ``.urdf`` file of at most :data:`MAX_MODEL_BYTES`, parse as XML with a ``<robot>``
root (no DTD: no entity expansion), and load into a single-arm ``MultibodyPlant`` exactly as
:class:`~drake_coop.control.arm_model.ArmModel` loads it (``base_link`` welded to the world), with the
``pad`` frame and :data:`NUM_JOINTS` revolute joints. A failure raises
:class:`~drake_coop.scenario.ScenarioError` with one line naming the field and the path.

Paths are resolved as the arms resolve them (relative to
:func:`drake_coop.plant.arms.urdf_dir`). A file already checked is not parsed again while its size
and modification time are unchanged.
"""

from __future__ import annotations

import functools
import logging
import os
import xml.etree.ElementTree as ET
from pathlib import Path

from drake_coop.scenario.bounds import one_line
from drake_coop.scenario.schema import Scenario, ScenarioError

__all__ = ["MAX_MODEL_BYTES", "NUM_JOINTS", "check_model_file", "check_models"]

#: Largest model file read (bytes); ours are 6 kB.
MAX_MODEL_BYTES = 10_000_000
#: Joints of every arm (waist, shoulder, elbow).
NUM_JOINTS = 3


def check_models(scenario: Scenario) -> None:
    """Check the simulated and the controller's model file of every robot.

    Raises
    ------
    ScenarioError
        ``robots[i].controller_model`` (or ``robots[i].model``), the path and the problem.
    """
    from drake_coop.plant.arms import Arm

    for i, robot in enumerate(scenario.robots):
        arm = Arm(robot)
        check_model_file(arm.urdf_path, f"robots[{i}].model")
        if robot.controller_model:
            check_model_file(arm.controller_urdf_path, f"robots[{i}].controller_model")


def check_model_file(path: str | Path, field: str) -> None:
    """Check one URDF file for a 3-joint arm (see the module's docstring).

    Raises
    ------
    ScenarioError
        ``"<field>: <path> <problem>"``.
    """
    path = Path(path)
    shown = one_line(path, 120)
    try:
        st = os.stat(path)
    except OSError as exc:
        raise ScenarioError(f"{field}: {shown} {_why(exc)}") from None
    problem = _check_cached(str(path), st.st_mtime_ns, st.st_size)
    if problem:
        raise ScenarioError(f"{field}: {shown} {problem}")


def _why(exc: OSError) -> str:
    return "not found" if isinstance(exc, FileNotFoundError) else (
        f"cannot be read ({exc.strerror or exc})")


@functools.lru_cache(maxsize=64)
def _check_cached(path: str, mtime_ns: int, size: int) -> str:
    """The problem with the file ('' if none); cached per path, mtime and size."""
    p = Path(path)
    if not p.is_file():
        return "is not a regular file"
    if p.suffix.lower() != ".urdf":
        return "must be a .urdf file"
    if size > MAX_MODEL_BYTES:
        return f"is larger than {MAX_MODEL_BYTES} bytes"
    try:
        raw = p.read_bytes()
    except OSError as exc:
        return _why(exc)
    if b"<!DOCTYPE" in raw or b"<!ENTITY" in raw:
        return "must not declare a DTD or entities"
    try:
        root = ET.fromstring(raw)
    except ET.ParseError as exc:
        return f"is not valid XML ({one_line(exc, 80)})"
    if root.tag != "robot":
        return f"is not a URDF: its root element is <{one_line(root.tag, 40)}>, not <robot>"
    links = {e.get("name") for e in root.findall("link")}
    for frame in ("base_link", "pad"):
        if frame not in links:
            return f"has no link named '{frame}' (the arm's base and its end-effector pad)"
    revolute = [e for e in root.findall("joint") if e.get("type") in ("revolute", "continuous")]
    if len(revolute) != NUM_JOINTS:
        return f"has {len(revolute)} revolute joints, the arm needs {NUM_JOINTS}"
    return _drake_problem(p)


def _drake_problem(path: Path) -> str:
    """Load the file as :class:`~drake_coop.control.arm_model.ArmModel` does; '' if Drake accepts it."""
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    logger = logging.getLogger("drake")      # Drake's C++ log goes through this logger
    previous = logger.level
    logger.setLevel(logging.CRITICAL)        # warnings would add lines to the one-line error
    try:
        plant = MultibodyPlant(0.0)
        Parser(plant).AddModels(str(path))
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName("base_link"))
        plant.Finalize()
        if plant.num_positions() != NUM_JOINTS:
            return f"gives {plant.num_positions()} joint positions, the arm needs {NUM_JOINTS}"
        plant.GetFrameByName("pad")
    except Exception as exc:    # Drake's parser and plant raise RuntimeError / ValueError
        return f"is not a model Drake can load: {one_line(exc, 120)}"
    finally:
        logger.setLevel(previous)
    return ""
