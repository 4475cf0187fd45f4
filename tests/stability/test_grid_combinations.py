"""``stability --grid`` (and a study's grid) is checked in its combinations: a value that is
invalid against the base alone but valid with another key's value is accepted;
an invalid combination is named by its case, and a value bad on its own by its key."""

import pytest

from drake_coop.stability.grid import grid_cases
from drake_coop.studies import StudyError


def test_control_period_with_plant_time_step_is_checked_together():
    # plant.time_step = 0.002 does not divide the base's control_period 0.009: alone it is
    # refused, but every combination here is valid.
    cases = grid_cases(None, {"control_period": [0.002, 0.004], "plant.time_step": [0.002]})
    assert [(c.values["control_period"], c.values["plant.time_step"]) for c in cases] == [
        (0.002, 0.002), (0.004, 0.002)]


def test_an_invalid_combination_is_named_by_its_case():
    with pytest.raises(StudyError, match=r"^case 0 \(control_period=0\.003, "
                                         r"plant\.time_step=0\.002\): control_period \(0\.003\) "
                                         r"must be an integer multiple"):
        grid_cases(None, {"control_period": [0.003, 0.004], "plant.time_step": [0.002]})


def test_a_value_bad_on_its_own_is_named_by_its_key_in_a_two_key_grid():
    with pytest.raises(StudyError, match=r"^grid\.control_period = -0\.003: control_period "):
        grid_cases(None, {"plant.time_step": [0.001], "control_period": [-0.003, 0.003]})


def test_the_command_accepts_the_pair(tmp_path, capsys):
    from drake_coop.cli import main

    out = tmp_path / "o"
    assert main(["stability", "paper", "--out", str(out), "--grid", "control_period=0.004",
                 "--grid", "plant.time_step=0.002", "--point", "free", "--quiet"]) == 0
    assert "0.004" in (out / "stability.csv").read_text()
