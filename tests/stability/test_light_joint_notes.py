"""``drake-coop gains`` says why a joint's derived gain is far below the arm's others: the
least inertia the joint sees, and a model without rotor inertia (a URDF whose gear reduction
Drake ignores). The reduction is read here from the source URDF with ElementTree."""

import xml.etree.ElementTree as ET
from types import SimpleNamespace

import pytest

from drake_coop.control.arm_plant import description_packages
from drake_coop.scenario.schema import Scenario
from drake_coop.stability.gains_cli import light_joint_notes


def _report(robot_name, K_R, inertia):
    return SimpleNamespace(robots=[SimpleNamespace(name=robot_name,
                                                   gains=SimpleNamespace(K_R=K_R),
                                                   inertia=inertia)])


def test_the_paper_arms_gains_need_no_note():
    from drake_coop.scenario.loading import default_scenario

    sc = default_scenario()
    assert light_joint_notes(sc, _report("robot1", sc.robots[0].gains.K_R, [1.0] * 3)) == []


@pytest.mark.skipif("example-robot-data" not in description_packages(),
                    reason='example-robot-data is not installed (pip install -e ".[robots]")')
def test_a_light_wrist_of_a_geared_arm_is_explained_with_its_ignored_reduction():
    from drake_coop.scenario.lab_arms import lab_arm_robot
    from drake_coop.scenario.resources import resolve_package_url

    robot = lab_arm_robot("jaco2")
    K_R = [1.5, 16.5, 8.4, 0.14, 0.88, 0.063]
    notes = light_joint_notes(Scenario(robots=[robot]),
                              _report("jaco2_1", K_R, [0.013, 0.15, 0.076, 0.00127, 0.0079,
                                                       0.000564]))
    assert len(notes) == 2                        # joints 4 and 6: below 5 % of 16.5
    source = ET.parse(resolve_package_url(robot.model)).getroot()
    reduction = {j.get("name"): t.findtext(".//mechanicalReduction").strip()
                 for t in source.findall("transmission") for j in t.findall("joint")
                 if t.findtext(".//mechanicalReduction") is not None}
    joint = "j2s6s200_joint_6"
    assert notes[1].startswith(f"jaco2_1: K_R[6] ({joint}) = 0.063 N·m·s/rad = κ J/h with "
                               "J = 0.000564 kg·m²")
    assert (f"no rotor inertia for it (its URDF's mechanicalReduction {reduction[joint]} is "
            "ignored by Drake") in notes[1]
    assert "\n" not in notes[1]
