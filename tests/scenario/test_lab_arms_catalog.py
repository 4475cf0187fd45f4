"""Every serial arm of example-robot-data loads as a run loads it (drake_coop.scenario.lab_arms,
``drake-coop arms``): the prepared URDF parses into a plant with a SceneGraph attached (where
Drake checks visual materials), the joints and effort limits Drake reads are the source URDF's
(read here with ElementTree, independently), and Kinova Jaco2's conflicting material
definitions are renamed. Skipped without example-robot-data (the ``robots`` extra)."""

import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

from drake_coop.control.arm_plant import description_packages
from drake_coop.scenario.lab_arms import LAB_ARMS, arm_facts, lab_arm_robot
from drake_coop.scenario.model_check import check_model_file
from drake_coop.scenario.resources import model_urdf_path, resolve_package_url

pytestmark = pytest.mark.skipif(
    "example-robot-data" not in description_packages(),
    reason='example-robot-data is not installed (pip install -e ".[robots]")')

#: Joints each arm moves once its gripper is locked (counted from the arms' data sheets).
EXPECTED_JOINTS = {"panda": 7, "ur3": 6, "ur5": 6, "ur10": 6, "xarm7": 7, "jaco2": 6,
                   "z1": 6, "so100": 5, "so101": 5}


def test_every_listed_arm_has_an_expected_joint_count():
    assert set(LAB_ARMS) == set(EXPECTED_JOINTS)


@pytest.mark.parametrize("name", sorted(LAB_ARMS))
def test_prepared_urdf_loads_with_a_scene_graph(name):
    robot = lab_arm_robot(name)
    n = check_model_file(model_urdf_path(robot), "robots[0].model", robot)
    facts = arm_facts(name)
    assert n == len(facts.joints) == EXPECTED_JOINTS[name]
    # The effort limits Drake reads are the source URDF's <limit effort> of the same joints.
    source = ET.parse(resolve_package_url(robot.model)).getroot()
    effort = {j.get("name"): float(j.find("limit").get("effort"))
              for j in source.findall("joint") if j.find("limit") is not None}
    assert facts.effort_limits == [effort[j] for j in facts.joints]
    assert all(lo < hi for lo, hi in zip(facts.lower, facts.upper))


def test_jaco2_conflicting_materials_are_renamed():
    robot = lab_arm_robot("jaco2")
    source = ET.parse(resolve_package_url(robot.model)).getroot()

    def definitions(root):
        out = {}
        for m in root.iter("material"):
            if m.find("color") is not None:
                out.setdefault(m.get("name"), set()).add(m.find("color").get("rgba"))
        return out

    # The package's file defines carbon_fiber with two colours (what Drake refuses) ...
    assert len(definitions(source)["carbon_fiber"]) == 2
    # ... the prepared one gives each name one colour, and keeps both colours.
    prepared = definitions(ET.parse(model_urdf_path(robot)).getroot())
    assert all(len(colours) == 1 for colours in prepared.values())
    assert set().union(*prepared.values()) >= definitions(source)["carbon_fiber"]


def test_gear_reductions_are_read_where_drake_ignores_them():
    assert arm_facts("xarm7").reductions == [100.0] * 7
    assert arm_facts("jaco2").reductions == [160.0] * 6
    assert arm_facts("panda").reductions == [None] * 7


def _cli(*args):
    return subprocess.run([sys.executable, "-m", "drake_coop", *args], capture_output=True,
                          text=True, timeout=300)


def test_arms_command_lists_every_arm_and_prints_a_robot_entry():
    done = _cli("arms")
    assert done.returncode == 0, done.stderr
    rows = [line.split("\t") for line in done.stdout.splitlines()[1:]]
    assert {r[0]: int(r[1]) for r in rows} == EXPECTED_JOINTS
    done = _cli("arms", "--yaml", "jaco2")
    assert done.returncode == 0 and "kinova.urdf" in done.stdout
    done = _cli("arms", "--yaml", "iiwa")
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "--yaml must be one of" in done.stderr

