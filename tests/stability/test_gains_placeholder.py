"""``drake-coop gains`` derives K_R, so it accepts a scenario without gains or with a placeholder
K_R of the wrong length (``run`` refuses both); the derived gains it writes are sized by the
arm's joints (read from the model with Drake, independently of the sizing rule)."""

import re

import pytest
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from drake_coop.cli import main
from drake_coop.control.arm_plant import description_packages
from drake_coop.scenario import ScenarioError, load_scenario
from drake_coop.scenario.resources import find_scenario, model_urdf_path
from drake_coop.stability import gains as rules
from drake_coop.stability.gains_cli import load_for_gains

pytestmark = pytest.mark.skipif(
    "example-robot-data" not in description_packages(),
    reason='example-robot-data is not installed (pip install -e ".[robots]")')


def _ur5_text(gains_line: str) -> str:
    """two_ur5.yaml with every robot's ``gains: {...}`` mapping replaced (or removed)."""
    text = find_scenario("two_ur5").read_text()
    new, count = re.subn(r"\n  gains: \{[^}]*\}", "\n  " + gains_line if gains_line else "",
                         text)
    assert count == 2
    return new


def _joints(robot) -> int:
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(str(model_urdf_path(robot)))
    plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(robot.base_frame))
    plant.Finalize()
    return plant.num_positions()


@pytest.mark.parametrize("gains_line", ["", "gains: {K_R: [1.0, 2.0]}"])
def test_gains_accepts_missing_or_wrong_length_K_R(tmp_path, monkeypatch, gains_line):
    text = _ur5_text(gains_line)
    assert ("K_R: [81.14" in text) is False           # the shipped gains are gone
    path = tmp_path / "ur5_no_gains.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError, match=r"gains\.K_R must have 6 entries") as err:
        load_scenario(path)                            # a run refuses it ...
    assert ("run `drake-coop gains SCENARIO --out DIR`" in str(err.value)) == (gains_line == "")
    scenario = load_for_gains(path)                    # ... the gains command takes it
    assert [len(r.gains.K_R) for r in scenario.robots] == [_joints(r) for r in scenario.robots]

    def quick(s, **k):
        report = rules.GainsReport(robots=rules.derive_gains(s))
        report.rho, report.stable = {"free": 0.5, "held": 0.5, "free_margin": 0.5,
                                     "held_margin": 0.5}, True
        return report

    monkeypatch.setattr(rules, "derive_and_check", quick)
    from drake_coop.stability import gains_cli    # the margin: tests/stability/test_margin.py

    monkeypatch.setattr(gains_cli, "gains_margins", lambda scenario, report: {"line": "m"})
    out = tmp_path / "out"
    assert main(["gains", str(path), "--out", str(out), "--quiet"]) == 0
    written = load_scenario(out / "scenario.yaml")     # a run takes the written scenario
    assert [len(r.gains.K_R) for r in written.robots] == [6, 6]
    assert all(k > 0 for r in written.robots for k in r.gains.K_R)


def test_gains_still_refuses_other_bad_fields(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(_ur5_text("gains: {K_R: [1.0], Lambda: -3.0}"))
    with pytest.raises(ScenarioError, match="Lambda"):
        load_for_gains(path)
