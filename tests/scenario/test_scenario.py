"""Scenario loading and validation: the paper's numbers, and one clear error per bad input."""

import math
from pathlib import Path

import pytest

from drake_coop.scenario import (
    ScenarioError,
    aligned_periods,
    default_scenario,
    dump_scenario,
    load_scenario,
)

PAPER = Path(__file__).resolve().parents[2] / "scenarios" / "paper.yaml"


def test_paper_yaml_holds_the_papers_numbers():
    s = load_scenario(PAPER)
    assert s == default_scenario()
    assert s.control_period == 0.009
    r1, r2 = s.robots
    assert (r1.gains.Lambda, r2.gains.Lambda) == (35.0, 26.0)
    assert r1.gains.K_R == [120.0] * 3 and r2.gains.K_R == [100.0] * 3
    for r in (r1, r2):
        assert (r.gains.k_d, r.gains.k_F, r.gains.xi, r.gains.zeta) == (40.0, 0.05, 1e-5, 1e-3)
    assert (r1.contact_xy, r2.contact_xy) == ([0.6, 0.0], [0.8192, 0.0])
    t = s.task
    assert (t.t_grasp, t.t_circle_start, t.t_circle_end, t.t_release, t.t_end) == (
        15.0, 25.0, 65.0, 75.0, 90.0)
    assert t.force_omega == pytest.approx(3 * math.pi / 40)
    assert (t.force_mean, t.force_amplitude, t.circle_radius, t.circle_top_z) == (
        32.0, 18.0, 0.05, 0.635)


def test_dump_and_load_round_trip():
    s = default_scenario()
    assert load_scenario(data=dump_scenario(s)) == s


@pytest.mark.parametrize("text, field", [
    ("control_period: -1", "control_period must be a finite number in [0.0001, 0.1] s"),
    ("control_period: .nan", "control_period must be a finite number in [0.0001, 0.1] s, got nan"),
    ("plant: {time_step: 0.002}", "integer multiple of plant.time_step"),
    ("plant: {time_step: 0.018}", "plant.time_step (0.018) must not exceed control_period"),
    ("plant: {object_mode: glue}", "plant.object_mode must be one of planes, rigid, contact"),
    ("plant: {object_mass: -0.5}", "plant.object_mass must be a finite number in (0, 20] kg"),
    ("colour: red", "colour is not a known field of scenario"),
    ("plant: {stepsize: 1}", "plant.stepsize is not a known field of plant"),
    ("task: {t_grasp: soon}", "task.t_grasp must be a number"),
    ("task: {t_grasp: 30}", "task.t_circle_start must be > task.t_grasp"),
    ("robots: [{name: a, gains: {K_R: [1, 2]}}, {name: b, normals: [[1, 0, 0]]}]",
     "robots[0].gains.K_R must have 3 entries"),
    ("robots: [{gains: {beta: 0}}, {name: b, normals: [[1, 0, 0]]}]", "robots[0].gains.beta must be a finite number in (0, 1000] 1/s"),
    ("robots: [{gains: {K_R: [1, -1, 1]}}, {name: b, normals: [[1, 0, 0]]}]",
     "robots[0].gains.K_R[1] must be a finite number in (0, 10000]"),
    ("robots: [{}]", "robots must list 2 to 8 robots"),
    ("task: {circle_radius: 0.5}", "out of reach"),
    ("robots: [{home: [2.0, 0, 0.5]}, {name: b, model: crs_a255, base_xyz: [1.16, 0, 0], "
     "base_yaw_deg: 180, contact_xy: [0.8192, 0], normals: [[1, 0, 0]], home: [0.9, 0, 0.6]}]",
     "robots[0] (robot1): target"),
    ("task: {force_amplitude: 40}", "task.force_amplitude (40.0) must not exceed"),
    ("{{{", "invalid YAML"),
])
def test_bad_input_names_the_field_and_the_allowed_range(text, field):
    with pytest.raises(ScenarioError) as info:
        load_scenario(data=text)
    message = str(info.value)
    assert field in message, message
    assert "\n" not in message


def test_missing_file_is_a_scenario_error(tmp_path):
    with pytest.raises(ScenarioError, match="not found"):
        load_scenario(tmp_path / "nope.yaml")


@pytest.mark.parametrize("h, dt", [(0.009, 0.001), (0.009, 0.003), (0.009, 0.0045),
                                   (0.009, 0.009), (0.001, 0.001), (0.009, 0.0001)])
def test_aligned_periods_make_every_tick_a_plant_step(h, dt):
    H, D = aligned_periods(h, dt)
    N = round(H / D)
    assert H == N * D
    assert abs(H - h) < 1e-14 and abs(D - dt) < 1e-14
    # Drake schedules events at k * period: every control tick coincides with a plant step.
    assert all(k * H == (N * k) * D for k in range(0, 100001))


#: Shipped scenarios of arms from example-robot-data (the ``robots`` extra): loaded only when it
#: is installed, and slow (validation integrates two 7-joint references over 90 s).
LAB_ARMS = ("two_pandas.yaml", "two_ur5.yaml")


def _shipped(path):
    if path.name not in LAB_ARMS:
        return path
    from drake_coop.control.arm_plant import description_packages

    return pytest.param(path, marks=[pytest.mark.slow, pytest.mark.skipif(
        "example-robot-data" not in description_packages(),
        reason='example-robot-data is not installed (pip install -e ".[robots]")')])


@pytest.mark.parametrize("path", [_shipped(p) for p in sorted(PAPER.parent.glob("*.yaml"))],
                         ids=lambda p: p.name)
def test_every_shipped_scenario_loads(path):
    s = load_scenario(path)
    assert len(s.robots) >= 2
    if path.name not in ("three_arms.yaml", "three_arms_contact.yaml",
                         "six_joint.yaml") + LAB_ARMS:                    # the paper's arms
        assert len(s.robots) == 2 and s.robots[0].gains.K_R == [120.0] * 3


def test_dataclass_defaults_are_paper_yaml_robot_1_and_task():
    """paper.yaml is the source of the paper's numbers; a field a scenario file leaves out
    takes the dataclass default, which must be the paper's robot 1 / task / plant value."""
    import dataclasses

    from drake_coop.scenario import Robot, Task
    from drake_coop.scenario.schema import Guards, PlantSettings

    paper = load_scenario()
    assert dataclasses.asdict(Robot(name="robot1")) == dataclasses.asdict(paper.robots[0])
    assert dataclasses.asdict(Task()) == dataclasses.asdict(paper.task)
    assert dataclasses.asdict(PlantSettings()) == dataclasses.asdict(paper.plant)
    assert dataclasses.asdict(Guards()) == dataclasses.asdict(paper.guards)


# --------------------------------------------------------------------- package:// model paths
def _urdf_package(folder: Path, name: str = "my_arms") -> Path:
    """A ROS-style package (``package.xml``) holding a copy of the A465 model."""
    root = folder / name
    (root / "urdf").mkdir(parents=True)
    (root / "package.xml").write_text(
        f'<?xml version="1.0"?><package format="2"><name>{name}</name><version>0.0.0</version>'
        '<description>test</description><maintainer email="a@b.c">a</maintainer>'
        '<license>BSD</license></package>')
    source = PAPER.parents[1] / "urdf" / "crs_a465_3dof.urdf"
    (root / "urdf" / "a465.urdf").write_text(source.read_text())
    return root


def test_a_package_url_is_resolved_through_ros_package_path(tmp_path, monkeypatch):
    _urdf_package(tmp_path)
    monkeypatch.setenv("ROS_PACKAGE_PATH", str(tmp_path))
    s = load_scenario(data=PAPER.read_text().replace(
        "model: crs_a465", "model: package://my_arms/urdf/a465.urdf", 1))
    from drake_coop.scenario.resources import model_urdf_path
    assert model_urdf_path(s.robots[0]) == (tmp_path / "my_arms" / "urdf" / "a465.urdf").resolve()


def test_an_unknown_package_is_named_with_the_field_not_mangled_into_a_path():
    with pytest.raises(ScenarioError) as info:
        load_scenario(data=PAPER.read_text().replace(
            "model: crs_a255\n  controller_model: ''",
            "model: crs_a255\n  controller_model: package://nope/arm.urdf", 1))
    message = str(info.value)
    assert message.startswith("robots[1].controller_model: package://nope/arm.urdf: unknown "
                              "package 'nope' (Drake knows "), message
    assert "package:/nope" not in message and "\n" not in message
