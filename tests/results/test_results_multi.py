"""The results layer for l robots with n_i joints and m_i constraints: logs, metrics,
figures and force arrows of synthetic runs mixing n = 3 / 6 and m = 1 / 2."""

from __future__ import annotations

import dataclasses
import math
import xml.etree.ElementTree as ET

import matplotlib
import numpy as np
import pytest

from drake_coop.results import (
    compute_metrics,
    fig_references,
    load_logs,
    plot_figures,
    save_logs,
)
from drake_coop.results.figures import path_plane
from tests.results.test_io import PHASES, bits

H = 0.05
#: Robots of the synthetic run: (joints n, constraints m).
SIZES = {"robot1": (6, 2), "robot2": (3, 1), "robot3": (3, 2)}
FORCE_ERROR = (0.3, -0.4)
"""λ − λ_d of the m = 2 robots in the circle phase: its norm is 0.5 N."""
Z_OBS = 1e-6
"""q − q̂ of joint j is j · Z_OBS."""


def multi_run(t_end: float = 90.0, optional: bool = False) -> tuple[dict, dict]:
    """Three robots, n = 6 / 3 / 3 joints, m = 2 / 1 / 2 constraints, errors known in closed
    form: ``q − q̂ = (1, 2, …, n) Z_OBS``; for m = 2, ``λ − λ_d = FORCE_ERROR`` in the
    circle phase and 0 elsewhere, ``λ − λ̂ = (A cos ωt, A sin ωt)`` (norm A = 0.2 N)."""
    t = H * np.arange(round(t_end / H) + 1)
    N = t.size
    rng = np.random.default_rng(7)
    circle = (t >= 25.0) & (t < 65.0)
    logs = {}
    for k, (robot, (n, m)) in enumerate(SIZES.items()):
        q_hat = rng.normal(size=(N, n))
        lam_d = (20.0 + np.sin(0.2 * t) + k)[:, None] * np.ones(m)
        lam = lam_d + np.where(circle[:, None], FORCE_ERROR[:m], 0.0)
        lam_hat = lam.copy()
        if m == 2:
            lam_hat -= 0.2 * np.column_stack([np.cos(3.0 * t), np.sin(3.0 * t)])
        force = (lambda a: a[:, 0]) if m == 1 else (lambda a: a)
        logs[robot] = {
            "t": t.copy(), "q": q_hat + Z_OBS * np.arange(1, n + 1), "q_hat": q_hat,
            "q_d": rng.normal(size=(N, n)), "x": rng.normal(size=(N, 3)),
            "x_d": rng.normal(size=(N, 3)), "F_meas": rng.normal(size=(N, 3)),
            "lambda_meas": force(lam), "lambda_hat": force(lam_hat), "lambda_d": force(lam_d),
            "tau": rng.normal(size=(N, n)),
        }
        if optional:
            logs[robot].update({"qdot": rng.normal(size=(N, n)),
                                "qdot_hat": rng.normal(size=(N, n)),
                                "lambda_sensor": force(lam + 0.01),
                                "tau_cmd": rng.normal(size=(N, n))})
    meta = {"phases": PHASES, "robots": list(SIZES), "status": "ok", "message": "done"}
    return logs, meta


# --- logs ------------------------------------------------------------------------------------

def test_six_joints_two_constraints_round_trip_bit_for_bit_with_its_header(tmp_path):
    logs, meta = multi_run(t_end=1.0, optional=True)
    save_logs(tmp_path, logs, meta)
    back, _ = load_logs(tmp_path)
    for robot, log in logs.items():
        assert set(back[robot]) == set(log)
        for key, value in log.items():
            assert back[robot][key].shape == value.shape
            np.testing.assert_array_equal(bits(back[robot][key]), bits(value))
    lines = (tmp_path / "robot1.csv").read_text().splitlines()
    def joints(name: str) -> list[str]:
        return [f"{name}{j}" for j in range(1, 7)]

    assert lines[0].split(",") == (
        ["t"] + joints("q") + joints("q_hat") + joints("q_d")
        + ["x", "y", "z", "x_d", "y_d", "z_d", "Fx", "Fy", "Fz",
           "lambda_meas1", "lambda_meas2", "lambda_hat1", "lambda_hat2", "lambda_d1", "lambda_d2"]
        + joints("tau") + joints("qdot") + joints("qdot_hat")
        + ["lambda_sensor1", "lambda_sensor2"] + joints("tau_cmd"))
    table = np.loadtxt(tmp_path / "robot1.csv", delimiter=",", skiprows=1)
    columns = lines[0].split(",")
    log = logs["robot1"]
    for name, values in {"q6": log["q"][:, 5], "lambda_hat2": log["lambda_hat"][:, 1],
                         "lambda_d1": log["lambda_d"][:, 0], "tau_cmd4": log["tau_cmd"][:, 3],
                         "z": log["x"][:, 2]}.items():
        np.testing.assert_array_equal(bits(table[:, columns.index(name)]), bits(values))
    # Robot 2 (n = 3, m = 1) keeps the paper's columns in the same run.
    assert (tmp_path / "robot2.csv").read_text().splitlines()[0].startswith(
        "t,q1,q2,q3,q_hat1,q_hat2,q_hat3,q_d1,q_d2,q_d3,x,y,z,x_d,y_d,z_d,Fx,Fy,Fz,"
        "lambda_meas,lambda_hat,lambda_d,tau1,tau2,tau3,")


@pytest.mark.parametrize("key, shape, expected", [
    ("q_hat", (21, 3), "'q_hat' has shape (21, 3), expected (21, 6)"),
    ("tau_cmd", (21, 5), "'tau_cmd' has shape (21, 5), expected (21, 6)"),
    ("lambda_hat", (21,), "'lambda_hat' has shape (21,), expected (21, 2)"),
    ("lambda_d", (21, 1), "'lambda_d' has shape (21, 1), expected (21,) for one constraint"),
    ("q", (21,), "'q' has shape (21,), expected (N, n) = (21, n)"),
    ("x", (21, 6), "'x' has shape (21, 6), expected (21, 3)"),
])
def test_inconsistent_shapes_are_refused_naming_the_array(tmp_path, key, shape, expected):
    logs, meta = multi_run(t_end=1.0, optional=True)
    logs["robot1"][key] = np.zeros(shape)
    with pytest.raises(ValueError, match=r"log of robot1: " + expected.replace("(", r"\(")
                       .replace(")", r"\)")):
        save_logs(tmp_path, logs, meta)
    assert list(tmp_path.iterdir()) == []


# --- metrics ---------------------------------------------------------------------------------

def test_force_metrics_of_several_constraints_are_those_of_the_error_norm():
    logs, meta = multi_run()
    metrics = compute_metrics(logs, meta)
    for robot in ("robot1", "robot3"):
        circle, free = metrics[robot]["circle"], metrics[robot]["free"]
        # ‖(0.3, −0.4)‖ = 0.5 N at every sample of the circle, 0 before it.
        assert circle["force_error"]["rms"] == pytest.approx(0.5, rel=1e-12)
        assert circle["force_error"]["max"] == pytest.approx(0.5, rel=1e-12)
        assert free["force_error"] == {"rms": 0.0, "max": 0.0, "unit": "N"}
        # ‖(A cos ωt, A sin ωt)‖ = A at every sample: RMS = max = A (no 1/√2).
        assert circle["estimate_error"]["rms"] == pytest.approx(0.2, rel=1e-12)
        assert circle["estimate_error"]["max"] == pytest.approx(0.2, rel=1e-12)
    # One constraint: the error of the first row alone, |0.3|.
    assert metrics["robot2"]["circle"]["force_error"]["max"] == pytest.approx(0.3, rel=1e-12)


def test_one_observation_error_per_joint():
    logs, meta = multi_run()
    metrics = compute_metrics(logs, meta)
    for robot, (n, _) in SIZES.items():
        names = [k for k in metrics[robot]["all"] if k.startswith("z") and k[1:].isdigit()]
        assert names == [f"z{j}" for j in range(1, n + 1)]
        for j in range(1, n + 1):
            assert metrics[robot]["all"][f"z{j}"]["rms"] == pytest.approx(j * Z_OBS, rel=1e-6)


def test_a_second_constraint_with_zero_error_leaves_the_metrics_of_the_first():
    logs, meta = multi_run()
    one = {k: (v[:, 0].copy() if k.startswith("lambda") else v)
           for k, v in logs["robot1"].items()}
    two = {**one, **{k: np.column_stack([one[k], np.full_like(one[k], 7.0)])
                     for k in ("lambda_meas", "lambda_hat", "lambda_d")}}
    m1 = compute_metrics({"robot1": one}, {**meta, "robots": ["robot1"]})["robot1"]
    m2 = compute_metrics({"robot1": two}, {**meta, "robots": ["robot1"]})["robot1"]
    for phase in m1:
        for error in ("force_error", "estimate_error", "aux_force_error"):
            # pytest.approx compares numbers only (pytest 9 refuses a dict holding the unit).
            numbers = {k for k, v in m1[phase][error].items() if not isinstance(v, str)}
            assert m2[phase][error].keys() == m1[phase][error].keys()
            assert {k: m2[phase][error][k] for k in numbers} == pytest.approx(
                {k: m1[phase][error][k] for k in numbers}, rel=1e-15)
            assert all(m2[phase][error][k] == m1[phase][error][k]
                       for k in m1[phase][error].keys() - numbers)


def test_non_finite_force_rows_are_counted_and_huge_ones_do_not_overflow():
    logs, meta = multi_run(t_end=20.0)
    log = logs["robot1"]
    log["lambda_meas"][-2:, 1] = np.nan
    log["lambda_meas"][5] = log["lambda_d"][5] + [3e300, 4e300]
    m = compute_metrics(logs, meta)["robot1"]
    assert m["lift"]["n_nonfinite"] == 2
    assert m["free"]["force_error"]["max"] == pytest.approx(5e300, rel=1e-12)


# --- figures ---------------------------------------------------------------------------------

def _svg_text(path) -> str:
    root = ET.parse(path).getroot()
    return "".join("".join(e.itertext()) for e in root.iter("{http://www.w3.org/2000/svg}text")
                   ).replace("\xa0", "").replace(" ", "").replace("\n", "")


def test_three_robots_with_six_and_three_joints_draw_every_figure(tmp_path):
    """Every figure of three robots (six and three joints), drawn as SVG, whose text is
    checked: the layout does not depend on the format, and PNGs of every figure are checked
    by ``test_figures.py`` (drawing them here too doubled this test's cost)."""
    logs, meta = multi_run(optional=True)
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        paths = (plot_figures(logs, meta, tmp_path, formats=("svg",))
                 + fig_references(logs, meta, tmp_path, formats=("svg",)))
    names = ["fig2_tracking_errors", "fig3_force_tracking", "fig4_force_estimate",
             "fig5_aux_force_error", "fig6_observation_errors", "fig_force_errors",
             "fig7_velocity_estimate",
             "fig_references"]
    assert [p.name for p in paths] == [f"{n}.svg" for n in names]
    assert all(p.stat().st_size > 10_000 for p in paths)
    text = {n: _svg_text(tmp_path / f"{n}.svg") for n in names}
    # Fig. 6: 3 rows × 6 columns, robots 2 and 3 leave their panels 4–6 out.
    letters = [f"({c})" for c in "abcdefghijklmnopqr"]
    drawn = letters[:6] + letters[6:9] + letters[12:15]
    for name in ("fig6_observation_errors", "fig7_velocity_estimate"):
        assert all(x in text[name] for x in drawn)
        assert not any(x in text[name] for x in set(letters) - set(drawn))
    assert text["fig6_observation_errors"].count("[µrad]") == 12
    # Forces of two constraints: one line per row, labelled λ_1, λ_2.
    fig3 = text["fig3_force_tracking"]
    for label in ("measuredλ1", "measuredλ2", "desired(29)λd1", "desired(29)λd2"):
        assert fig3.count(label) == 2                                # robots 1 and 3
    assert fig3.count("measuredλdesired") == 1                       # robot 2 (m = 1)
    assert "(c)robot3" in fig3
    assert fig3.count("(squeeze)") == 1                              # robot 2 only (m = 1)
    # The references: one panel per robot, then the path (d) and λ_d (e), each robot labelled.
    assert all(f"({c})robot{i}" in text["fig_references"] for i, c in enumerate("abc", 1))
    assert "(d)pathinthe" in text["fig_references"] and "(e)desiredsqueeze" in text[
        "fig_references"]
    assert text["fig_references"].count("robot3") >= 3


@pytest.mark.parametrize("moving, plane", [((1, 2), (1, 2)), ((0, 1), (0, 1)), ((0, 2), (0, 2)),
                                           ((2,), (1, 2)), ((), (1, 2))])
def test_paths_are_drawn_in_the_plane_of_their_two_largest_extents(moving, plane):
    t = np.linspace(0.0, 10.0, 201)
    held = np.where(t >= 2.0, 20.0, 0.0)
    x_d = np.tile([0.6, 0.0, 0.5], (t.size, 1))
    x_d[t < 2.0, 0] = np.linspace(0.3, 0.6, (t < 2.0).sum())   # approach along x, not held
    for k, j in enumerate(moving):
        x_d[t >= 2.0, j] += (0.05 * (k + 1)) * np.sin(t[t >= 2.0])
    logs = {"r": {"x_d": x_d, "lambda_d": held}}
    assert path_plane(logs, ["r"]) == plane


# --- force arrows ----------------------------------------------------------------------------

def test_arrows_of_two_constraints_are_the_sum_of_the_normals_times_lambda():
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from drake_coop.control.reference_layout import ReferenceLayout
    from drake_coop.plant.arms import Arm
    from drake_coop.results.export import shared_meshcat
    from drake_coop.results.viz import ARROW_KINDS, ARROW_SCALE, ForceArrows
    from drake_coop.scenario import load_scenario
    from tests.results.test_viz import _last, _scene

    s = load_scenario("scenarios/six_joint.yaml")
    n1 = np.array([-1.0, 0.0, 0.0])
    n2 = np.array([0.0, 0.6, 0.8])
    robot6 = dataclasses.replace(s.robots[0], normals=[list(n1), list(n2)])
    arms = [Arm(robot6, s.task), Arm(s.robots[1], s.task)]
    meshcat = shared_meshcat()
    meshcat.Delete()
    b = DiagramBuilder()
    arrows = b.AddSystem(ForceArrows(meshcat, arms, n_joints=[6, 3]))
    simulator = Simulator(b.Build())
    ctx = arrows.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    q6 = np.array([0.0, 0.6, 1.2, 0.0, -0.2, 0.0])
    lambda_d, lambda_hat = np.array([30.0, -5.0]), np.array([28.0, 2.0])
    ref = np.r_[q6, np.zeros(12), lambda_d, 1.0]
    assert ref.size == ReferenceLayout(6, 2).size
    arrows.GetInputPort("robot1_state").FixValue(ctx, np.r_[q6, np.zeros(6)])
    arrows.GetInputPort("robot1_reference").FixValue(ctx, ref)
    arrows.GetInputPort("robot1_F_meas").FixValue(ctx, np.zeros(3))
    arrows.GetInputPort("robot1_lambda_hat").FixValue(ctx, lambda_hat)
    arrows.GetInputPort("robot2_state").FixValue(ctx, np.zeros(6))
    arrows.GetInputPort("robot2_reference").FixValue(ctx, np.zeros(11))
    arrows.GetInputPort("robot2_F_meas").FixValue(ctx, np.zeros(3))
    arrows.GetInputPort("robot2_lambda_hat").FixValue(ctx, [0.0])
    simulator.Initialize()
    scene = _scene(meshcat.StaticHtml())
    for kind, lam in (("desired", lambda_d), ("estimated", lambda_hat)):
        F = -(lam[0] * n1 + lam[1] * n2)       # the force on the object, −N_1ᵀ λ
        path = f"/drake/coop/forces/robot1/{kind}"
        M = np.array(_last(scene, "set_transform", path)["matrix"]).reshape(4, 4).T
        np.testing.assert_allclose(M[:3, 2], F / np.linalg.norm(F), atol=1e-12)
        head = np.array(_last(scene, "set_transform", f"{path}/head")["matrix"])
        assert head[14] == pytest.approx(ARROW_SCALE * math.sqrt(F @ F))
        tip = arms[0].fk(q6) + [0.0, 0.0, ARROW_KINDS[kind][1]]       # on the pad
        np.testing.assert_allclose(M[:3, 3], tip - ARROW_SCALE * F, atol=1e-12)
