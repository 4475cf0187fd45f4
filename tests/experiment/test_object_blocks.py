"""The squeeze's couple in a run (``object_model.couple``): which scenarios use it,
the samples each arm gets (against the moment balance by hand, on the pads' centres from
Drake's kinematics and the box's width), and the blocks it adds to the diagram."""

from __future__ import annotations

import numpy as np
import pytest

from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.experiment.object_blocks import couple_samples
from drake_coop.experiment.plan import plan_run
from drake_coop.scenario import load_scenario
from drake_coop.scenario.resources import find_scenario

CONTACT = "plant: {object_mode: contact, object_mass: 0.5, friction: 1.0, time_step: 0.003}\n"


def uses_couple(scenario) -> bool:
    return plan_run(scenario).uses_couple


def test_the_couple_is_used_where_the_pads_follow_their_contact_points():
    known = load_scenario(data=CONTACT + "object_model: {mode: known}\n")
    assert uses_couple(known)
    assert uses_couple(load_scenario(data=CONTACT + "object_model: {mode: estimated}\n"))
    assert not uses_couple(load_scenario(data=CONTACT))                      # the paper's
    assert not uses_couple(load_scenario(
        data=CONTACT + "object_model: {mode: known, couple: false}\n"))
    assert not uses_couple(load_scenario(
        data=CONTACT + "object_model: {mode: known, control_point: centre}\n"))
    assert uses_couple(load_scenario(
        data=CONTACT + "object_model: {mode: known, control_point: centre, couple: true}\n"))
    rigid = load_scenario(find_scenario("rigid"))
    rigid.object_model.mode = "estimated"
    assert not uses_couple(rigid)


def test_each_arm_gets_its_part_of_the_moment_balance_along_the_references():
    """f_c,1 = −f_c,2 = −λ_d (T (E_1 − E_2)) / w: the pads' centres E_i from Drake's
    kinematics of the arms' models at both references' q_d, w the box's width
    ``b_2 − b_1 − 2ρ`` (the faces the pads touch, whatever their compression); zero
    before the grasp."""
    from drake_coop.plant.arms import arm_model

    s = load_scenario(data=CONTACT + "object_model: {mode: known}\n")
    plan = plan_run(s, 30.0)
    trajectories = [robot.reference for robot in plan.robots]
    t = np.linspace(10.0, 30.0, 81)
    f = [couple_samples(plan, i, t) for i in range(2)]
    layout = ReferenceLayout(3, 1)
    r = [np.asarray(tr.vector_values(t)).T for tr in trajectories]
    E = [np.array([arm_model(arm, closed_form=False).ee_position(q)
                   for q in layout.column(ri, "q_d")]) for arm, ri in zip(plan.arms, r)]
    lam = layout.column(r[0], "lambda_d")[:, 0] * r[0][:, -1]
    width = s.robots[1].contact_xy[0] - s.robots[0].contact_xy[0] - 2 * 0.015
    expected = np.zeros((len(t), 3))
    expected[:, 1:] = -(lam / width)[:, None] * (E[0] - E[1])[:, 1:]
    np.testing.assert_allclose(f[0], expected, rtol=0, atol=1e-7)   # q_d between ticks
    np.testing.assert_allclose(f[1], -f[0], rtol=0, atol=1e-15)
    assert np.all(f[0][t < s.task.t_grasp] == 0.0)
    assert np.abs(f[0][:, 2]).max() > 0.1       # the pads' centres leave one height: it matters


@pytest.mark.parametrize("couple, present", [(None, True), (False, False)])
def test_the_couple_source_feeds_both_blocks(couple, present):
    from drake_coop.experiment.diagram import build_experiment

    s = load_scenario(data=CONTACT + "object_model: {mode: estimated}\n")
    s.object_model.couple = couple
    s.task.t_end = 16.0
    exp = build_experiment(plan_run(s))
    names = {system.get_name() for system in exp.diagram.GetSystems()}
    assert ("robot1_f_couple" in names) == present
    assert ("robot2_f_couple" in names) == present
    ff = exp.diagram.GetSubsystemByName("robot1_load_feedforward")
    assert (ff.num_input_ports() == 5) == present
    # The friction limit keeps the grasp's margin: at most μ λ_d / margin = 1.0 · 3 / 1.5 N
    # across the normal (x here).
    assert ff.friction_limited(np.array([0.0, 0.0, 10.0]), np.array([3.0])) \
        == pytest.approx([0.0, 0.0, 2.0])


@pytest.mark.parametrize("value", ["maybe", "3"])
def test_a_bad_couple_exits_2_naming_it(tmp_path, capsys, value):
    from drake_coop.cli import main

    path = tmp_path / "bad.yaml"
    path.write_text(CONTACT + f"object_model: {{mode: known, couple: {value}}}\n")
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "couple" in err and "Traceback" not in err
