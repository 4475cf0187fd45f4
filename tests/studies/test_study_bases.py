"""A study's ``base`` grid axis: one study over several base scenario files (arm sets), the
other grid values and the Monte Carlo draws applied on each; errors in one line naming the
field and the base (no simulation here)."""

from pathlib import Path

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.scenario import load_scenario
from drake_coop.studies import StudyError, expand, load_study

ROOT = Path(__file__).resolve().parents[2]
THREE = ROOT / "scenarios" / "three_arms.yaml"


def _files(tmp_path: Path, study: str) -> Path:
    """A two-arm base (the paper's arms, h = 6 ms), the shipped three-arm one beside it as
    ``three.yaml``, and the study file ``s.yaml``."""
    (tmp_path / "two.yaml").write_text("control_period: 0.006\n")
    (tmp_path / "three.yaml").write_text(THREE.read_text())
    (tmp_path / "s.yaml").write_text(study)
    return tmp_path / "s.yaml"


STUDY = """
grid:
  base: [two.yaml, three.yaml]
  robots.*.gains.k_d: [20, 60]
monte_carlo:
  n: 3
  seed: 11
  perturb:
    plant.friction: {uniform: [0.5, 1.0]}
    robots.*.gains.Lambda: {uniform: [20, 40]}
"""


def test_each_case_is_its_base_with_the_grid_values_and_the_draws_replayed(tmp_path):
    cases = expand(load_study(_files(tmp_path, STUDY)))
    assert len(cases) == 2 * 2 * 3                          # bases × k_d × samples
    assert [(c.params["base"], c.params["robots.*.gains.k_d"], c.params["sample"])
            for c in cases] == [(b, k, s) for b in ("two.yaml", "three.yaml")
                                for k in (20, 60) for s in range(3)]
    assert [c.values["base"] for c in cases] == [c.params["base"] for c in cases]
    files = {"two.yaml": load_scenario(tmp_path / "two.yaml"), "three.yaml": load_scenario(THREE)}
    for c in cases:
        scenario = load_scenario(data=c.scenario_yaml)
        base = files[c.params["base"]]
        # the base's own fields kept, its arms (two or three), the grid's value on each
        assert scenario.control_period == base.control_period
        assert [r.name for r in scenario.robots] == [r.name for r in base.robots]
        assert [r.base_xyz for r in scenario.robots] == [r.base_xyz for r in base.robots]
        assert {r.gains.k_d for r in scenario.robots} == {c.params["robots.*.gains.k_d"]}
        # the draws, replayed independently: sample by sample, path by path, element by
        # element of this base (the three-arm base takes one more draw per sample)
        rng = np.random.default_rng(11)
        for _ in range(c.params["sample"] + 1):
            friction = rng.uniform(0.5, 1.0)
            lam = [rng.uniform(20, 40) for _ in base.robots]
        assert scenario.plant.friction == pytest.approx(friction, rel=1e-12)
        assert [r.gains.Lambda for r in scenario.robots] == pytest.approx(lam, rel=1e-12)


def test_draws_of_paths_every_base_has_alike_are_paired_across_the_bases(tmp_path):
    study = STUDY.replace("    robots.*.gains.Lambda: {uniform: [20, 40]}\n", "")
    cases = expand(load_study(_files(tmp_path, study)))
    by_base: dict = {}
    for c in cases:
        by_base.setdefault(c.params["base"], []).append(
            load_scenario(data=c.scenario_yaml).plant.friction)
    assert by_base["two.yaml"] == by_base["three.yaml"]
    assert len(set(by_base["two.yaml"][:3])) == 3             # three different draws


def test_a_case_has_the_hash_of_the_same_case_in_a_one_base_study(tmp_path):
    """The axis only picks the base: a case is the case a study with that file as its
    top-level base gives (same scenario, same hash; finished cases are found again)."""
    cases = expand(load_study(_files(tmp_path, STUDY)))
    for name in ("two.yaml", "three.yaml"):
        single = STUDY.replace("  base: [two.yaml, three.yaml]\n", "")
        (tmp_path / "one.yaml").write_text(f"base: {name}\n{single}")
        alone = expand(load_study(tmp_path / "one.yaml"))
        mine = [c for c in cases if c.params["base"] == name]
        assert [c.hash for c in mine] == [c.hash for c in alone]
        assert [c.scenario_yaml for c in mine] == [c.scenario_yaml for c in alone]


@pytest.mark.parametrize("study, start", [
    ("base: two.yaml\ngrid: {base: [three.yaml]}",
     "grid.base: the grid's base files replace the top-level base; give one or the other"),
    ("grid: {base: [two]}", "grid.base: each value must be a scenario file path (.yaml"),
    ("grid: {base: [{control_period: 0.006}]}", "grid.base: each value must be a scenario file"),
    ("grid: {base: [two.yaml, two.yaml]}", "grid.base: 'two.yaml' is listed twice"),
    ("grid: {base: [two.yaml, nowhere.yaml]}",
     "grid.base = 'nowhere.yaml': scenario file not found: "),
    ("grid: {base: [two.yaml, bad.yaml]}", "grid.base = 'bad.yaml': "),
    ("grid: {base: [two.yaml, three.yaml], robots.2.gains.k_d: [20]}",
     "grid.robots.2.gains.k_d: 'robots.2' is not an index of a list of 2 (use 0 … 1 or *) "
     "(on base 'two.yaml')"),
    ("grid: {base: [two.yaml, three.yaml]}\nmonte_carlo: {n: 1, seed: 1, perturb: "
     "{robots.2.gains.k_d: {uniform: [1, 2]}}}",
     "monte_carlo.perturb.robots.2.gains.k_d: 'robots.2' is not an index of a list of 2"),
    ("grid: {base: [three.yaml, two.yaml], robots.*.gains.k_d: [-1, 20]}",
     "grid.robots.*.gains.k_d = -1 (on base 'three.yaml'): "),
])
def test_a_bad_base_axis_is_one_line_naming_the_field_and_the_base(tmp_path, study, start):
    (tmp_path / "bad.yaml").write_text("control_period: -1\n")
    with pytest.raises(StudyError) as info:
        expand(load_study(_files(tmp_path, study)))
    message = str(info.value)
    assert message.startswith(start) and "\n" not in message, message
    if "robots.2.gains.k_d" in start:
        assert message.endswith("(on base 'two.yaml')"), message
    if start.startswith("grid.robots.*.gains.k_d = -1"):
        assert "(on base 'three.yaml')" in message, message


def test_a_base_axis_value_that_is_not_a_loaded_file_is_refused():
    from drake_coop.studies.spec import Study

    with pytest.raises(StudyError, match=r"^grid\.base = 'x\.yaml': not one of the study's"):
        expand(Study(name="s", grid={"base": ["x.yaml"]}))


def test_a_bad_base_axis_on_the_command_line_exits_2_with_one_line(tmp_path, capsys):
    path = _files(tmp_path, "grid: {base: [two.yaml, missing.yaml]}\n")
    assert main(["study", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        "drake-coop study: error: grid.base = 'missing.yaml': scenario file not found"), err
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_the_shipped_lab_study_pairs_its_draws_over_three_arm_sets():
    """studies/object_carry_lab.yaml: every object model on every arm set on the same
    draws of mass and μ, in the ranges the study file gives; the two-arm lab scenarios get
    contact.yaml's plant."""
    study = load_study(ROOT / "studies" / "object_carry_lab.yaml")
    study.monte_carlo.n = 2
    cases = expand(study)
    assert len(cases) == 3 * 3 * 2
    contact = load_scenario(ROOT / "scenarios" / "contact.yaml").plant
    draws = {}
    for c in cases:
        s = load_scenario(data=c.scenario_yaml)
        assert len(s.robots) == (3 if "three_arms" in c.params["base"] else 2)
        assert (s.plant.object_mode, s.plant.time_step, s.plant.stand_clearance) == (
            contact.object_mode, contact.time_step, contact.stand_clearance)
        assert 0.2 <= s.plant.object_mass <= 1.5 and 0.5 <= s.plant.friction <= 1.0
        draws.setdefault(c.params["sample"], set()).add((s.plant.object_mass, s.plant.friction))
        assert s.object_model.mode == c.params["object_model"]["mode"]
    assert all(len(v) == 1 for v in draws.values()) and len(draws) == 2
