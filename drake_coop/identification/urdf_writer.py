"""The identified model as a URDF: the nominal file with the identified dynamics written in.

Kinematics, geometry, joint limits and gear ratios stay those of the nominal URDF (they are
not identified). For every moving composite body the link's ``<inertial>`` gets the
identified mass, centre of mass ``c = h / m`` and rotational inertia about the centre of mass
(``I_c = I_o − m (|c|² 1 − c cᵀ)``); the other members of the composite (force sensor, pad:
their inertia is part of the identified composite) get zero mass. Each transmission's
``drake:rotor_inertia`` becomes ``I_a / N²`` with the file's gear ratio ``N``, each joint's
``<dynamics damping>`` the identified viscous friction. The identified Coulomb friction is
not a URDF property of Drake: it is recorded in a comment (and in ``identify.json``).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from drake_coop.identification.regressor import ArmStructure
from drake_coop.plant.model_error import DRAKE_NS
from drake_coop.scenario.description import IDENTIFIED_MARK


def central_inertia(theta_b: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Mass, centre of mass and rotational inertia about it (3×3) of ten parameters.

    Parameters
    ----------
    theta_b : numpy.ndarray
        ``[m, h, I_Bo]`` (10,).

    Returns
    -------
    m : float
        The mass, kg.
    c : numpy.ndarray
        The centre of mass (3,), m.
    I_c : numpy.ndarray
        The inertia about it (3, 3), kg·m².
    """
    m, hx, hy, hz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz = (float(x) for x in theta_b)
    c = np.array([hx, hy, hz]) / m
    I_o = np.array([[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]])
    return m, c, I_o - m * (c @ c * np.eye(3) - np.outer(c, c))


def _set_inertial(link: ET.Element, m: float, c: np.ndarray, I: np.ndarray) -> None:
    for old in link.findall("inertial"):
        link.remove(old)
    inertial = ET.Element("inertial")
    ET.SubElement(inertial, "origin", xyz=" ".join(repr(float(x)) for x in c))
    ET.SubElement(inertial, "mass", value=repr(float(m)))
    ET.SubElement(inertial, "inertia", **{
        k: repr(float(v)) for k, v in zip(("ixx", "iyy", "izz", "ixy", "ixz", "iyz"),
                                          (I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]))})
    link.insert(0, inertial)


def identified_urdf_text(nominal_text: str, structure: ArmStructure, theta: np.ndarray,
                         note: str = "") -> str:
    """The nominal URDF text with the identified parameters ``theta`` (module docstring).

    Parameters
    ----------
    nominal_text : str
        The nominal URDF.
    structure : ArmStructure
        The parameter layout.
    theta : numpy.ndarray
        The identified parameters (p,).
    note : str
        A comment written into the file.
    """
    ET.register_namespace("drake", DRAKE_NS)
    root = ET.fromstring(nominal_text)
    links = {link.get("name"): link for link in root.iter("link")}
    for i, name in enumerate(structure.links):
        m, c, I = central_inertia(theta[10 * i: 10 * i + 10])
        _set_inertial(links[name], m, c, I)
        for member in structure.members[name][1:]:
            if member in links:
                _set_inertial(links[member], 0.0, np.zeros(3), np.zeros((3, 3)))
    rotor = theta[structure.joint_slice("rotor_inertia")]
    viscous = theta[structure.joint_slice("viscous")]
    coulomb = theta[structure.joint_slice("coulomb")]
    for joint in root.iter("joint"):
        name = joint.get("name")
        if name in structure.joints:
            k = structure.joints.index(name)
            dynamics = joint.find("dynamics")
            if dynamics is None:
                dynamics = ET.SubElement(joint, "dynamics")
            dynamics.set("damping", repr(float(viscous[k])))
    for transmission in root.iter("transmission"):
        joint = transmission.find("joint")
        if joint is None or joint.get("name") not in structure.joints:
            continue
        k = structure.joints.index(joint.get("name"))
        for actuator in transmission.iter("actuator"):
            for r in actuator.iter(f"{{{DRAKE_NS}}}rotor_inertia"):
                r.set("value", repr(float(rotor[k] / structure.gear_ratios[k] ** 2)))
    comment = ET.Comment(
        f" {IDENTIFIED_MARK} " + note + " Coulomb friction (N·m): "
        + ", ".join(f"{j} {f:.4g}" for j, f in zip(structure.joints, coulomb)) + " ")
    root.insert(0, comment)
    return ET.tostring(root, encoding="unicode")
