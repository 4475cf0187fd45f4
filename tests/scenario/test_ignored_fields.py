"""A field that the chosen mode ignores is refused, naming it: it must not run
as if it had been honoured."""

import pytest

from drake_coop.cli import main
from drake_coop.scenario import ScenarioError, load_scenario

CONTACT = "plant: {object_mode: contact, object_mass: 0.5, friction: 1.0, time_step: 0.003}\n"


@pytest.mark.parametrize("mode", ["none", "estimated"])
def test_an_object_mass_for_a_mode_that_ignores_it_is_refused(tmp_path, capsys, mode):
    section = f"object_model: {{mode: {mode}, mass: 3}}\n"
    with pytest.raises(ScenarioError, match=r"^object_model\.mass: only mode known"):
        load_scenario(data=CONTACT + section)
    path = tmp_path / "s.yaml"
    path.write_text(CONTACT + section)
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "object_model.mass" in err[0] and f"mode {mode!r}" in err[0]
    assert not (tmp_path / "o").exists()


def test_the_mass_of_mode_known_is_accepted():
    scenario = load_scenario(data=CONTACT + "object_model: {mode: known, mass: 3}\n")
    assert scenario.object_model.mass == 3
