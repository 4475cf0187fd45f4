"""The scenario's ``object_model:`` section: its checks (CLI exit 2 naming the field), the
blocks it adds to the experiment's diagram, the references it changes, a short run's logs."""

from __future__ import annotations

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.experiment.plan import plan_run
from drake_coop.scenario import ObjectModelSettings, Scenario, load_scenario, validate
from drake_coop.scenario.resources import shipped_scenarios
from tests.conftest import short_scenario

CONTACT = "plant: {object_mode: contact, object_mass: 0.5, friction: 1.0, time_step: 0.003}\n"


@pytest.mark.parametrize("section, field", [
    ("{mode: known, mass: -1}", "object_model.mass"),
    ("{mode: known, mu: 0}", "object_model.mu"),
    ("{mode: estimated, mu: -0.5}", "object_model.mu"),
    ("{mode: bogus}", "object_model.mode"),
    ("{mode: known, squeeze: tight}", "object_model.squeeze"),
    ("{squeeze: friction}", "object_model.squeeze"),
    ("{mode: estimated, prior_mass_factor: 0}", "object_model.prior_mass_factor"),
    ("{mode: known, margin: 0.5}", "object_model.margin"),
    ("{mode: known, colour: red}", "object_model.colour"),
    ("{mode: estimated, squeeze: friction, shared: 1}", "object_model.shared"),
    ("{mode: estimated, shared: true}", "object_model.shared"),
    ("{shared: true}", "object_model.shared"),
    ("{mode: estimated, squeeze: friction, shared: true, squeeze_rate: 0}",
     "object_model.squeeze_rate"),
    ("{mode: known, control_point: middle}", "object_model.control_point"),
    ("{control_point: contact}", "object_model.control_point"),
])
def test_bad_object_model_fields_exit_2_naming_the_field(tmp_path, capsys, section, field):
    path = tmp_path / "bad.yaml"
    path.write_text(CONTACT + f"object_model: {section}\n")
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and field in err and "Traceback" not in err


def test_none_is_the_default_everywhere():
    assert Scenario().object_model == ObjectModelSettings()
    assert ObjectModelSettings().mode == "none"
    from drake_coop.scenario.description import ROBOTS_EXTRA
    from drake_coop.scenario.schema import ScenarioError

    for name, path in shipped_scenarios().items():
        try:
            scenario = load_scenario(path)
        except ScenarioError as error:      # a lab-arm scenario without the robots extra
            assert ROBOTS_EXTRA in str(error), error
            assert "object_model" not in path.read_text(), name
            continue
        assert scenario.object_model.mode == "none", name


def _blocks(scenario):
    from drake_coop.experiment.diagram import build_experiment
    exp = build_experiment(plan_run(scenario))
    return {exp.diagram.GetSubsystemByName(n).get_name() for n in (
        s.get_name() for s in exp.diagram.GetSystems())}


def test_the_blocks_appear_in_the_diagram_only_with_an_object_model():
    s = short_scenario("rigid")
    names = _blocks(s)
    assert not any("feedforward" in n or "mass_" in n or "tau_sum" in n for n in names)
    s.object_model.mode = "known"
    names = _blocks(s)
    assert {"robot1_load_feedforward", "robot1_tau_sum", "robot1_mass_share",
            "robot2_load_feedforward"} <= names
    assert "robot1_mass_estimator" not in names
    s.object_model.mode = "estimated"
    names = _blocks(s)
    assert {"robot1_mass_estimator", "robot2_mass_estimator"} <= names
    assert not any("object_state" in n or "compressed" in n for n in names)
    s.object_model.squeeze, s.object_model.shared = "friction", True
    names = _blocks(s)
    assert "object_state_estimator" in names          # one block between the arms
    assert not any("compressed" in n for n in names)  # rigid: nothing to press in
    s.object_model.mode = "known"                     # the constant shares feed it too
    assert {"object_state_estimator", "robot1_mass_share"} <= _blocks(s)


def test_the_shared_block_is_one_block_between_the_arms_and_feeds_their_references():
    """contact + estimated + shared: one object_state_estimator reads both mass estimators
    and a_d, and each arm's control block, feedforward and log read its reference through
    it (and the compliant contact's online compression)."""
    from drake_coop.experiment.diagram import build_experiment
    s = load_scenario(data=CONTACT + "object_model: {mode: estimated, squeeze: friction, "
                      "shared: true}\n")
    exp = build_experiment(plan_run(s))
    d = exp.diagram
    shared = exp.object_state_estimator
    assert shared is d.GetSubsystemByName("object_state_estimator")
    est = [d.GetSubsystemByName(f"robot{i}_mass_estimator") for i in (1, 2)]
    conn = {(dst.get_name(), dst.get_input_port(int(i)).get_name()):
            (src.get_name(), src.get_output_port(int(o)).get_name())
            for (dst, i), (src, o) in d.connection_map().items()}
    for i, e in enumerate(est):
        assert conn[("object_state_estimator", f"mass_share_{i}")] == (e.get_name(),
                                                                       "mass_share")
        assert conn[(f"robot{i + 1}_compressed_reference", "reference")] == (
            "object_state_estimator", f"reference_out_{i}")
        assert conn[(f"robot{i + 1}_control", "reference")] == (
            f"robot{i + 1}_compressed_reference", "compressed_reference")
    assert conn[("object_state_estimator", "acceleration_d")] == ("robot1_acceleration_d",
                                                                   "y0")


def test_a_compliant_contact_presses_the_joint_references_in():
    """With an object model in contact mode, q_d puts the pad δ(λ_d) inside the undeformed
    face along the inward normal, δ the root of the sphere's law λ = π E (δ² − 2δ³/(3r))
    with the pads' E = 5 MPa, r = 15 mm (urdf/README.md); the force profile is (29) in the
    circle, and never below it (the grasp's ramp, the least squeeze that holds the box,
    RunPlan.squeeze) outside the ramps (the pads' centres followed: control_point centre)."""
    from drake_coop.control.reference_layout import ReferenceLayout
    base = load_scenario(data=CONTACT)
    known = load_scenario(data=CONTACT + "object_model: {mode: known, control_point: centre}\n")
    for i in range(2):
        t, r0 = plan_run(base, 30.0).robots[i].samples
        _, r1 = plan_run(known, 30.0).robots[i].samples
        layout = ReferenceLayout(3, 1)
        arm = plan_run(base).arms[i]
        lam = layout.column(r0, "lambda_d")[:, 0]
        circle = t >= 25.0
        assert np.array_equal(lam[circle], layout.column(r1, "lambda_d")[circle, 0])
        lift = (t >= 16.0) & (t < 25.0)
        assert np.all(layout.column(r1, "lambda_d")[lift, 0] >= lam[lift])
        k = np.searchsorted(t, 27.0)
        x0 = arm.fk(layout.column(r0, "q_d")[k:k + 1])[0]
        x1 = arm.fk(layout.column(r1, "q_d")[k:k + 1])[0]
        inward = -np.asarray(base.robots[i].normals[0], dtype=float)
        r = 0.015
        roots = np.roots([-2.0 / (3.0 * r), 1.0, 0.0, -lam[k] / (np.pi * 5e6)])
        delta = min(z.real for z in roots if abs(z.imag) < 1e-12 and 0 < z.real < r)
        assert np.allclose(x1 - x0, delta * inward, atol=1e-9)


def test_friction_squeeze_is_the_cone_bound_times_the_margin():
    """squeeze: friction at the circle's start (zero acceleration): each pad carries m g / 2
    tangentially, so λ_d = margin · m g / (2 μ)."""
    from drake_coop.control.reference_layout import ReferenceLayout
    s = load_scenario(data=CONTACT.replace("friction: 1.0", "friction: 0.6") +
                      "object_model: {mode: known, squeeze: friction, margin: 1.4}\n")
    t, r = plan_run(s, 26.0).robots[0].samples
    lam = ReferenceLayout(3, 1).column(r, "lambda_d")[:, 0]
    k = int(np.argmin(abs(t - 25.0)))
    assert np.isclose(lam[k], 1.4 * 0.5 * 9.81 / (2 * 0.6), rtol=1e-9)
    assert lam[np.searchsorted(t, 5.0)] == 0.0          # not held


def _sphere_compression(lam, E=5e6, r=0.015):
    """δ of Drake's hydroelastic sphere on a rigid face, λ = π E (δ² − 2δ³/(3r)), by the
    cubic's roots (independent of ContactStiffness)."""
    if lam <= 0.0:
        return 0.0
    roots = np.roots([-2.0 / (3.0 * r), 1.0, 0.0, -lam / (np.pi * E)])
    return min(z.real for z in roots if abs(z.imag) < 1e-12 and 0 < z.real < r)


@pytest.mark.parametrize("squeeze", ["profile", "friction"])
def test_the_squeeze_holds_the_box_by_the_ramps_end_pressing_the_pads_in_along_the_quintic(
        squeeze):
    """A grasp held by friction on compliant pads: the hold λ_hold (two opposing pads at rest
    each carry m (g + a_z) / 2 across their normal, so λ_hold = margin · m (g + a_z) / (2 μ), a
    hand static balance) is brought in by σ(τ)² (the quintic over 1 s, squared: the pads'
    law's exponent): with ``friction`` λ_d = λ_hold σ², so each pad's compression δ(λ_d) is
    δ(λ_hold) σ, the quintic itself (rate zero at the grasp, where a linear rise gives
    δ ∝ √t); with ``profile`` λ_d = max((29), λ_hold σ²). By the ramp's end λ_d holds the
    prior's weight in the cone; in the circle the shipped box's (29) is above the hold."""
    from drake_coop.scenario.task_path import cartesian_reference, force_reference, quintic

    s = load_scenario(data=CONTACT.replace("friction: 1.0", "friction: 0.6")
                      + f"object_model: {{mode: estimated, squeeze: {squeeze}}}\n")
    plan = plan_run(s)
    task, om = s.task, s.object_model
    hold = om.margin * om.prior_mass_factor * 0.5 * 9.81 / (2 * 0.6)
    t_g = task.t_grasp
    assert plan.squeeze(np.array([t_g + 1.0]))[0] >= hold * (1 - 1e-9)
    for tau in (0.1, 0.3, 0.5, 0.8):
        t = np.array([t_g + tau])
        lam = plan.squeeze(t)[0]
        a_z = cartesian_reference(task, s.robots[0], t)[2][0, 2]
        sigma = quintic(np.array([tau]))[0][0]
        held = hold * (9.81 + a_z) / 9.81 * sigma ** 2
        if squeeze == "profile":
            assert lam == pytest.approx(max(force_reference(task, t)[0], held), rel=1e-9)
            continue
        assert lam == pytest.approx(held, rel=1e-9)
        # The sphere's exact law: δ along the quintic within its δ³/r term (δ ≤ 0.8 mm,
        # r = 15 mm: a few percent).
        assert _sphere_compression(lam) == pytest.approx(
            _sphere_compression(held / sigma ** 2) * sigma, rel=0.03)
    if squeeze == "friction":
        # The compression at the grasp: δ(ε) = O(ε³), not a linear rise's O(√ε).
        eps = 1e-3
        assert _sphere_compression(plan.squeeze(np.array([t_g + eps]))[0]) < 1e-8
        assert _sphere_compression(hold * eps) > 1e-6
    else:
        t = np.array([30.0, 45.0, 60.0])
        np.testing.assert_array_equal(plan.squeeze(t), force_reference(task, t))
    assert plan.squeeze(np.array([t_g - 0.01, task.t_release + 0.01])).tolist() == [0.0, 0.0]


def test_a_heavy_box_lifts_the_profile_squeeze_to_the_hold_and_no_model_keeps_29():
    """On a box (29) cannot hold (2 kg at μ 0.4: the prior's 3 kg needs 1.5 · 3 · 9.81 /
    (2 · 0.4) = 55 N), λ_d is the hold wherever (29) is below it; without an object model,
    and in the rigid mode, λ_d stays (29) exactly (the paper's run)."""
    from drake_coop.scenario.task_path import cartesian_reference, force_reference

    heavy = CONTACT.replace("object_mass: 0.5", "object_mass: 2.0").replace(
        "friction: 1.0", "friction: 0.4")
    plan = plan_run(load_scenario(data=heavy + "object_model: {mode: estimated}\n"))
    t = np.array([25.0, 45.0, 60.0])
    a = cartesian_reference(plan.scenario.task, plan.scenario.robots[0], t)[2]
    # Each pad carries m (a − g) / 2 across its normal (x): its y, z parts.
    need = 3.0 / 2 * np.hypot(a[:, 1], 9.81 + a[:, 2]) / 0.4
    np.testing.assert_allclose(plan.squeeze(t), 1.5 * need, rtol=1e-9)
    assert need[0] == pytest.approx(3.0 * 9.81 / (2 * 0.4))     # the circle's start: at rest
    tt = np.linspace(0.0, 90.0, 9001)
    for data in (heavy, heavy.replace("contact", "rigid") + "object_model: {mode: known}\n"):
        plan = plan_run(load_scenario(data=data))
        np.testing.assert_array_equal(plan.squeeze(tt), force_reference(plan.scenario.task, tt))


@pytest.mark.slow
def test_a_short_rigid_run_estimates_the_mass_and_logs_the_new_signals():
    from drake_coop.experiment.simulate import simulate
    s = short_scenario("rigid")
    s.object_model.mode = "estimated"
    validate(s)
    res = simulate(s)
    assert res.ok
    logs = res.logs
    t = logs["robot1"]["t"]
    for name in ("robot1", "robot2"):
        assert {"tau_ff", "f_load", "mass_share"} <= set(logs[name])
    total = logs["robot1"]["mass_share"] + logs["robot2"]["mass_share"]
    # The prior is 1.5 × 0.5 kg; by the end of the circle (6 s) within 5 % of the truth.
    assert total[np.searchsorted(t, 1.0)] == pytest.approx(0.75)
    assert total[np.searchsorted(t, 5.9)] == pytest.approx(0.5, rel=0.05)
    # Nothing fed forward before the grasp.
    assert np.all(logs["robot1"]["tau_ff"][t < 0.99] == 0.0)


def test_an_object_model_needs_a_held_object(tmp_path, capsys):
    path = tmp_path / "planes.yaml"
    path.write_text("object_model: {mode: known}\n")       # the paper's planes: no object
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "object_model.mode" in capsys.readouterr().err


def test_a_short_shared_contact_run_against_the_plant():
    """contact, estimated, shared, the phases compressed (grasp at 1 s, circle 3-5 s): the
    shared total mass against the plant's box body, the online squeeze against the cone
    inequality at the true load (m g / 2 per pad, μ of the plant), and the plant's contact
    results: no drop, no slip, the pads inside their cones."""
    from drake_coop.experiment.simulate import simulate
    from drake_coop.results.metrics import compute_metrics
    s = load_scenario(data=CONTACT.replace("0.5,", "0.8,").replace("1.0,", "0.7,") +
                      "object_model: {mode: estimated, squeeze: friction, shared: true}\n")
    for key, value in dict(t_pregrasp=0.5, t_grasp=1.0, t_circle_start=3.0,
                           t_circle_end=5.0, t_release=6.0, t_end=7.0).items():
        setattr(s.task, key, value)
    validate(s)
    result = simulate(s, t_end=5.0)
    assert result.ok
    coop = result.experiment.coop              # the plant that ran (not built a second time)
    plant = coop.plant
    box = coop.grasp.box
    m_true = box.default_mass() if hasattr(box, "default_mass") else box.get_default_mass()
    assert m_true == pytest.approx(0.8)
    logs = result.logs
    t = logs["robot1"]["t"]
    k = np.searchsorted(t, 4.9)
    total = logs["robot1"]["mass_share"][k] + logs["robot2"]["mass_share"][k]
    assert total == pytest.approx(m_true, rel=0.05)
    lam_d = logs["robot1"]["lambda_d"][k]
    assert np.array_equal(lam_d, logs["robot2"]["lambda_d"][k])        # one shared squeeze
    hold = m_true * 9.81 / 2 / 0.7                  # the least squeeze at the true load
    assert hold < lam_d < 1.6 * hold               # inside the cone, near the margin 1.5
    metrics = compute_metrics(result.logs, result.meta)
    for robot in metrics:
        for phase in ("lift", "circle"):
            assert metrics[robot][phase]["drops"]["count"] == 0
            assert metrics[robot][phase]["slips"]["count"] == 0
        assert metrics[robot]["circle"]["friction_use"]["max"] < 1.0
    del plant
