"""Model error without hand-written URDFs: the controller's scaled model, the simulated payload.

The controller's model (:class:`~drake_coop.control.arm_model.ArmModel`) is parsed from the simulated
arm's URDF (or the robot's ``controller_model``) after :func:`scaled_urdf_text` multiplied

* every link's ``<mass>`` by ``mass_scale``,
* every link's ``<inertia>`` (rotational inertia about the centre of mass) and every
  ``drake:rotor_inertia`` (whose reflected ``N² J_m`` dominates H) by ``inertia_scale``,
* every joint's ``<dynamics damping>`` (D of (1)) by ``damping_scale``.

The scaled text goes through a temporary file that is deleted once parsed. The simulated arm
is the truth and is not scaled; it may carry a payload (:func:`add_payload`) that the
controller does not know.
"""

from __future__ import annotations

import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RigidBody, SpatialInertia, UnitInertia

from drake_coop.control.arm_model import ArmModel
from drake_coop.plant.arms import arm_model
from drake_coop.plant.arms import Arm
from drake_coop.scenario.schema import ModelError

DRAKE_NS = "http://drake.mit.edu"
#: Radius of the payload's inertia (a small solid sphere around its centre), m.
PAYLOAD_RADIUS = 0.02


def _scale(element: ET.Element, attribute: str, factor: float) -> None:
    element.set(attribute, repr(float(element.get(attribute)) * factor))


def scaled_urdf_text(text: str, error: ModelError) -> str:
    """The URDF ``text`` with masses, inertias (links, rotors) and damping scaled.

    Parameters
    ----------
    text : str
        A URDF document.
    error : ModelError
        ``mass_scale``, ``inertia_scale``, ``damping_scale`` (the other fields are the
        simulated arm's and are ignored here).
    """
    ET.register_namespace("drake", DRAKE_NS)
    root = ET.fromstring(text)
    for inertial in root.iter("inertial"):
        for mass in inertial.iter("mass"):
            _scale(mass, "value", error.mass_scale)
        for inertia in inertial.iter("inertia"):
            for name in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
                if inertia.get(name) is not None:
                    _scale(inertia, name, error.inertia_scale)
    for rotor in root.iter(f"{{{DRAKE_NS}}}rotor_inertia"):
        _scale(rotor, "value", error.inertia_scale)
    for dynamics in root.iter("dynamics"):
        if dynamics.get("damping") is not None:
            _scale(dynamics, "damping", error.damping_scale)
    return ET.tostring(root, encoding="unicode")


def has_scaling(error: ModelError) -> bool:
    """Whether any of the controller-model scales differs from 1.

    Parameters
    ----------
    error : ModelError
        The scenario's model error.

    Returns
    -------
    bool
        True if a scale differs from 1.
    """
    return any(s != 1.0 for s in (error.mass_scale, error.inertia_scale, error.damping_scale))


def controller_arm_model(arm: Arm, error: ModelError | None = None) -> ArmModel:
    """The controller's model of ``arm``: its controller URDF with ``error``'s scales.

    Without scaling (all scales 1) this is ``arm_model(arm)`` itself, parsed from the file.

    Parameters
    ----------
    arm : Arm
        The robot.
    error : ModelError or None
        The scales of the controller's model; None for none.
    """
    if error is None or not has_scaling(error):
        return arm_model(arm)
    text = scaled_urdf_text(Path(arm.controller_urdf_path).read_text(), error)
    with tempfile.TemporaryDirectory(prefix="drake_coop_model_") as folder:
        path = Path(folder) / f"{arm.name}_controller_model.urdf"
        path.write_text(text)
        return arm_model(arm, path)


def add_payload(plant: MultibodyPlant, instance, mass: float,
                sensor_joint: str = "flange_sensor_weld") -> RigidBody | None:
    """Weld an unmodelled payload of ``mass`` kg to the tool flange of one simulated arm.

    The payload's centre is the origin of the force-sensor body (the flange: the child frame
    of ``sensor_joint``), fixed to the last link (its parent): it sits on the arm's side of the
    wrist sensor, so the ground-truth force (the reaction of ``sensor_joint``) does not weigh
    it. Nothing is added for ``mass == 0``. Call before ``plant.Finalize()``.

    Parameters
    ----------
    plant : MultibodyPlant
        The plant (not finalized).
    instance : ModelInstanceIndex
        The arm's model instance.
    mass : float
        The payload's mass, kg.
    sensor_joint : str
        The force sensor's weld joint.

    Returns
    -------
    RigidBody or None
        The payload's body, or None for ``mass == 0``.
    """
    if mass <= 0.0:
        return None
    weld = plant.GetJointByName(sensor_joint, instance)
    X_link_flange = weld.frame_on_parent().GetFixedPoseInBodyFrame()
    body = plant.AddRigidBody("payload", instance, SpatialInertia(
        mass, np.zeros(3), UnitInertia.SolidSphere(PAYLOAD_RADIUS)))
    plant.WeldFrames(weld.parent_body().body_frame(), body.body_frame(), X_link_flange)
    return body
