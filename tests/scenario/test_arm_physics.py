"""A physically impossible arm is refused before anything is built, in one line naming the
link or joint and the attribute (:func:`drake_coop.scenario.model_check.physical_problem`):
``ScenarioError`` (a ``ValueError``) in the API, exit 2 from ``run`` and ``gains``."""

from __future__ import annotations

import pytest

from drake_coop.scenario.model_check import check_model_file
from drake_coop.scenario.schema import ScenarioError


def arm_urdf(masses=(1.0, 1.0, 1.0), inertia=(0.01, 0.01, 0.01), limits=(-3.0, 3.0),
             effort="50", transmissions=True, sensor_mass=0.2, sensor_inertia=1e-4) -> str:
    """A three-joint arm (z, y, y), a fixed wrist sensor joint and a pad."""
    links, joints, trans = [], [], []
    ixx, iyy, izz = inertia
    for i, m in enumerate(masses, 1):
        links.append(f"""<link name="l{i}"><inertial><origin xyz="0 0 0.1"/>
          <mass value="{m}"/><inertia ixx="{ixx}" iyy="{iyy}" izz="{izz}" ixy="0" ixz="0"
          iyz="0"/></inertial></link>""")
        parent = "base_link" if i == 1 else f"l{i - 1}"
        axis = "0 0 1" if i == 1 else "0 1 0"
        joints.append(f"""<joint name="j{i}" type="revolute"><parent link="{parent}"/>
          <child link="l{i}"/><origin xyz="0 0 {0.1 if i == 1 else 0.3}"/><axis xyz="{axis}"/>
          <limit lower="{limits[0]}" upper="{limits[1]}" effort="{effort}" velocity="2"/>
          </joint>""")
        trans.append(f"""<transmission name="t{i}"><type>transmission_interface/SimpleTransmission</type>
          <joint name="j{i}"/><actuator name="a{i}"/></transmission>""")
    return f"""<?xml version="1.0"?><robot name="arm"><link name="base_link"/>
      {''.join(links)}<link name="sensor"><inertial><mass value="{sensor_mass}"/>
      <inertia ixx="{sensor_inertia}" iyy="{sensor_inertia}" izz="{sensor_inertia}" ixy="0"
      ixz="0" iyz="0"/></inertial></link>
      <link name="pad"/>{''.join(joints)}
      <joint name="flange_sensor_weld" type="fixed"><parent link="l3"/><child link="sensor"/>
        <origin xyz="0 0 0.3"/></joint>
      <joint name="sensor_pad" type="fixed"><parent link="sensor"/><child link="pad"/>
        <origin xyz="0 0 0.05"/></joint>
      {''.join(trans) if transmissions else ''}</robot>"""


def _refusal(tmp_path, **kwargs) -> str:
    path = tmp_path / "arm.urdf"
    path.write_text(arm_urdf(**kwargs))
    with pytest.raises(ValueError) as err:
        check_model_file(path, "robots[0].model")
    assert isinstance(err.value, ScenarioError)
    text = str(err.value)
    assert "\n" not in text and text.startswith(f"robots[0].model: {path} ")
    return text


def test_a_possible_arm_loads(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(arm_urdf())
    assert check_model_file(path, "robots[0].model") == 3


@pytest.mark.parametrize("kwargs, expected", [
    (dict(masses=(1.0, -1.0, 1.0)), "link 'l2' has mass -1.0 (<inertial><mass value>)"),
    (dict(masses=(0.0, 0.0, 0.0), sensor_mass=0.0), "link 'l1' has mass 0 (<inertial><mass "
                                                     "value>) and a nonzero <inertia>"),
    (dict(masses=(0.0, 0.0, 0.0), inertia=(0, 0, 0), sensor_mass=0.0, sensor_inertia=0),
     "joint 'j1' moves no mass"),
    (dict(inertia=(0.01, 0.01, 0.05)), "link 'l1' has an <inertia> no body has"),
    (dict(inertia=(0.01, -0.01, 0.01)), "is not positive semi-definite"),
    (dict(effort="0"), "joint 'j1' has <limit effort='0'>: an arm's joint needs an actuator"),
    (dict(limits=(1.0, -1.0)), "joint 'j1' has <limit lower='1.0' upper='-1.0'>: lower must "
                               "be <= upper"),
    (dict(transmissions=False), "joint 'j1' has no actuator"),
])
def test_an_impossible_arm_is_refused_in_one_line_naming_the_part(tmp_path, kwargs, expected):
    assert expected in _refusal(tmp_path, **kwargs)


def test_the_triangle_inequality_is_the_bound(tmp_path):
    """A thin rod's moments (a, a, ~0) are on the bound: accepted; just past it: refused."""
    path = tmp_path / "arm.urdf"
    path.write_text(arm_urdf(inertia=(0.01, 0.01, 0.02)))       # a + b = c: a flat disc
    assert check_model_file(path, "robots[0].model") == 3
    assert "break the triangle inequality" in _refusal(tmp_path, inertia=(0.01, 0.01, 0.0201))


@pytest.mark.parametrize("command", ["run", "gains", "identify"])
def test_commands_that_load_the_arm_exit_2(tmp_path, capsys, command):
    from drake_coop.cli import main

    (tmp_path / "arm.urdf").write_text(arm_urdf(masses=(1.0, -1.0, 1.0)))
    scenario = tmp_path / "s.yaml"
    scenario.write_text("robots:\n- {name: robot1, model: arm.urdf, base_frame: base_link}\n"
                        "- {name: robot2, model: arm.urdf, base_frame: base_link, "
                        "normals: [[1, 0, 0]], contact_xy: [0.7, 0.0], base_xyz: [1.2, 0, 0],"
                        " base_yaw_deg: 180}\n")
    code = main([command, str(scenario), "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "robots[0].model" in err[0] and "link 'l2' has mass -1.0" in err[0]
