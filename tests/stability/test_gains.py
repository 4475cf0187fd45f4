"""``drake-coop gains``: the derived gains against their rules, against the stability map
(ρ < 1, computed afresh from the written scenario) and against a simulation that grasps and
holds the object; bad input exits 2 before any computation; the output is whole or absent."""

import csv
import json
import math

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.simulate import simulate
from drake_coop.plant.arms import arm_model
from drake_coop.scenario.loading import load_scenario
from drake_coop.scenario.resources import find_scenario
from drake_coop.stability import gains as rules
from drake_coop.stability.one_joint import observer_period_limit


def test_the_derived_gains_follow_their_rules_on_an_arm_they_were_not_tuned_on():
    s = load_scenario(find_scenario("six_joint"))
    plan = plan_run(s)
    derived = rules.derive_gains(s)
    h = plan.h
    for i, d in enumerate(derived):
        g = d.gains
        model = arm_model(plan.arms[i])
        # J_j: the inertia joint j sees with the others free (the Schur complement of H),
        # smallest over the task's postures; it lies above min λ_min(H).
        postures, grasp = rules.task_postures(plan.robots[i])
        schur, lam_min = [], []
        for q in postures:
            H = model.H(q)
            lam_min.append(np.linalg.eigvalsh(H)[0])
            row = []
            for j in range(H.shape[0]):
                r = [k for k in range(H.shape[0]) if k != j]
                row.append(H[j, j] - H[j, r] @ np.linalg.solve(H[np.ix_(r, r)], H[r, j]))
            schur.append(row)
        np.testing.assert_allclose(d.inertia, np.min(schur, axis=0), rtol=1e-10)
        assert min(d.inertia) >= min(lam_min) - 1e-12
        np.testing.assert_allclose(np.asarray(g.K_R) * h / np.asarray(d.inertia), rules.KAPPA)
        assert 2.0 / observer_period_limit(g.Lambda, g.k_d) * h <= rules.SIGMA + 1e-12
        assert 0.0 < g.momentum_gain * h <= 0.5
        J = model.J_phi(grasp)
        gain = (np.linalg.pinv(J).T @ np.diag(g.K_R) @ np.linalg.pinv(J)).item() * g.xi
        assert gain == pytest.approx(rules.FORCE_LOOP_GAIN)
    # the six-joint arm's light wrist gets a lower K_R than its shoulder, as hand-tuned
    assert max(derived[0].gains.K_R[3:]) < min(derived[0].gains.K_R[:2])


@pytest.fixture(scope="module")
def paper_gains(tmp_path_factory):
    out = tmp_path_factory.mktemp("gains") / "paper"
    assert main(["gains", "paper", "--out", str(out), "--quiet"]) == 0
    return out


@pytest.mark.slow
def test_the_command_writes_gains_whose_map_and_run_are_stable(paper_gains):
    from drake_coop.stability.grid import point_rows

    out = paper_gains
    assert sorted(p.name for p in out.iterdir()) == ["gains.csv", "run.json", "scenario.yaml",
                                                     "stability.csv"]
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "ok" and set(meta["rho"]) == {"free", "held", "free_margin",
                                                           "held_margin"}
    # the delay margin with the derived gains, without and with compensation
    margin = meta["delay_margin"]
    assert margin["without"]["margin_s"] > 0 and margin["with"]["margin_s"] > 0
    assert margin["with"]["horizon"] == "matched" and "without compensation" in margin["line"]
    assert margin["without"]["rho"][0] == pytest.approx(meta["rho"]["free"], rel=1e-3)
    rows = list(csv.DictReader((out / "stability.csv").open()))
    assert all(float(r["rho"]) < 1.0 for r in rows) and len(rows) == 4
    text = (out / "scenario.yaml").read_text()
    scenario = load_scenario(data=text)
    with (out / "gains.csv").open() as f:
        for robot, row in zip(scenario.robots, csv.DictReader(f)):
            np.testing.assert_allclose(robot.gains.K_R, [float(k) for k in row["K_R"].split()],
                                       rtol=1e-5)
    # The map afresh, from the written scenario (the grid's own entry point).
    (free,) = point_rows(text, ["free"])
    assert free["status"] == "stable" and free["rho"] == pytest.approx(meta["rho"]["free"],
                                                                      rel=1e-6)
    # A run: free motion, the grasp at 15 s and two seconds of holding during the lift.
    result = simulate(scenario, t_end=17.0)
    assert result.ok
    for name in ("robot1", "robot2"):
        log = result.logs[name]
        held = log["t"] > 16.0
        err = log["lambda_meas"][held] - log["lambda_d"][held]
        assert np.all(log["lambda_meas"][held] > 1.0)            # the object is squeezed
        assert np.sqrt(np.mean(err ** 2)) < 0.5                   # and its force tracked
        assert np.max(np.abs(log["x"][held] - log["x_d"][held])) < 1e-3


def test_bad_input_exits_2_before_any_computation(tmp_path, capsys, monkeypatch):
    def fail(*a, **k):
        raise AssertionError("computed despite bad input")

    monkeypatch.setattr(rules, "derive_and_check", fail)
    a_file = tmp_path / "file"
    a_file.write_text("x")
    cases = [["gains", "no_such_scenario", "--out", str(tmp_path / "a")],
             ["gains", "paper", "--out", str(a_file)],
             ["gains", "paper", "--out", str(a_file / "below")]]
    bad = tmp_path / "bad.yaml"
    bad.write_text("control_period: -1\n")
    cases.append(["gains", str(bad), "--out", str(tmp_path / "b")])
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    cases.append(["gains", "paper", "--out", str(foreign)])
    for argv in cases:
        assert main(argv) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("drake-coop: error:") and "\n" not in err
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()
    assert [p.name for p in foreign.iterdir()] == ["notes.txt"]


def test_an_interrupt_leaves_no_output_and_exits_130(tmp_path, monkeypatch):
    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(rules, "derive_and_check", interrupted)
    assert main(["gains", "paper", "--out", str(tmp_path / "out"), "--quiet"]) == 130
    assert list(tmp_path.iterdir()) == []          # neither the folder nor its staging


def test_a_previous_output_is_replaced_only_with_force(tmp_path, monkeypatch):
    s = load_scenario()

    def quick(scenario, **k):
        report = rules.GainsReport(robots=rules.derive_gains(scenario))
        report.rho, report.stable = {"free": 0.5, "held": 0.5, "free_margin": 0.5,
                                     "held_margin": 0.5}, True
        return report

    monkeypatch.setattr(rules, "derive_and_check", quick)
    from drake_coop.stability import gains_cli

    monkeypatch.setattr(gains_cli, "gains_margins", lambda scenario, report: {"line": "m"})
    out = tmp_path / "out"
    assert main(["gains", "paper", "--out", str(out), "--quiet"]) == 0
    assert main(["gains", "paper", "--out", str(out), "--quiet"]) == 2
    assert main(["gains", "paper", "--out", str(out), "--quiet", "--force"]) == 0
    assert math.isclose(json.loads((out / "run.json").read_text())["rho"]["free"], 0.5)
    assert len(load_scenario(data=(out / "scenario.yaml").read_text()).robots) == len(s.robots)


def test_a_failing_derivation_is_one_line_exit_1_and_no_output(tmp_path, monkeypatch, capsys):
    def broken(*a, **k):
        raise RuntimeError("no equilibrium\nat all")

    monkeypatch.setattr(rules, "derive_and_check", broken)
    assert main(["gains", "paper", "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == "drake-coop: gains failed: RuntimeError: no equilibrium at all"
    assert list(tmp_path.iterdir()) == []


def test_a_contact_scenario_is_checked_on_its_planes_copy():
    s = load_scenario(find_scenario("contact"))
    assert s.plant.object_mode == "contact"
    checked, mode = rules.map_copy(s)
    assert mode == "planes" and checked.plant.object_mode == "planes"
    assert s.plant.object_mode == "contact"          # the input is left as it is
    same, mode = rules.map_copy(load_scenario())
    assert mode == "planes" and same.plant.object_mode == "planes"
