"""Material definitions Drake's parser refuses once a SceneGraph is attached (a name defined
twice with different colours): the model check loads with a SceneGraph, as a run does, and
names the file in one line; the preparation renames a conflicting redefinition only."""

import xml.etree.ElementTree as ET

import pytest

from drake_coop.scenario.model_check import check_model_file


def _crs_with_materials(tmp_path, first: str, second: str):
    """The shipped CRS A465 with its first two visuals' materials named alike."""
    from drake_coop.scenario.resources import urdf_dir

    text = (urdf_dir() / "crs_a465_3dof.urdf").read_text()
    text = text.replace('<material><color rgba="0.3 0.3 0.3 1"/></material>',
                        f'<material name="paint"><color rgba="{first}"/></material>', 1)
    text = text.replace('<material><color rgba="0.85 0.85 0.85 1"/></material>',
                        f'<material name="paint"><color rgba="{second}"/></material>', 1)
    path = tmp_path / "crs_paint.urdf"
    path.write_text(text)
    return path


def test_the_model_check_sees_what_a_scene_graph_refuses(tmp_path):
    from drake_coop.scenario.schema import Robot, ScenarioError

    robot = Robot(model="crs_a465")
    same = _crs_with_materials(tmp_path, "0.3 0.3 0.3 1", "0.3 0.3 0.3 1")
    assert check_model_file(same, "robots[0].model", robot) == 3      # one definition: fine
    clash = _crs_with_materials(tmp_path, "0.3 0.3 0.3 1", "0.85 0.85 0.85 1")
    # (Drake's message, cut to one line, names the material after the file's path.)
    with pytest.raises(ScenarioError, match=r"^robots\[0\]\.model: .* is not a model Drake "
                                            r"can load: "):
        check_model_file(clash, "robots[0].model", robot)


def test_preparing_renames_only_a_conflicting_material(tmp_path, monkeypatch):
    from drake_coop.scenario.description import prepared_urdf
    from drake_coop.scenario.schema import Robot

    monkeypatch.setenv("DRAKE_COOP_CACHE_DIR", str(tmp_path / "cache"))
    clash = _crs_with_materials(tmp_path, "0.3 0.3 0.3 1", "0.85 0.85 0.85 1")
    robot = Robot(model=str(clash), locked_joints={})
    out = prepared_urdf(robot, clash)
    names = [m.get("name") for m in ET.parse(out).getroot().iter("material")
             if m.find("color") is not None]
    assert names.count("paint") == 1 and names.count("paint__2") == 1
    assert check_model_file(out, "robots[0].model", Robot(model="crs_a465")) == 3
