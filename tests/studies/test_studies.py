"""Study files: parsing, path resolution, grid expansion, Monte Carlo sampling, case hashes,
errors naming the field (no simulation here)."""

import dataclasses
import hashlib
import itertools
import json

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.scenario import default_scenario, load_scenario
from drake_coop.studies import StudyError, expand, load_study

H_VALUES = [0.003, 0.009]
KD_VALUES = [20.0, 40.0, 80.0]


def _study(text: str):
    return load_study(data=text)


def _scenarios(cases):
    return [load_scenario(data=c.scenario_yaml) for c in cases]


def test_grid_is_the_cartesian_product_and_star_sets_every_robot():
    cases = expand(_study(f"""
grid:
  control_period: {H_VALUES}
  robots.*.gains.k_d: {KD_VALUES}
"""))
    assert len(cases) == len(H_VALUES) * len(KD_VALUES)
    got = {(s.control_period, s.robots[0].gains.k_d, s.robots[1].gains.k_d)
           for s in _scenarios(cases)}
    assert got == {(h, k, k) for h, k in itertools.product(H_VALUES, KD_VALUES)}
    assert [c.params for c in cases] == [
        {"control_period": h, "robots.*.gains.k_d": k}
        for h, k in itertools.product(H_VALUES, KD_VALUES)]
    paper = default_scenario()
    for s in _scenarios(cases):        # nothing else changed
        assert s.robots[0].gains.K_R == paper.robots[0].gains.K_R
        assert s.robots[1].gains.Lambda == paper.robots[1].gains.Lambda


def test_list_fields_whole_broadcast_and_element_wise():
    cases = expand(_study("""
grid:
  robots.0.gains.K_R: [[100, 110, 90], 80]
  robots.1.gains.K_R.2: [70]
"""))
    s_whole, s_scalar = _scenarios(cases)
    assert s_whole.robots[0].gains.K_R == [100.0, 110.0, 90.0]
    assert s_scalar.robots[0].gains.K_R == [80.0, 80.0, 80.0]
    for s in (s_whole, s_scalar):
        assert s.robots[1].gains.K_R == [100.0, 100.0, 70.0]


def test_identical_scenarios_share_a_hash_and_t_end_enters_it():
    cases = expand(_study("grid: {robots.0.gains.k_d: [40, 40.0, 41]}"))
    assert cases[0].hash == cases[1].hash != cases[2].hash
    # the hash is over the scenario the case runs (its YAML loaded back), every field but
    # the opt-ins added after cases were stored, at their null default (anti-windup)
    loaded = dataclasses.asdict(load_scenario(data=cases[0].scenario_yaml))
    for robot in loaded["robots"]:
        assert robot.pop("anti_windup") is None and robot.pop("anti_windup_gain") is None
    canonical = json.dumps(loaded, sort_keys=True, separators=(",", ":"))
    expected = hashlib.sha256(f"{canonical}\n# t_end: None\n".encode()).hexdigest()[:16]
    assert cases[0].hash == expected
    other = expand(_study("t_end: 5.0\ngrid: {robots.0.gains.k_d: [40]}"))
    assert other[0].scenario_yaml == cases[0].scenario_yaml and other[0].hash != cases[0].hash


MC = """
monte_carlo:
  n: {n}
  seed: {seed}
  perturb:
    robots.0.gains.k_d: {{uniform: [30, 50]}}
    robots.*.gains.Lambda: {{scale_uniform: [0.8, 1.2]}}
    robots.1.gains.K_R: {{scale_uniform: [0.9, 1.1]}}
    robots.0.gains.K_R.*: {{scale_uniform: [0.5, 1.5]}}
    robots.1.gains.k_F: {{normal: [0.05, 0.005]}}
"""


def test_monte_carlo_draws_follow_the_documented_order_from_the_seed():
    n, seed = 40, 7
    cases = expand(_study(MC.format(n=n, seed=seed)))
    assert len(cases) == n
    rng = np.random.default_rng(seed)     # independent replay: sample, path, element
    for s in _scenarios(cases):
        k_d = rng.uniform(30, 50)
        lam = [35.0 * rng.uniform(0.8, 1.2), 26.0 * rng.uniform(0.8, 1.2)]
        kr1 = 100.0 * rng.uniform(0.9, 1.1)
        kr0 = [120.0 * rng.uniform(0.5, 1.5) for _ in range(3)]
        k_f = rng.normal(0.05, 0.005)
        assert s.robots[0].gains.k_d == pytest.approx(k_d, rel=1e-12)
        assert [r.gains.Lambda for r in s.robots] == pytest.approx(lam, rel=1e-12)
        assert s.robots[1].gains.K_R == pytest.approx([kr1] * 3, rel=1e-12)
        assert s.robots[0].gains.K_R == pytest.approx(kr0, rel=1e-12)
        assert s.robots[1].gains.k_F == pytest.approx(k_f, rel=1e-12)


def test_monte_carlo_is_reproducible_from_its_seed_and_within_bounds():
    a = expand(_study(MC.format(n=60, seed=3)))
    b = expand(_study(MC.format(n=60, seed=3)))
    c = expand(_study(MC.format(n=60, seed=4)))
    assert [x.hash for x in a] == [x.hash for x in b]
    assert not {x.hash for x in a} & {x.hash for x in c}
    scen = _scenarios(a)
    k_d = np.array([s.robots[0].gains.k_d for s in scen])
    assert np.all((k_d >= 30) & (k_d <= 50))
    # mean of U(30, 50) is 40, std 20/sqrt(12); 60 samples: 5 standard errors is 3.7
    assert abs(k_d.mean() - 40.0) < 5 * (20 / np.sqrt(12)) / np.sqrt(60)
    # scale_uniform multiplies the base value; one factor for the whole list without *,
    # independent factors per element with *
    ratio1 = np.array([s.robots[1].gains.K_R for s in scen]) / 100.0
    assert np.all((ratio1 >= 0.9) & (ratio1 <= 1.1))
    assert np.allclose(ratio1, ratio1[:, :1])
    ratio0 = np.array([s.robots[0].gains.K_R for s in scen]) / 120.0
    assert np.all((ratio0 >= 0.5) & (ratio0 <= 1.5))
    assert np.ptp(ratio0, axis=1).min() > 0
    lam = np.array([[r.gains.Lambda for r in s.robots] for s in scen]) / [35.0, 26.0]
    assert np.all((lam >= 0.8) & (lam <= 1.2)) and not np.allclose(lam[:, 0], lam[:, 1])


def test_grid_times_monte_carlo_uses_the_same_draws_at_every_grid_point():
    cases = expand(_study("grid: {control_period: [0.003, 0.009]}\n" + MC.format(n=3, seed=1)))
    assert len(cases) == 6
    scen = _scenarios(cases)
    for i in range(3):
        assert scen[i].robots[0].gains.K_R == scen[3 + i].robots[0].gains.K_R
        assert scen[i].control_period == 0.003 and scen[3 + i].control_period == 0.009
        assert cases[i].params["sample"] == cases[3 + i].params["sample"] == i


@pytest.mark.parametrize("text, start", [
    ("grid: {robots.0.gains.k_x: [1]}", "grid.robots.0.gains.k_x: no such field"),
    ("grid: {robots.5.gains.k_d: [1]}", "grid.robots.5.gains.k_d: 'robots.5' is not an index of a list of 2"),
    ("grid: {control_period.x: [1]}", "grid.control_period.x: no such field"),
    ("grid: {control_period: [-0.009]}",
     "grid.control_period = -0.009: control_period must be a finite number in"),
    ("grid: {robots.*.gains.k_d: [40, abc]}", "grid.robots.*.gains.k_d = 'abc':"),
    ("grid: {control_period: []}", "grid.control_period: must be a non-empty list"),
    ("grids: {control_period: [0.009]}", "grids: no such field"),
    ("t_end: 0\ngrid: {control_period: [0.009]}", "t_end: must be at least 1e-05 s"),
    ("monte_carlo: {n: 3, seed: 1, perturb: {robots.0.gains.k_d: {beta: [1, 2]}}}",
     "monte_carlo.perturb.robots.0.gains.k_d: unknown distribution 'beta'"),
    ("monte_carlo: {n: 0, seed: 1, perturb: {robots.0.gains.k_d: {uniform: [1, 2]}}}",
     "monte_carlo.n: must be an integer >= 1"),
    ("monte_carlo: {n: 2, seed: 1, perturb: {robots.0.gains.k_d: {uniform: [2, 1]}}}",
     "monte_carlo.perturb.robots.0.gains.k_d.uniform: needs lo <= hi"),
    ("monte_carlo: {n: 2, seed: 1, perturb: {robots.0.gains.k_q: {uniform: [1, 2]}}}",
     "monte_carlo.perturb.robots.0.gains.k_q: no such field"),
    ("monte_carlo: {n: 2, seed: 1, perturb: {robots.0.name: {scale_uniform: [1, 2]}}}",
     "monte_carlo.perturb.robots.0.name: scale_uniform needs a numeric base value"),
    ("name: x", "grid: a study needs a grid, a monte_carlo block, or both"),
    ("base: nowhere.yaml\ngrid: {control_period: [0.009]}", "base: scenario file not found"),
])
def test_bad_study_files_name_the_field(text, start):
    with pytest.raises(StudyError) as info:
        expand(_study(text))
    assert str(info.value).startswith(start), str(info.value)


def test_bad_study_file_on_the_command_line_exits_2_with_one_line(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text("grid:\n  robots.0.gains.k_x: [1, 2]\n")
    assert main(["study", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["drake-coop study: error: grid.robots.0.gains.k_x: no such field "
                   "('robots.0.gains.k_x'); allowed here: Lambda, K_R, k_d, k_F, xi, xi_matrix, zeta, beta, "
                   "momentum_gain"]
    assert not (tmp_path / "out").exists()
    path.write_text("grid: {control_period: [0.009]}\nmetrics: [worst.speed.rms]\n")
    assert main(["study", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "metrics: unknown column 'worst.speed.rms'" in capsys.readouterr().err


def test_base_is_relative_to_the_study_file_or_inline(tmp_path):
    (tmp_path / "base.yaml").write_text("control_period: 0.006\nplant: {time_step: 0.003}\n")
    (tmp_path / "s.yaml").write_text("base: base.yaml\ngrid: {robots.0.gains.k_d: [20]}\n")
    (s,) = _scenarios(expand(load_study(tmp_path / "s.yaml")))
    assert (s.control_period, s.plant.time_step, s.robots[0].gains.k_d) == (0.006, 0.003, 20)
    (s,) = _scenarios(expand(_study("base: {control_period: 0.003}\n"
                                    "grid: {plant.time_step: [0.001]}")))
    assert (s.control_period, s.plant.time_step) == (0.003, 0.001)


def test_a_base_file_finds_its_robots_urdfs_beside_it(tmp_path):
    """As drake-coop run does: identify's identified.yaml names its URDFs beside it; the
    study's cases load the file found there (not urdf/'s), whatever the working folder."""
    from drake_coop.scenario.resources import urdf_dir
    folder = tmp_path / "ident"
    folder.mkdir()
    text = (urdf_dir() / "crs_a465_3dof.urdf").read_text()
    (folder / "mine.urdf").write_text(text)
    (folder / "base.yaml").write_text("robots:\n- {name: robot1, model: crs_a465, "
                                      "controller_model: mine.urdf}\n"
                                      "- {name: robot2, model: crs_a255, base_xyz: [1.16, 0, 0], "
                                      "base_yaw_deg: 180, contact_xy: [0.8192, 0], "
                                      "normals: [[1, 0, 0]], home: [0.9, 0, 0.6]}\n")
    (tmp_path / "s.yaml").write_text("base: ident/base.yaml\n"
                                     "grid: {robots.0.gains.k_d: [20]}\n")
    (s,) = _scenarios(expand(load_study(tmp_path / "s.yaml")))
    assert s.robots[0].controller_model == str((folder / "mine.urdf").resolve())
    assert s.robots[1].controller_model == ""
    # A base naming no file beside it keeps its text (and its cases' hashes).
    (tmp_path / "plain.yaml").write_text("control_period: 0.006  # h\n")
    (tmp_path / "p.yaml").write_text("base: plain.yaml\ngrid: {plant.time_step: [0.003]}\n")
    assert load_study(tmp_path / "p.yaml").base_yaml == "control_period: 0.006  # h\n"


def test_mapping_values_are_variants_that_update_only_the_fields_they_name():
    cases = expand(_study("""
grid:
  robots.*:
    - {velocity_source: measured}
    - {gains: {k_d: 20}}
  control_period: [0.003, 0.009]
"""))
    assert len(cases) == 4
    s = _scenarios(cases)
    paper = default_scenario()
    for r, p in zip(s[0].robots, paper.robots):
        assert r.velocity_source == "measured" and r.gains == p.gains and r.home == p.home
    for r, p in zip(s[2].robots, paper.robots):
        assert r.velocity_source == "observer" and r.gains.k_d == 20
        assert r.gains.K_R == p.gains.K_R and r.gains.Lambda == p.gains.Lambda
    assert [x.control_period for x in s] == [0.003, 0.009, 0.003, 0.009]
    with pytest.raises(StudyError) as info:
        expand(_study("grid: {robots.*: [{speed: 1}]}"))
    assert str(info.value).startswith("grid.robots.* = {'speed': 1}: robots[0].speed is not a "
                                      "known field"), str(info.value)


# ---------------------------------------------------------------- figure labels


@pytest.mark.parametrize("metric, unit, label", [
    ("worst.force_error.rms", "N", r"$\lambda - \lambda_d$, RMS, worst robot [N]"),
    ("robot2.position_error.max", "µm", r"$|x - x_d|$ (worst axis), max, robot2 [µm]"),
    ("worst.z3.max", "µrad", "z of joint 3, max, worst robot [µrad]"),
])
def test_study_metrics_are_labelled_in_words_with_their_unit(metric, unit, label):
    from drake_coop.studies.plots import metric_label
    assert metric_label(metric, unit) == label


@pytest.mark.parametrize("param, label, factor", [
    ("control_period", "control period h [ms]", 1e3),
    ("robots.*.gains.k_d", "k_d, every robot [1/s]", 1.0),
    ("robots.0.gains.K_R", "K_R, robot 1 [N·m·s/rad]", 1.0),        # unit from BOUNDS
    ("robots.*.model_error.mass_scale", "mass_scale, every robot", 1.0),
])
def test_study_parameters_are_labelled_with_the_scenario_units(param, label, factor):
    from drake_coop.studies.plots import param_label
    assert param_label(param) == (label, factor)


def test_study_values_are_drawn_in_the_unit_their_size_calls_for():
    from drake_coop.studies.plots import _metric_unit
    assert _metric_unit("worst.position_error.max", [2.0e-5, 1.8e-4]) == (1e6, "µm")
    assert _metric_unit("worst.position_error.max", [2.8e-3, float("nan")]) == (1e3, "mm")
    assert _metric_unit("worst.velocity_error.rms", [0.059]) == (1e3, "mrad/s")
    assert _metric_unit("worst.force_error.rms", [132.0]) == (1.0, "N")


def test_friction_draws_reach_every_joint_of_every_arm():
    # coulomb_friction defaults to [] (no friction, any arm): a per-joint path must still find
    # one element per joint of each arm, not silently match nothing.
    cases = expand(_study("""
t_end: 1.0
monte_carlo:
  n: 2
  seed: 7
  perturb:
    robots.*.model_error.coulomb_friction.*: {uniform: [0.0, 1.0]}
"""))
    for scenario in _scenarios(cases):
        for robot in scenario.robots:
            friction = robot.model_error.coulomb_friction
            assert len(friction) == 3 and len(set(friction)) == 3
            assert all(0.0 <= f <= 1.0 for f in friction)


def test_the_shipped_model_mismatch_study_draws_its_published_cases():
    import csv
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    cases = expand(load_study(root / "studies" / "model_mismatch.yaml"))
    with open(root / "docs" / "figures" / "studies" / "model_mismatch_results.csv") as f:
        published = list(csv.DictReader(f))
    assert len(cases) == len(published) == 60
    for case, row in zip(cases, published):
        drawn = {k: v for k, v in case.values.items() if k.startswith("robots.")}
        assert len(drawn) == 12      # mass, inertia, damping per arm; friction per joint
        assert drawn == {k: float(row[k]) for k in drawn}


def test_a_study_reach_checks_each_base_once(monkeypatch):
    """The reachability check (every target through each arm's kinematics, the costly part of
    validation) runs once per base geometry: the base's loading and every case share its
    result, also the cases that go through the YAML loading (a variant value); a second
    geometry is checked once more (the counter can fail)."""
    import drake_coop.scenario.reach as validation

    calls = []
    inner = validation.check_reachable
    monkeypatch.setattr(validation, "check_reachable",
                        lambda scenario: (calls.append(1), inner(scenario))[1])
    cases = expand(_study("grid: {robots.0.velocity_source: [observer, difference], "
                          "robots.0.gains.k_d: [20, 40]}"))
    assert len(cases) == 4 and len(calls) == 1
    calls.clear()
    cases = expand(_study("grid: {task.lift_height: [0.05, 0.06], "
                          "robots.0.velocity_source: [observer, difference]}"))
    assert len(cases) == 4 and len(calls) == 3          # the base and two lift heights
