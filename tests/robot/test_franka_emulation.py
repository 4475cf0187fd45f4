"""drake-franka-driver's torque mode, point by point from its published source
(``franka_driver.cc``, ``DoTorqueControl`` and ``PublishRobotState``; libfranka's control
loop as the driver calls it), against :class:`~drake_coop.robot.torque_driver.TorqueDriver`
with ``emulate="drake-franka-driver"``: one arm, its state and command fixed by the test, the
robot's ``g(q)`` a function written here."""

import math

import numpy as np
import pytest
from pydrake.common.value import AbstractValue
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator

from drake import lcmt_panda_status
from drake_coop.robot.driver_spec import DriverSpec, SharedPandaCommand, default_damping
from drake_coop.robot.torque_driver import (
    EMULATE,
    FRANKA_NO_FILTER_HZ,
    DriverClock,
    TorqueDriver,
)
from drake_coop.scenario.driver import FRANKA_DAMPING

ORIGIN = 1_700_000_000_000_000        # the driver's wall clock at t = 0, µs since the epoch
Q = np.array([0.1, -0.4, 0.2, -2.0, 0.3, 1.6, 0.7])
V = np.array([0.3, -0.2, 0.1, 0.4, -0.5, 0.6, -0.7])
K_D = np.array([37.5, 50.0, 37.5, 25.0, 5.0, 3.75, 2.5])   # franka_driver.cc, read by hand


def gravity(q):
    """A stand-in for the robot's g(q) (N·m), not zero at Q."""
    return 10.0 * np.sin(q) + np.arange(1, 8)


def spec(n=7, gravity_convention="robot_adds", expire=0.1):
    return DriverSpec("panda", "panda", "PANDA_STATUS", "PANDA_COMMAND", n, 1e-3, None, 0.05,
                      expire, "hold", time_base="epoch", gravity=gravity_convention,
                      damping=default_damping(n))


def command(tau, utime, mode=lcmt_panda_status.CONTROL_MODE_TORQUE):
    msg = SharedPandaCommand()
    msg.utime = int(utime)
    msg.control_mode_expected = mode
    msg.num_joint_position = msg.num_joint_velocity = 0
    msg.joint_position, msg.joint_velocity = [], []
    msg.joint_torque = [float(v) for v in tau]
    msg.num_joint_torque = len(msg.joint_torque)
    return msg


def ramp(target, cycles, start=0.0):
    """``τ_d`` after ``cycles`` driver cycles toward a constant ``target`` from ``start`` under
    libfranka's rate limit alone (1000 N·m/s: 1 N·m a cycle)."""
    y = np.full(7, start, dtype=float)
    for _ in range(cycles):
        y = y + np.clip(target - y, -1.0, 1.0)
    return y


class Rig:
    """The driver alone: the arm's state fixed at (Q, V); statuses collected. With a
    ``model`` the emulation estimates the external torque; ``phase`` is its clock's."""

    def __init__(self, convention="robot_adds", low_pass_hz=FRANKA_NO_FILTER_HZ, n=7,
                 model=None, phase=0.0):
        import dataclasses

        self.lcm = DrakeLcm("memq://")
        self.statuses = []
        self.lcm.Subscribe("PANDA_STATUS", lambda d: self.statuses.append(
            lcmt_panda_status.decode(d)))
        self.driver = TorqueDriver(dataclasses.replace(spec(n, convention), clock_phase=phase),
                                   DriverClock("epoch", origin=ORIGIN), self.lcm, model=model,
                                   emulate=EMULATE, low_pass_hz=low_pass_hz)
        self.sim = Simulator(self.driver)
        self.ctx = self.sim.get_mutable_context()
        self.state = self.driver.get_input_port(1).FixValue(self.ctx, np.concatenate([Q, V]))
        self.driver.get_input_port(2).FixValue(self.ctx, gravity(Q[:n]))
        self.port = self.driver.get_input_port(0).FixValue(
            self.ctx, AbstractValue.Make(SharedPandaCommand()))
        self.sim.Initialize()

    def send(self, msg):
        self.port.GetMutableData().set_value(msg)

    def cycle(self, t):
        """Run the driver's cycles up to and including the one at ``t`` (s)."""
        self.sim.AdvanceTo(t + 5e-4)
        self.lcm.HandleSubscriptions(0)
        return self.driver.get_output_port(0).Eval(self.ctx).copy()


def test_the_damping_gains_are_the_drivers():
    assert FRANKA_DAMPING == tuple(K_D)


def test_before_the_first_command_gravity_compensation_and_damping():
    rig = Rig()
    # climbing at the rate limit from 0 (cycles at 0, 1, 2, 3 ms) ...
    np.testing.assert_allclose(rig.cycle(0.003), gravity(Q) + ramp(-K_D * V, 4), atol=1e-12)
    assert not np.allclose(ramp(-K_D * V, 4), -K_D * V)
    # ... to −k_d v (the largest, 11.25 N·m, within 12 cycles)
    np.testing.assert_allclose(rig.cycle(0.02), gravity(Q) - K_D * V, rtol=0, atol=1e-12)


def test_a_fresh_command_reaches_the_arm_with_the_robots_gravity_added():
    rig = Rig()
    tau = np.array([0.4, -0.3, 0.2, 0.1, -0.05, 0.02, 0.01])     # under the rate limit
    rig.send(command(tau, ORIGIN + 2000))
    np.testing.assert_allclose(rig.cycle(0.002), tau + gravity(Q), rtol=0, atol=1e-9)


def test_a_command_two_tenths_of_a_second_old_is_dropped():
    rig = Rig()
    rig.sim.AdvanceTo(0.2995)
    rig.send(command(np.full(7, 0.5), ORIGIN + 300_000 - 200_000))   # 0.2 s before t = 0.3
    np.testing.assert_allclose(rig.cycle(0.3), gravity(Q) - K_D * V, rtol=0, atol=1e-12)


def test_a_command_stamped_in_the_future_beyond_the_expiry_is_dropped_too():
    rig = Rig()                                                       # |now − utime| > 0.1 s
    rig.send(command(np.full(7, 0.5), ORIGIN + 2000 + 100_001))
    np.testing.assert_allclose(rig.cycle(0.002), gravity(Q) + ramp(-K_D * V, 3), atol=1e-12)
    rig2 = Rig()                                                      # at 0.1 s: still taken
    rig2.sim.AdvanceTo(0.0015)
    rig2.send(command(np.full(7, 0.5), ORIGIN + 2000 + 100_000))
    y = ramp(-K_D * V, 2)
    np.testing.assert_allclose(rig2.cycle(0.002), gravity(Q) + y + np.clip(0.5 - y, -1, 1),
                               rtol=0, atol=1e-9)


def test_a_command_is_held_until_it_expires_then_damping():
    rig = Rig()
    rig.send(command(np.full(7, 0.5), ORIGIN + 1000))
    np.testing.assert_allclose(rig.cycle(0.101), 0.5 + gravity(Q), rtol=0, atol=1e-9)
    # 0.1 s + 1 µs old at the cycle of 0.102 s: dropped, and not taken again
    tau_d = -K_D * V
    applied = rig.cycle(0.102)
    step = 1000.0 * 1e-3                                     # libfranka's rate limit per cycle
    np.testing.assert_allclose(applied - gravity(Q), 0.5 + np.clip(tau_d - 0.5, -step, step),
                               rtol=0, atol=1e-9)


def test_driver_subtracts_gravity_the_arm_gets_the_command():
    rig = Rig(convention="driver_subtracts")
    tau = gravity(Q) + 0.3                       # the wire carries the torque with gravity
    rig.port.GetMutableData().set_value(command(tau, ORIGIN))
    # the first cycles climb at the rate limit (from 0) toward τ − g = 0.3
    applied = rig.cycle(0.0)
    np.testing.assert_allclose(applied, 0.3 + gravity(Q), rtol=0, atol=1e-9)


def test_the_torque_rate_is_limited_to_1000_newton_metres_a_second():
    rig = Rig()
    rig.send(command(np.full(7, 100.0), ORIGIN))
    for k, t in enumerate([0.0, 0.001, 0.002]):
        rig.send(command(np.full(7, 100.0), ORIGIN + int(t * 1e6)))
        np.testing.assert_allclose(rig.cycle(t) - gravity(Q), np.full(7, 1.0 * (k + 1)),
                                   rtol=0, atol=1e-9)


def test_the_torque_is_low_pass_filtered_at_the_drivers_cutoff():
    rig = Rig(low_pass_hz=30.0)
    a = 1e-3 / (1e-3 + 1.0 / (2 * math.pi * 30.0))       # libfranka's lowpassFilter gain
    y = 0.0
    for t in [0.0, 0.001, 0.002, 0.003]:
        rig.send(command(np.full(7, 0.5), ORIGIN + int(t * 1e6)))
        y = a * 0.5 + (1 - a) * y
        np.testing.assert_allclose(rig.cycle(t) - gravity(Q), np.full(7, y), rtol=0, atol=1e-9)
    assert 0.05 < y < 0.3                      # filtered, not passed through


def test_the_status_carries_the_drivers_wall_clock_and_the_measured_torque():
    rig = Rig()
    tau = np.full(7, 0.25)
    rig.send(command(tau, ORIGIN))
    rig.cycle(0.004)
    stamps = [s.utime for s in rig.statuses]
    assert stamps == [ORIGIN + 1000 * j for j in range(5)]            # epoch µs, each cycle
    last = rig.statuses[-1]
    np.testing.assert_array_equal(last.joint_position, Q)
    np.testing.assert_array_equal(last.joint_velocity, V)
    # published before the cycle's command is taken: τ_J is the torque of the cycle before
    np.testing.assert_allclose(last.joint_torque, tau + gravity(Q), rtol=0, atol=1e-9)
    np.testing.assert_allclose(rig.statuses[0].joint_torque, 0.0)     # nothing applied yet
    assert last.control_mode == lcmt_panda_status.CONTROL_MODE_TORQUE
    assert last.robot_utime == 4000


@pytest.mark.parametrize("field, msg", [
    ("control_mode_expected", command(np.zeros(7), ORIGIN,
                                      mode=lcmt_panda_status.CONTROL_MODE_POSITION)),
    ("num_joint_torque", command(np.zeros(6), ORIGIN)),
    ("joint_torque", command([0, 0, math.nan, 0, 0, 0, 0], ORIGIN)),
])
def test_a_command_the_driver_throws_on_stops_it(field, msg):
    rig = Rig()
    rig.send(msg)
    applied = rig.cycle(0.002)
    reason = rig.driver.fault(rig.driver.GetMyContextFromRoot(rig.ctx))
    assert reason.startswith("PANDA_COMMAND: " + field), reason
    np.testing.assert_allclose(applied, gravity(Q) + ramp(-K_D * V, 3), atol=1e-12)
    count = len(rig.statuses)
    rig.send(command(np.zeros(7), ORIGIN + 3000))                     # too late: stopped
    np.testing.assert_allclose(rig.cycle(0.03), gravity(Q) - K_D * V, rtol=0, atol=1e-12)
    assert len(rig.statuses) == count                                 # no status any more


def test_seven_joints_are_required():
    with pytest.raises(ValueError, match=r"^robots: panda has 3 joints; drake-franka-driver "
                                         r"serves 7 only$"):
        Rig(n=3)


class StubModel:
    """An arm model written here: H = 2 I, no Coriolis, the test's gravity."""

    def H(self, q):
        return 2.0 * np.eye(7)

    def Cv(self, q, v):
        return np.zeros(7)

    def g(self, q):
        return gravity(q)

    def inverse_dynamics_terms(self, q, v, a):
        return self.H(q) @ a + self.Cv(q, v) + self.g(q)


def test_the_external_torque_has_frankas_sign():
    """An arm held still by its surroundings (its state fixed) while the driver applies
    τ_d + g(q): the surroundings push back with −τ_d, and Franka's tau_ext_hat_filtered (the
    negative of the environment's torque) reads +τ_d."""
    lcm = DrakeLcm("memq://")
    statuses = []
    lcm.Subscribe("PANDA_STATUS", lambda d: statuses.append(lcmt_panda_status.decode(d)))
    driver = TorqueDriver(spec(), DriverClock("epoch", origin=ORIGIN), lcm, model=StubModel(),
                          emulate=EMULATE, low_pass_hz=FRANKA_NO_FILTER_HZ)
    sim = Simulator(driver)
    ctx = sim.get_mutable_context()
    driver.get_input_port(1).FixValue(ctx, np.concatenate([Q, np.zeros(7)]))
    driver.get_input_port(2).FixValue(ctx, gravity(Q))
    tau = np.array([0.4, -0.3, 0.2, 0.1, -0.05, 0.02, 0.01])
    driver.get_input_port(0).FixValue(ctx, AbstractValue.Make(command(tau, ORIGIN)))
    sim.Initialize()
    sim.AdvanceTo(0.0035)
    lcm.HandleSubscriptions(0)
    np.testing.assert_allclose(statuses[-1].joint_torque_external, tau, rtol=0, atol=1e-12)
    np.testing.assert_allclose(statuses[0].joint_torque_external, 0.0)   # t = 0: none yet


def test_the_estimate_read_between_the_drivers_cycle_and_the_plants_step_is_the_statuss():
    """The arm's velocity steps from V to V + δ between the cycles at 1 and 2 ms (the plant's
    step). Read just after the driver's cycle at 2 ms, before any later step (where a
    controller's tick an ulp after the cycle reads it), the port holds what the status of
    that cycle published: τ₋ − (H δ / 1 ms + g(q)), with τ₋ the torque on the arm over the
    cycle before (H = 2 I, no Coriolis, no damping). Computed at the reading instant instead,
    the driver's own fresh velocity made the acceleration 0: τ₋ − g(q), off by 2 δ / 1 ms."""
    rig = Rig(model=StubModel())
    driver, ctx = rig.driver, rig.ctx
    rig.send(command(np.zeros(7), ORIGIN))
    rig.sim.AdvanceTo(0.0015)
    tau_before = driver.get_output_port(0).Eval(ctx).copy()         # on the arm from 1 ms
    delta = np.array([2e-4, -1e-4, 3e-4, 0.0, 1e-4, -2e-4, 1e-4])   # rad/s
    rig.state.GetMutableData().set_value(np.concatenate([Q, V + delta]))   # the plant's step
    rig.sim.AdvanceTo(0.002 + 1e-9)                                 # just after the cycle
    rig.lcm.HandleSubscriptions(0)
    want = tau_before - (2.0 * delta / 1e-3 + gravity(Q))
    read = driver.get_output_port(2).Eval(ctx)
    np.testing.assert_allclose(read, want, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rig.statuses[-1].joint_torque_external, want, rtol=0, atol=1e-9)
    assert rig.statuses[-1].utime == ORIGIN + 2000                      # that cycle's status
    assert np.abs(read - (tau_before - gravity(Q))).max() > 0.5     # not the stale reading


def test_the_first_estimate_of_a_phased_clock_has_the_velocity_of_initialization():
    """A driver whose cycles start at 0.5 ms (``clock_phase``), the arm moving at a constant
    V: the first estimate (latched before the first cycle, the arm not yet driven: no torque
    on it) reads no acceleration, −g(q); against a v₋ of zeros it would read −(2 V / 1 ms +
    g(q))."""
    rig = Rig(model=StubModel(), phase=5e-4)
    rig.sim.AdvanceTo(4.99e-4)                              # after the first latch only
    np.testing.assert_allclose(rig.driver.get_output_port(2).Eval(rig.ctx), -gravity(Q),
                               rtol=0, atol=1e-12)


def test_an_expired_command_is_counted_once_and_a_fresh_one_not_at_all():
    rig = Rig()
    rig.send(command(np.full(7, 0.5), ORIGIN + 1000))
    rig.cycle(0.101)
    assert rig.driver.counts(rig.ctx)["expired"] == 0          # 0.1 s old: still held
    rig.cycle(0.110)                                            # dropped at 0.102 s, once
    assert rig.driver.counts(rig.ctx)["expired"] == 1
    rig.send(command(np.full(7, 0.5), ORIGIN + 111_000))        # a fresh one
    rig.cycle(0.115)
    assert rig.driver.counts(rig.ctx)["expired"] == 1


def test_the_cycles_the_rate_limit_changes_the_torque_are_counted():
    rig = Rig()
    rig.send(command(np.zeros(7), ORIGIN))
    rig.driver.get_input_port(1).FixValue(rig.ctx, np.concatenate([Q, np.zeros(7)]))
    rig.cycle(0.003)                                            # 0 → 0: never bound
    assert rig.driver.counts(rig.ctx)["rate_limited"] == 0
    rig.send(command(np.full(7, 2.5), ORIGIN + 4000))           # 2.5 N·m: 3 cycles to reach
    rig.cycle(0.008)
    assert rig.driver.counts(rig.ctx)["rate_limited"] == 2


def test_the_journal_holds_each_command_as_taken():
    rig = Rig()
    rig.driver.journal = []
    tau = np.array([0.4, -0.3, 0.2, 0.1, -0.05, 0.02, 0.01])
    rig.send(command(tau, ORIGIN + 2000))
    rig.cycle(0.004)                                            # one command: one row
    (row,) = rig.driver.journal
    assert row[:2].tolist() == [ORIGIN, ORIGIN + 2000]          # taken at the cycle of t = 0
    cols = row[2:].reshape(5, 7)
    for got, want in zip(cols, [tau, tau, gravity(Q), tau + gravity(Q), Q]):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_with_a_journal_each_expiry_is_kept_with_the_commands_stamp():
    rig = Rig()
    rig.driver.journal = []
    rig.send(command(np.full(7, 0.5), ORIGIN + 1000))
    rig.cycle(0.110)
    assert rig.driver.expiries == [[ORIGIN + 102_000, ORIGIN + 1000]]
    assert len(rig.driver.journal) == 1


def test_an_expired_command_is_dropped_before_the_driver_checks_it():
    """DoTorqueControl resets an expired command before its DRAKE_THROW_UNLESS checks: a
    command in another mode that is too old is dropped, and the driver keeps running."""
    rig = Rig()
    rig.send(command(np.zeros(7), ORIGIN - 200_000, mode=lcmt_panda_status.CONTROL_MODE_POSITION))
    applied = rig.cycle(0.03)
    assert rig.driver.fault(rig.ctx) == ""
    assert rig.driver.counts(rig.ctx)["expired"] == 1
    np.testing.assert_allclose(applied, gravity(Q) - K_D * V, rtol=0, atol=1e-12)
    count = len(rig.statuses)
    rig.cycle(0.035)
    assert len(rig.statuses) == count + 5                             # still publishing
