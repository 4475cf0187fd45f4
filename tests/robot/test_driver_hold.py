"""The simulated driver holds each arm as a real driver does
(:class:`~drake_coop.robot.torque_driver.TorqueDriver`): until that arm's own first command
by gravity compensation and damping (another arm's command releases nothing), and after the
last command (a ``serve`` that tripped, sent its safe command and stopped) the same once the
command expires: the arms come to rest, they do not fall. On the paper's arms, in one
process (``memq://``), the commands written here."""

import numpy as np
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from drake_coop.experiment.plan import plan_run
from drake_coop.robot.driver_spec import torque_command_message
from drake_coop.robot.drivers import add_driver_side
from drake_coop.robot.loopback import initialize_sides
from drake_coop.robot.torque_driver import DriverClock
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.driver import Driver

ORIGIN = 1_700_000_000_000_000


def driver_run(scenario, t_end, commands, v0=None):
    """The driver side alone for ``t_end`` s; ``commands(t)`` gives, every 9 ms, each arm's
    wire torque or None (no command). Returns each arm's logged state (ticks × 2n)."""
    plan = plan_run(scenario, t_end)
    lcm = DrakeLcm("memq://")
    builder = DiagramBuilder()
    side = add_driver_side(builder, plan, lcm, clock=DriverClock("epoch", origin=ORIGIN))
    logs = [LogVectorOutput(side.coop.plant.get_state_output_port(a.instance), builder,
                            publish_period=plan.h) for a in side.coop.arms]
    sim = Simulator(builder.Build())
    ctx = sim.get_mutable_context()
    initialize_sides(plan, ctx, side, None)
    plant = side.coop.plant
    pctx = plant.GetMyMutableContextFromRoot(ctx)
    if v0 is not None:
        for a in side.coop.arms:
            plant.SetVelocities(pctx, a.instance, v0)
    sim.Initialize()
    t = 0.0
    while t < t_end - 1e-12:
        for arm, tau in zip(side.arms, commands(t)):
            if tau is not None:
                msg = torque_command_message(tau, ORIGIN + int(round(t * 1e6)))
                lcm.Publish(arm.spec.command_channel, msg.encode())
        lcm.HandleSubscriptions(0)
        t = min(t_end, t + plan.h)
        sim.AdvanceTo(t)
    return [log.FindLog(ctx).data().T for log in logs], side


def paper(**driver):
    s = load_scenario()
    for robot in s.robots:
        robot.driver = Driver(**driver)
    return load_scenario(data=dump_scenario(s))


def test_an_arm_is_held_until_its_own_first_command():
    """robot1 commanded from the start (zero on the wire: the robot's own gravity
    compensation), robot2 never: robot2 stays where it was, to a micro-radian."""
    s = paper()
    states, _ = driver_run(s, 0.5, lambda t: [np.zeros(3), None])
    q2 = states[1][:, :3]
    assert np.max(np.abs(q2 - q2[0])) < 1e-6
    # the same arm with no gravity compensation (a driver giving zero torque) falls
    fall, _ = driver_run(s, 0.5, lambda t: [np.zeros(3), None if t < 0.3 else np.zeros(3)])
    assert np.max(np.abs(fall[1][:, :3] - q2[0])) < 1e-6     # (held until its own command)
    plain = paper(gravity="none", safe_command="hold")
    dropped, _ = driver_run(plain, 0.5, lambda t: [np.zeros(3), np.zeros(3)])
    assert np.max(np.abs(dropped[1][:, :3] - q2[0])) > 1e-2   # zero torque on the arm: falls


def test_after_the_last_command_the_arms_come_to_rest():
    """Both arms moving at 0.3 rad/s on every joint; the safe command (zero on the wire) for
    50 ms, then nothing: 0.1 s later the command expires and gravity compensation and damping
    (2.5 N·m·s/rad on these 3-joint arms) bring the arms to rest; they do not fall."""
    s = paper()
    v0 = np.full(3, 0.3)
    states, side = driver_run(s, 3.0, lambda t: [np.zeros(3)] * 2 if t < 0.05 else [None] * 2,
                              v0=v0)
    for x in states:
        v = x[:, 3:]
        assert np.max(np.abs(v[-1])) < 0.05 * 0.3            # at rest at the end
        assert np.max(np.abs(x[-1, :3] - x[0, :3])) < 1.0     # not fallen to the stops
    assert side.arms[0].spec.command_timeout == 0.1
