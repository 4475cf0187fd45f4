"""A seven-joint arm of our own for the benchmark and the tests of the general path (n = 7).

Joints z, y, z, y, z, y, z like a KUKA iiwa (0.2 m between joints, 0.08 m to the flange),
cylinder links with masses from 4 to 0.5 kg, joint damping, a pad frame 0.05 m beyond the
flange. It is no
shipped arm: its only use is a redundant chain whose kinematics and dynamics Drake evaluates.
"""

from __future__ import annotations

from pathlib import Path

#: (joint axis, link length to the next joint m, link mass kg, radius m)
LINKS = [("0 0 1", 0.2, 4.0, 0.07), ("0 1 0", 0.2, 4.0, 0.07), ("0 0 1", 0.2, 3.0, 0.06),
         ("0 1 0", 0.2, 2.7, 0.06), ("0 0 1", 0.2, 1.7, 0.05), ("0 1 0", 0.2, 1.8, 0.05),
         ("0 0 1", 0.08, 0.5, 0.04)]


def _inertia(mass: float, radius: float, length: float) -> str:
    length = max(length, 0.05)
    ixx = mass * (3 * radius ** 2 + length ** 2) / 12.0
    izz = mass * radius ** 2 / 2.0
    return (f'<inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{ixx:.6g}" iyz="0" '
            f'izz="{izz:.6g}"/>')


def seven_joint_urdf() -> str:
    """The URDF text: ``base_link``, ``link1``…``link7``, joints ``joint1``…``joint7``,
    a ``pad`` frame."""
    parts = ['<?xml version="1.0"?>', '<robot name="seven_joint">',
             '  <link name="base_link"><inertial><mass value="5"/>'
             '<origin xyz="0 0 0.05"/>' + _inertia(5.0, 0.1, 0.1) + '</inertial></link>']
    parent = "base_link"
    offset = 0.15                                   # base to joint 1
    for k, (axis, length, mass, radius) in enumerate(LINKS, start=1):
        parts.append(f'  <link name="link{k}"><inertial><mass value="{mass}"/>'
                     f'<origin xyz="0 0 {length / 2:.4g}"/>{_inertia(mass, radius, length)}'
                     '</inertial></link>')
        parts.append(f'  <joint name="joint{k}" type="revolute"><parent link="{parent}"/>'
                     f'<child link="link{k}"/><origin xyz="0 0 {offset}"/>'
                     f'<axis xyz="{axis}"/><limit lower="-2.9" upper="2.9" effort="150" '
                     'velocity="2"/><dynamics damping="0.5"/></joint>')
        parent, offset = f"link{k}", length
    parts.append('  <link name="pad"/>')
    parts.append(f'  <joint name="pad_weld" type="fixed"><parent link="{parent}"/>'
                 '<child link="pad"/><origin xyz="0 0 0.13"/></joint>')
    parts.append("</robot>")
    return "\n".join(parts) + "\n"


def write_seven_joint_urdf(folder: str | Path) -> Path:
    """Write :func:`seven_joint_urdf` as ``folder/seven_joint.urdf`` and return its path."""
    path = Path(folder) / "seven_joint.urdf"
    path.write_text(seven_joint_urdf(), encoding="utf-8")
    return path
