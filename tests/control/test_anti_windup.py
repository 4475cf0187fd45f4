"""Anti-windup of the force integral (6) (``anti_windup: conditional``) against independent
computations: hand-computed ``ΔF̃`` sequences while clipped, bit-identity with the paper's (6)
when never clipped, the refusals, and (slow) the simulated truth on a saturated lift."""

import dataclasses
import hashlib
import json

import numpy as np
import pytest

from drake_coop.control.anti_windup import check_limits, clipped, force_integral_step
from drake_coop.control.block import build_control_block
from drake_coop.control.finger import FingerLaw
from drake_coop.control.momentum import MomentumObserver
from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.control.sources import SensedForce
from drake_coop.plant.arms import Arm, arm_model
from drake_coop.scenario.loading import default_scenario, load_scenario
from drake_coop.scenario.schema import ScenarioError
from drake_coop.studies.expand import case_hash

H = 0.009
LIMITS = np.array([4.0, 4.0, 4.0])


def _reference(lam_d, held=True):
    return np.concatenate([np.zeros(9), [lam_d], [float(held)]])


# The commanded torques of five ticks and whether each is clipped at LIMITS: a torque equal
# to its limit passes unclipped (as Drake's Saturation passes it).
TAUS = [([1.0, 1.0, 1.0], False), ([5.0, 0.0, 0.0], True), ([-4.0, 0.0, 4.0], False),
        ([0.0, 0.0, -4.5], True), ([0.0, 0.0, 0.0], False)]


def test_clipping_is_any_joint_beyond_its_limit():
    assert [clipped(np.array(t), LIMITS) for t, _ in TAUS] == [c for _, c in TAUS]
    assert not clipped(np.array([50.0, 0.0, 0.0]), None)        # no anti-windup


def test_the_sensor_loop_holds_its_integral_on_clipped_ticks():
    sf = SensedForce(H, ReferenceLayout(3, 1), anti_windup_limits=LIMITS)
    ctx = sf.CreateDefaultContext()
    sf.GetInputPort("lambda_sensor").FixValue(ctx, [30.0])
    sf.GetInputPort("reference").FixValue(ctx, _reference(25.0))
    seen = []
    for tau, _ in TAUS:
        sf.GetInputPort("tau").FixValue(ctx, tau)
        ctx.SetDiscreteState(sf.EvalUniquePeriodicDiscreteUpdate(ctx))
        seen.append(sf.GetOutputPort("Delta_F_tilde").Eval(ctx)[0])
    # h (30 − 25) = 0.045 N·s a tick, none on ticks 2 and 4.
    np.testing.assert_allclose(seen, [0.045, 0.045, 0.090, 0.090, 0.135], rtol=0, atol=1e-15)
    sf.GetInputPort("reference").FixValue(ctx, _reference(25.0, held=False))
    ctx.SetDiscreteState(sf.EvalUniquePeriodicDiscreteUpdate(ctx))
    assert sf.GetOutputPort("Delta_F_tilde").Eval(ctx)[0] == 0.0    # reset on release


def _momentum_ticks(obs, q, taus, lam_d=20.0):
    """ΔF̃ after each tick and λ̂ of each tick, an arm at rest at ``q``."""
    ctx = obs.CreateDefaultContext()
    obs.set_initial_state(ctx, q)
    obs.get_q_input_port().FixValue(ctx, q)
    obs.get_qdot_hat_input_port().FixValue(ctx, np.zeros(3))
    obs.get_reference_input_port().FixValue(ctx, _reference(lam_d))
    DF, lam = [], []
    for tau in taus:
        obs.get_tau_input_port().FixValue(ctx, tau)
        lam.append(obs.GetOutputPort("lambda_hat").Eval(ctx)[0])
        ctx.SetDiscreteState(obs.EvalUniquePeriodicDiscreteUpdate(ctx))
        DF.append(obs.GetOutputPort("Delta_F_tilde").Eval(ctx).copy())
        DF[-1] = np.concatenate([DF[-1], ctx.get_discrete_state(0).value()])  # [ΔF̃, σ]
    return np.array(DF), np.array(lam)


def _model():
    s = default_scenario()
    arm = Arm(s.robots[0], s.task)
    return arm_model(arm), arm.ik(arm.c)


def test_the_momentum_observer_holds_its_integral_on_clipped_ticks():
    model, q = _model()
    taus = [model.g(q) + np.array(t) for t, _ in TAUS]      # gravity plus the listed excess
    limits = np.abs(model.g(q)) + LIMITS                     # clipped where the excess is
    assert [bool(np.any(np.abs(t) > limits)) for t in taus] == [c for _, c in TAUS]
    obs = MomentumObserver(model, ReferenceLayout(3, 1), H, 50.0, anti_windup_limits=limits)
    states, lam = _momentum_ticks(obs, q, taus)
    assert np.all(np.abs(lam - 20.0) > 1.0)      # every unclipped tick moves ΔF̃
    expected, DF = [], 0.0
    for (_, is_clipped), lam_k in zip(TAUS, lam):
        DF = DF if is_clipped else DF + H * (lam_k - 20.0)
        expected.append(DF)
    np.testing.assert_allclose(states[:, 0], expected, rtol=0, atol=1e-12)
    assert states[1, 0] == states[0, 0] and states[3, 0] == states[2, 0]


def test_never_clipped_is_the_papers_integral_to_the_bit():
    rng = np.random.default_rng(3)
    model, q = _model()
    taus = model.g(q) + rng.uniform(-3.0, 3.0, (40, 3))
    plain = MomentumObserver(model, ReferenceLayout(3, 1), H, 50.0)
    limited = MomentumObserver(model, ReferenceLayout(3, 1), H, 50.0,
                               anti_windup_limits=np.abs(model.g(q)) + 3.5)
    np.testing.assert_array_equal(_momentum_ticks(plain, q, taus)[0],
                                  _momentum_ticks(limited, q, taus)[0])
    # The sensor loop: random readings, never clipped.
    readings = rng.uniform(20.0, 30.0, 40)
    out = []
    for limits in (None, [1e3, 1e3, 1e3]):
        sf = SensedForce(H, ReferenceLayout(3, 1), anti_windup_limits=limits)
        ctx = sf.CreateDefaultContext()
        sf.GetInputPort("reference").FixValue(ctx, _reference(25.0))
        seen = []
        for reading, tau in zip(readings, taus):
            sf.GetInputPort("lambda_sensor").FixValue(ctx, [reading])
            if limits is not None:
                sf.GetInputPort("tau").FixValue(ctx, tau)
            ctx.SetDiscreteState(sf.EvalUniquePeriodicDiscreteUpdate(ctx))
            seen.append(sf.GetOutputPort("Delta_F_tilde").Eval(ctx)[0])
        out.append(seen)
    np.testing.assert_array_equal(out[0], out[1])
    assert out[0][-1] != 0.0


def test_the_integral_step_is_6_or_held():
    DF, e = np.array([0.3, -0.2]), np.array([1.5, 4.0])
    np.testing.assert_array_equal(force_integral_step(DF, e, True, H), DF + H * e)
    held = force_integral_step(DF, e, True, H, frozen=True)
    np.testing.assert_array_equal(held, DF)
    assert held is not DF
    np.testing.assert_array_equal(force_integral_step(DF, e, False, H, frozen=True), [0, 0])


@pytest.mark.parametrize("limits", [[1.0, 2.0], [1.0, -2.0, 3.0], [1.0, np.nan, 3.0], "x"])
def test_bad_limits_are_refused_by_name(limits):
    with pytest.raises(ValueError, match="^anti_windup_limits: 3 torque limits > 0"):
        check_limits(limits, 3)


def test_the_block_wires_the_torque_and_refuses_sources_without_the_option():
    model, _ = _model()
    law = FingerLaw(model, default_scenario().robots[0].gains)
    diagram, _, force, ctrl = build_control_block("r", law, H, force_source="sensor",
                                                  anti_windup_limits=[5.0, 5.0, 5.0])
    assert force.HasInputPort("tau")
    # The block's context evaluates the force source's tau from the controller's output.
    context = diagram.CreateDefaultContext()
    ctrl_context = ctrl.GetMyContextFromRoot(context)
    ctrl_context.SetDiscreteState(0, np.array([1.0, -2.0, 3.0]))
    np.testing.assert_array_equal(
        force.GetInputPort("tau").Eval(force.GetMyContextFromRoot(context)), [1.0, -2.0, 3.0])
    plain = build_control_block("r", law, H, force_source="sensor")[2]
    assert not plain.HasInputPort("tau")
    with pytest.raises(ValueError, match="^anti_windup_limits: only for force_source "
                                         "'sensor' or 'momentum'"):
        build_control_block("r", law, H, force_source="observer",
                            anti_windup_limits=[5.0, 5.0, 5.0])


ROBOT2 = ("- {name: robot2, model: crs_a255, base_xyz: [1.16, 0, 0], base_yaw_deg: 180,"
          " contact_xy: [0.8192, 0], normals: [[1, 0, 0]], home: [0.9, 0, 0.6]}\n")


@pytest.mark.parametrize("entry, message", [
    ("force_source: momentum, anti_windup: windup, actuators: {torque_limits: [9, 9, 9]}",
     r"^robots\[0\]\.anti_windup must be null or one of conditional, back_calculation, "
     r"got 'windup'$"),
    ("force_source: sensor, anti_windup: conditional",
     r"^robots\[0\]\.anti_windup: conditional needs actuators\.torque_limits"),
    ("force_source: observer, anti_windup: conditional, actuators: {torque_limits: [9, 9, 9]}",
     r"^robots\[0\]\.anti_windup applies to force_source: sensor or momentum only"),
])
def test_a_bad_anti_windup_field_is_refused_in_one_line_naming_it(entry, message):
    text = "robots:\n- {name: robot1, " + entry + "}\n" + ROBOT2
    with pytest.raises(ScenarioError, match=message) as info:
        load_scenario(data=text)
    assert "\n" not in str(info.value)


def test_the_option_off_leaves_every_case_hash_as_before_the_field():
    s = default_scenario()
    data = dataclasses.asdict(s)
    for robot in data["robots"]:
        del robot["anti_windup"]          # the scenario as it was before the fields existed
        del robot["anti_windup_gain"]
    text = json.dumps(data, sort_keys=True, separators=(",", ":")) + "\n# t_end: 8.0\n"
    assert case_hash(s, 8.0) == hashlib.sha256(text.encode()).hexdigest()[:16]
    s.robots[0].actuators.torque_limits = [9.0, 9.0, 9.0]
    before = case_hash(s, 8.0)
    s.robots[0].anti_windup = "conditional"
    assert case_hash(s, 8.0) != before


def test_the_scenario_check_allows_the_modules_schemes():
    from drake_coop.control import anti_windup, registry

    robot = default_scenario().robots[0]
    robot.actuators.torque_limits = [9.0, 9.0, 9.0]
    for scheme in anti_windup.ANTI_WINDUP_SCHEMES:
        robot.anti_windup = scheme
        robot.anti_windup_gain = 10.0 if scheme == "back_calculation" else None
        registry.source("force", "sensor").check(robot, H)


@pytest.mark.parametrize("force_source", ["sensor", "momentum"])
def test_the_scenario_field_reaches_the_experiments_force_source(force_source):
    from drake_coop.experiment.diagram import build_experiment
    from drake_coop.experiment.plan import plan_run
    from tests.conftest import short_scenario

    scenario = short_scenario()
    for robot in scenario.robots:
        robot.force_source = force_source
    scenario.robots[0].actuators.torque_limits = [30.0, 30.0, 30.0]
    scenario.robots[0].anti_windup = "conditional"
    exp = build_experiment(plan_run(scenario), log=False)
    with_option, without = (rs.force_observer for rs in exp.robots)
    assert with_option._windup_limits.tolist() == [30.0, 30.0, 30.0]
    assert without._windup_limits is None
    assert with_option.HasInputPort("tau")


def test_a_real_arms_controller_side_uses_the_drivers_limits():
    from pydrake.lcm import DrakeLcm
    from pydrake.systems.framework import DiagramBuilder

    from drake_coop.experiment.plan import plan_run
    from drake_coop.robot.drivers import add_controller_side

    scenario = load_scenario()
    for robot in scenario.robots:      # (a real arm's driver gives no F/T reading)
        robot.force_source = "momentum"
    scenario.robots[0].actuators.torque_limits = [30.0, 25.0, 20.0]
    scenario.robots[0].anti_windup = "conditional"
    side = add_controller_side(DiagramBuilder(), plan_run(scenario, 1.0), DrakeLcm("memq://"))
    first, second = side.arms
    np.testing.assert_array_equal(first.block.force_source._windup_limits,
                                  first.spec.torque_limits)
    np.testing.assert_array_equal(first.spec.torque_limits, [30.0, 25.0, 20.0])
    assert second.block.force_source._windup_limits is None
