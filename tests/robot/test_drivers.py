"""The controller side over LCM (``memq://`` only): the blocks read the driver's measured
position only; the watchdog's safe command reaches the wire within one tick; never a NaN on
the wire; the simulated driver's command hold and timeout."""

import copy
import math
import time

import numpy as np
import pytest
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from drake import lcmt_panda_command, lcmt_panda_status
from drake_coop.control.watchdog import TRIP_REASONS
from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.simulate import rest_posture
from drake_coop.robot.drivers import COMMAND_OFFSET, add_controller_side
from drake_coop.robot.driver_spec import safe_command_message
from drake_coop.robot.loopback import initialize_sides
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.driver import Driver


@pytest.fixture(scope="module")
def scenario():
    return load_scenario()


def status(q, k, h, rng=None):
    msg = lcmt_panda_status()
    n = len(q)
    msg.utime = int(round(k * h * 1e6))
    msg.num_joints = n
    msg.joint_position = [float(v) for v in q]
    extra = (lambda: list(rng.normal(size=n) * 50.0)) if rng is not None else (lambda: [0.0] * n)
    msg.joint_velocity = extra()
    msg.joint_torque = extra()
    msg.joint_torque_external = extra()
    msg.joint_position_desired = extra()
    msg.joint_velocity_desired = extra()
    msg.joint_acceleration_desired = extra()
    msg.joint_torque_desired = extra()
    msg.control_command_success_rate = 1.0
    return msg


def run_controller(scenario, positions, rng=None, ticks=6, stop_after=None, start_at=0):
    """The controller side alone; the test plays the driver: one status per arm per tick
    (``positions(i, k)``), from tick ``start_at`` until ``stop_after``. Returns the commands
    per tick and the watchdogs' reasons at the end."""
    plan = plan_run(scenario, 1.0)
    lcm = DrakeLcm("memq://")
    builder = DiagramBuilder()            # pumped here between ticks, as serve does
    side = add_controller_side(builder, plan, lcm)
    commands = {a.spec.robot: [] for a in side.arms}
    for a in side.arms:
        lcm.Subscribe(a.spec.command_channel,
                      lambda data, name=a.spec.robot: commands[name].append(
                          lcmt_panda_command.decode(data)))
    sim = Simulator(builder.Build())
    ctx = sim.get_mutable_context()
    q0, _ = rest_posture(plan)
    initialize_sides(plan, ctx, None, side, q0)

    def publish(k):
        for i, a in enumerate(side.arms):
            lcm.Publish(a.spec.status_channel, status(positions(i, k, q0[i]), k, plan.h,
                                                      rng).encode())

    if start_at == 0:
        publish(0)
    lcm.HandleSubscriptions(0)
    sim.Initialize()
    sim.AdvanceTo(COMMAND_OFFSET)
    for k in range(1, ticks):
        if k >= start_at and (stop_after is None or k <= stop_after):
            publish(k)
        lcm.HandleSubscriptions(0)
        sim.AdvanceTo(k * plan.h + COMMAND_OFFSET)
    lcm.HandleSubscriptions(0)
    reasons = {a.spec.robot: a.watchdog.reason(a.watchdog.GetMyContextFromRoot(ctx))
               for a in side.arms}
    return commands, reasons


def moving(i, k, q0):
    return q0 + 1e-3 * k * np.array([1.0, -0.5, 0.8])


def torques(commands):
    return {name: np.array([m.joint_torque for m in msgs]) for name, msgs in commands.items()}


def test_the_blocks_read_the_measured_position_only(scenario):
    a, _ = run_controller(scenario, moving, np.random.default_rng(1))
    b, _ = run_controller(scenario, moving, np.random.default_rng(2))
    ta, tb = torques(a), torques(b)
    for name in ta:
        assert ta[name].shape == (6, 3)
        # (tick 0 at rest: the controller's torque is g(q0), zero on the wire of a robot
        # that adds gravity itself)
        assert np.all(np.any(ta[name][1:] != 0.0, axis=1))
        np.testing.assert_array_equal(ta[name], tb[name])   # velocity, torque fields ignored
    # the same test can fail: a different position changes the command
    c, _ = run_controller(scenario, lambda i, k, q0: moving(i, k, q0) + 1e-6,
                          np.random.default_rng(1))
    assert not np.array_equal(torques(c)["robot1"], ta["robot1"])


def with_driver(scenario, **fields):
    s = copy.deepcopy(scenario)
    for robot in s.robots:
        robot.driver = Driver(**fields)
    return load_scenario(data=dump_scenario(s))


def test_commands_are_torque_mode_and_one_per_tick(scenario):
    """A driver that says its clock is the run's (``time_base: run``): stamped with the
    Diagram's time, as Drake's PandaCommandSender does."""
    commands, reasons = run_controller(with_driver(scenario, time_base="run"), moving)
    for msgs in commands.values():
        assert [m.utime for m in msgs] == [int(round((k * 0.009 + COMMAND_OFFSET) * 1e6))
                                           for k in range(6)]
        assert all(m.control_mode_expected == lcmt_panda_status.CONTROL_MODE_TORQUE
                   and m.num_joint_torque == 3 for m in msgs)
    assert set(reasons.values()) == {""}


def test_commands_are_stamped_with_the_drivers_wall_clock_by_default(scenario):
    """The default driver (drake-franka-driver's clock, ``time_base: epoch``): every command's
    utime is the wall clock's µs since the Unix epoch when it was sent, not the run's time
    (which such a driver would drop as older than its expiry)."""
    before = time.time() * 1e6
    commands, _ = run_controller(scenario, moving)
    after = time.time() * 1e6
    for msgs in commands.values():
        stamps = [m.utime for m in msgs]
        assert len(stamps) == 6 and all(before <= u <= after for u in stamps), stamps
        assert stamps == sorted(stamps)


def test_the_wire_carries_tau_minus_gravity_for_a_robot_that_adds_it(scenario):
    """``gravity: robot_adds`` against ``none`` on the same readings: the two commands differ
    by the controller model's g(q) at the tick's reading, computed here independently from
    the arm's URDF (Drake's gravity generalized forces of a plant of the arm alone)."""
    from drake_coop.plant.model_error import controller_arm_model
    from drake_coop.plant.cooperative import build_plant

    adds, _ = run_controller(scenario, moving)
    plain, _ = run_controller(with_driver(scenario, gravity="none", safe_command="hold"),
                              moving)
    plan = plan_run(scenario, 1.0)
    coop = build_plant(DiagramBuilder(), plan)
    q0, _ = rest_posture(plan)
    for i, name in enumerate(["robot1", "robot2"]):
        model = controller_arm_model(coop.arms[i].arm, None)
        plant = model.plant
        ctx = plant.CreateDefaultContext()
        d = torques(plain)[name] - torques(adds)[name]
        for k in range(1, 6):               # tick k reads the status of tick k (see above)
            plant.SetPositions(ctx, moving(i, k, q0[i]))
            g = -plant.CalcGravityGeneralizedForces(ctx)
            np.testing.assert_allclose(d[k], g, rtol=0, atol=1e-9)
        assert np.abs(d[1:]).max() > 1.0     # a real difference: gravity is not small


def test_a_nan_reading_sends_zero_torque_at_that_tick_and_never_a_nan(scenario):
    def nan_at_3(i, k, q0):
        q = moving(i, k, q0)
        if i == 0 and k >= 3:
            q[1] = math.nan
        return q

    commands, reasons = run_controller(scenario, nan_at_3)
    t = torques(commands)
    assert np.all(np.isfinite(t["robot1"])) and np.all(np.isfinite(t["robot2"]))
    assert np.all(np.any(t["robot1"][1:3] != 0.0, axis=1))     # (tick 0 at rest: g(q0))
    np.testing.assert_array_equal(t["robot1"][3:], 0.0)
    assert reasons["robot1"] == "malformed status: non-finite joint position in the status"


def test_a_status_that_stops_arriving_sends_zero_torque_within_one_tick(scenario):
    h, max_age = 0.009, 0.05          # the Driver default
    last = 2
    commands, reasons = run_controller(scenario, moving, ticks=11, stop_after=last)
    k_trip = next(k for k in range(last, 20) if (k - last) * h > max_age)   # independent
    t = torques(commands)["robot1"]
    assert np.all(np.any(t[1:k_trip] != 0.0, axis=1))     # (tick 0 at rest: g(q0))
    np.testing.assert_array_equal(t[k_trip:], 0.0)
    assert reasons["robot1"] == TRIP_REASONS[1]


def test_safe_command_message_is_finite_and_limited():
    from drake_coop.robot.driver_spec import DriverSpec

    spec = DriverSpec("r", "panda", "S", "C", 3, 1e-3, np.array([1.0, 2.0, 3.0]), 0.05, 0.05,
                      "zero_torque")
    msg = safe_command_message(spec, np.array([math.nan, -5.0, 0.5]), 7)
    assert msg.joint_torque == [0.0, -2.0, 0.5] and msg.num_joint_torque == 3
    assert list(lcmt_panda_command.decode(msg.encode()).joint_torque) == [0.0, -2.0, 0.5]


def test_no_controller_torque_leaves_before_the_first_status(scenario):
    """No status for the first three ticks (27 ms < max_status_age): the wire carries zero
    torque, then the controller's from the tick the first status arrives."""
    commands, reasons = run_controller(scenario, moving, ticks=8, start_at=3)
    for name, tau in torques(commands).items():
        assert tau.shape == (8, 3)
        np.testing.assert_array_equal(tau[:3], 0.0)
        assert np.all(np.any(tau[3:] != 0.0, axis=1))
        assert np.all(np.abs(tau) <= 2000.0)         # the URDF's effort limits
    assert set(reasons.values()) == {""}
