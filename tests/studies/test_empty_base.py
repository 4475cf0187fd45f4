"""An empty base scenario file (0 bytes, blanks, comments only) is an error wherever a
scenario is read — a scenario file, a study's top-level ``base:``, each file on a study's
``grid.base`` axis — one line naming the file, never the paper's scenario in its place."""

import pytest

from drake_coop.cli import main
from drake_coop.scenario import load_scenario
from drake_coop.scenario.schema import ScenarioError
from drake_coop.studies import StudyError, expand, load_study

EMPTY = {"zero": "", "blanks": " \n\n   \n", "comments": "# a scenario, to be written\n"}


@pytest.mark.parametrize("text", EMPTY.values(), ids=EMPTY.keys())
def test_an_empty_scenario_file_is_one_line_naming_the_file(tmp_path, text):
    path = tmp_path / "empty.yaml"
    path.write_text(text)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    message = str(info.value)
    assert str(path) in message and "is empty" in message and "\n" not in message


@pytest.mark.parametrize("text", EMPTY.values(), ids=EMPTY.keys())
@pytest.mark.parametrize("study", ["base: empty.yaml\ngrid: {control_period: [0.003]}\n",
                                   "grid: {base: [two.yaml, empty.yaml]}\n"],
                         ids=["top-level", "grid.base"])
def test_an_empty_base_file_in_a_study_is_refused_naming_it(tmp_path, text, study):
    (tmp_path / "empty.yaml").write_text(text)
    (tmp_path / "two.yaml").write_text("control_period: 0.006\n")
    (tmp_path / "s.yaml").write_text(study)
    with pytest.raises(StudyError) as info:
        expand(load_study(tmp_path / "s.yaml"))
    message = str(info.value)
    start = "grid.base = 'empty.yaml': " if "grid:" in study and "base: [" in study else "base: "
    assert message.startswith(start), message
    assert "empty.yaml" in message.removeprefix(start) and "is empty" in message
    assert "\n" not in message


@pytest.mark.parametrize("study", ["base: empty.yaml\ngrid: {control_period: [0.003]}\n",
                                   "grid: {base: [two.yaml, empty.yaml]}\n"],
                         ids=["top-level", "grid.base"])
def test_an_empty_base_file_on_the_command_line_exits_2_before_anything_runs(
        tmp_path, capsys, study):
    (tmp_path / "empty.yaml").write_bytes(b"")
    (tmp_path / "two.yaml").write_text("control_period: 0.006\n")
    (tmp_path / "s.yaml").write_text(study)
    assert main(["study", str(tmp_path / "s.yaml"), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "empty.yaml" in err[0] and "is empty" in err[0], err
    assert not (tmp_path / "out").exists()


def test_an_empty_base_text_reaching_the_case_builder_is_refused_not_replaced():
    """A study built in the API with an empty base text: refused, not the paper's scenario."""
    from drake_coop.studies.spec import Study

    with pytest.raises(StudyError, match="^base: .*empty"):
        expand(Study(name="s", grid={"control_period": [0.003]}, base_yaml=""))
