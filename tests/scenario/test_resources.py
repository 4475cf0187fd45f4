"""Where the models and shipped scenarios are found, and the errors when a model is missing.

The slow end-to-end install (wheel, fresh virtual environment, browser) is in
``test_install.py``; these tests run against the checkout.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from drake_coop.cli import main
from drake_coop.plant.arms import urdf_dir
from drake_coop.scenario import (
    ScenarioError,
    default_scenario,
    dump_scenario,
    load_scenario,
    resources,
)

REPO = Path(__file__).resolve().parents[2]


def test_checkout_reads_the_top_level_folders(monkeypatch):
    monkeypatch.delenv("DRAKE_COOP_URDF_DIR", raising=False)
    assert urdf_dir() == REPO / "urdf"
    assert resources.scenarios_dir() == REPO / "scenarios"
    assert resources.default_scenario_path() == REPO / "scenarios" / "paper.yaml"


def test_environment_variable_still_overrides_the_models(tmp_path, monkeypatch):
    monkeypatch.setenv("DRAKE_COOP_URDF_DIR", str(tmp_path))
    assert urdf_dir() == tmp_path


def test_installed_package_data_wins_over_the_checkout(tmp_path, monkeypatch):
    # A wheel's layout: <site>/drake_coop/data/urdf next to the modules.
    site = tmp_path / "site"
    shutil.copytree(REPO / "drake_coop", site / "drake_coop",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copytree(REPO / "urdf", site / "drake_coop" / "data" / "urdf")
    shutil.copytree(REPO / "scenarios", site / "drake_coop" / "data" / "scenarios")
    code = ("import drake_coop.scenario.resources as r; print(r.__file__); print(r.urdf_dir()); "
            "print(r.scenarios_dir())")
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, check=True, text=True,
                         capture_output=True, env={"PYTHONPATH": str(site), "PATH": ""}).stdout
    module, urdf, scenarios = out.split()
    assert module == str(site / "drake_coop" / "scenario" / "resources.py")
    assert urdf == str(site / "drake_coop" / "data" / "urdf")
    assert scenarios == str(site / "drake_coop" / "data" / "scenarios")


def test_default_scenario_is_the_shipped_paper_yaml():
    assert load_scenario() == default_scenario()
    assert load_scenario() == load_scenario(REPO / "scenarios" / "paper.yaml")


def test_shipped_scenarios_are_every_yaml_with_its_first_sentence():
    shipped = resources.shipped_scenarios()
    assert sorted(shipped) == sorted(p.stem for p in (REPO / "scenarios").glob("*.yaml"))
    assert resources.scenario_summary(shipped["rigid"]) == (
        "The paper's experiment with one rigid 0.5 kg object ball-constrained to both end "
        "effectors: the two arms carry it together and feel each other through it.")


def test_find_scenario_by_name_or_path(tmp_path, monkeypatch):
    assert resources.find_scenario("paper") == REPO / "scenarios" / "paper.yaml"
    assert resources.find_scenario("rigid.yaml") == REPO / "scenarios" / "rigid.yaml"
    mine = tmp_path / "paper.yaml"            # a local file of the same name wins
    mine.write_text("control_period: 0.009\n")
    monkeypatch.chdir(tmp_path)
    assert resources.find_scenario("paper.yaml") == Path("paper.yaml")
    with pytest.raises(ScenarioError, match="not found: nope.*shipped scenarios: contact"):
        resources.find_scenario("nope")
    with pytest.raises(ScenarioError, match="not found"):
        resources.find_scenario("some/dir/paper")   # a path is never a shipped name


def test_cli_lists_and_prints_shipped_scenarios(capsys):
    assert main(["scenarios"]) == 0
    listing = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in listing] == sorted(resources.shipped_scenarios())
    assert any(line.startswith("paper ") and "Section IV" in line for line in listing)
    assert main(["scenarios", "rigid"]) == 0
    assert capsys.readouterr().out == (REPO / "scenarios" / "rigid.yaml").read_text()
    assert main(["scenarios", "glue"]) == 2
    err = capsys.readouterr().err
    assert "unknown scenario 'glue'" in err and err.count("\n") == 1


def _scenario_with_controller_model(tmp_path: Path, value: str) -> Path:
    s = default_scenario()
    s.robots[1].controller_model = value
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(s))
    return path


@pytest.mark.parametrize("content, message", [
    (None, "robots[1].controller_model: {urdf_dir}/arm.urdf not found"),
    ("<robot", "robots[1].controller_model: {path} is not valid XML"),
    ('<robot name="x"><link name="a"/></robot>',
     "robots[1].controller_model: {path} has no link named 'base_link'"),
])
def test_bad_controller_model_exits_2_with_one_line(tmp_path, capsys, content, message):
    path = _scenario_with_controller_model(tmp_path, "arm.urdf")
    if content is not None:
        (tmp_path / "arm.urdf").write_text(content)
    code = main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert message.format(path=tmp_path.resolve() / "arm.urdf", urdf_dir=urdf_dir()) in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_missing_arm_model_exits_2_naming_field_and_path(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("DRAKE_COOP_URDF_DIR", str(tmp_path))
    code = main(["run", "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert f"robots[0].model: {tmp_path / 'crs_a465_3dof.urdf'} not found" in err
    assert err.count("\n") == 1


def test_controller_model_beside_the_scenario_is_made_absolute(tmp_path):
    shutil.copy(REPO / "urdf" / "crs_a255_3dof.urdf", tmp_path / "my_a255.urdf")
    s = load_scenario(_scenario_with_controller_model(tmp_path, "my_a255.urdf"))
    assert s.robots[1].controller_model == str(tmp_path / "my_a255.urdf")
    # A shipped model named relatively stays relative (the saved scenario stays portable).
    other = tmp_path / "other"
    other.mkdir()
    s = load_scenario(_scenario_with_controller_model(other, "crs_a255_3dof.urdf"))
    assert s.robots[1].controller_model == "crs_a255_3dof.urdf"
