"""The watchdog: each trip (stale status, NaN reading, out-of-range reading, force guard,
NaN torque, a malformed status, a NaN stamp, a jump beyond the velocity limits) gives the safe
command at the tick it is detected; nothing but the safe command before the first valid
status; torque limits always; never NaN."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from drake_coop.control.watchdog import STATUS_FAULTS, STATUS_NONE, TRIP_REASONS, Watchdog

H = 0.009
N = 3


def make(**kw):
    args = dict(max_status_age=0.02, q_min=[-1.0] * N, q_max=[1.0] * N, max_force=100.0,
                torque_limits=[5.0, 6.0, 7.0])
    args.update(kw)
    wd = Watchdog(N, 1, H, **args)
    sim = Simulator(wd)
    ctx = sim.get_mutable_context()
    ports = {"q": np.array([0.1, -0.2, 0.3]), "status": np.array([0.0, 0.0, 0.0]),
             "tau": np.array([1.0, -2.0, 3.0]), "lambda_hat": np.array([10.0])}
    fixed = {name: wd.GetInputPort(name).FixValue(ctx, value) for name, value in ports.items()}
    wd.set_initial_state(ctx, ports["q"])
    sim.Initialize()
    return wd, sim, ctx, fixed


def out(wd, ctx):
    return wd.get_tau_safe_output_port().Eval(ctx), wd.reason(ctx)


def advance_tick(sim, k):
    """Through the updates of tick k (a publish would come right after)."""
    sim.AdvanceTo(k * H + 1e-4)


def test_passes_the_torque_clipped_to_the_limits():
    wd, sim, ctx, fixed = make()
    fixed["tau"].GetMutableData().set_value(np.array([10.0, -2.0, -30.0]))
    for k in range(3):
        fixed["status"].GetMutableData().set_value(np.array([k * 1e-3, 0.0, 0.0]))
        advance_tick(sim, k)
    tau, reason = out(wd, ctx)
    assert reason == ""
    np.testing.assert_array_equal(tau, [5.0, -2.0, -7.0])


def test_a_status_that_stops_arriving_trips_at_the_first_tick_past_max_status_age():
    wd, sim, ctx, fixed = make(max_status_age=0.02)
    # the stamp never changes after tick 0: the first tick with k h > 0.02 is k = 3
    k_trip = next(k for k in range(10) if k * H > 0.02)
    for k in range(k_trip):
        advance_tick(sim, k)
        assert out(wd, ctx)[1] == "", k
    advance_tick(sim, k_trip)
    tau, reason = out(wd, ctx)
    assert reason == TRIP_REASONS[1]
    np.testing.assert_array_equal(tau, np.zeros(N))


def test_fresh_statuses_keep_it_untripped():
    wd, sim, ctx, fixed = make(max_status_age=0.02)
    for k in range(20):
        fixed["status"].GetMutableData().set_value(np.array([k * H, 0.0, 0.0]))
        advance_tick(sim, k)
    assert out(wd, ctx)[1] == ""


@pytest.mark.parametrize("field, value, code", [
    ("q", [0.1, math.nan, 0.3], 2),
    ("q", [0.1, 1.5, 0.3], 3),
    ("lambda_hat", [150.0], 4),
    ("lambda_hat", [math.nan], 4),
    ("tau", [math.nan, 0.0, 0.0], 5),
])
def test_a_bad_reading_or_a_guard_trip_sends_the_safe_command_at_that_tick(field, value, code):
    wd, sim, ctx, fixed = make()
    advance_tick(sim, 0)
    fixed["status"].GetMutableData().set_value(np.array([1e-3, 0.0, 0.0]))
    fixed[field].GetMutableData().set_value(np.array(value))
    if field == "tau":     # before the tick's update: the output is already safe, never NaN
        assert np.all(out(wd, ctx)[0] == 0.0)
    advance_tick(sim, 1)
    tau, reason = out(wd, ctx)
    assert reason == TRIP_REASONS[code]
    np.testing.assert_array_equal(tau, np.zeros(N))
    # latched: a good reading afterwards does not clear it
    fixed[field].GetMutableData().set_value(
        np.array({"q": [0.1, -0.2, 0.3], "lambda_hat": [10.0], "tau": [1.0, 1.0, 1.0]}[field]))
    fixed["status"].GetMutableData().set_value(np.array([2e-3, 0.0, 0.0]))
    advance_tick(sim, 2)
    assert out(wd, ctx)[1] == TRIP_REASONS[code]


def test_hold_sends_the_hold_torque_at_the_last_good_reading_clipped():
    def gravity(q):         # a stand-in model: any function of q, checked by value
        return np.array([100.0 * q[0], 2.0 * q[1], math.nan])

    wd, sim, ctx, fixed = make(safe_command="hold", hold_torque=gravity)
    good = np.array([0.01, -0.4, 0.2])
    fixed["q"].GetMutableData().set_value(good)
    advance_tick(sim, 0)
    fixed["q"].GetMutableData().set_value(np.array([0.5, math.nan, 0.0]))
    fixed["status"].GetMutableData().set_value(np.array([1e-3, 0.0, 0.0]))
    advance_tick(sim, 1)
    tau, reason = out(wd, ctx)
    assert reason == TRIP_REASONS[2]
    np.testing.assert_allclose(tau, [min(100.0 * 0.01, 5.0), 2.0 * -0.4, 0.0])


@pytest.mark.parametrize("kw, field", [
    (dict(max_status_age=0.0), "max_status_age"),
    (dict(max_force=-1.0), "max_force"),
    (dict(q_min=[1.0] * N), "q_min"),
    (dict(torque_limits=[1.0, 0.0, 1.0]), "torque_limits"),
    (dict(torque_limits=[1.0]), "torque_limits"),
    (dict(torque_limits=None), "torque_limits"),
    (dict(torque_limits=[1.0, math.inf, 1.0]), "torque_limits"),
    (dict(velocity_limits=[1.0, 0.0, 1.0]), "velocity_limits"),
    (dict(max_status_age=H / 2), "max_status_age"),
    (dict(safe_command="brake"), "safe_command"),
    (dict(safe_command="hold"), "hold_torque"),
])
def test_bad_arguments_name_the_field(kw, field):
    args = dict(max_status_age=0.02, q_min=[-1.0] * N, q_max=[1.0] * N, max_force=100.0,
                torque_limits=[1.0] * N)
    args.update(kw)
    with pytest.raises(ValueError, match=field):
        Watchdog(N, 1, H, **args)


def test_q_checked_is_the_reading_itself_or_the_last_good_one():
    wd, sim, ctx, fixed = make()
    good = np.array([0.1, -0.2, 0.3])
    advance_tick(sim, 0)
    q_checked = wd.get_q_checked_output_port()
    assert q_checked.Eval(ctx).tobytes() == good.tobytes()
    fixed["q"].GetMutableData().set_value(np.array([0.2, math.nan, 0.0]))
    np.testing.assert_array_equal(q_checked.Eval(ctx), good)


def test_ports_match_the_docstring_block_and_have_accessors():
    import re

    wd = make()[0]
    block = Watchdog.__doc__.split(".. pydrake_system::")[1].split("\n\n")[1]
    inputs, outputs = block.split("output_ports:")
    assert re.findall(r"- (\w+)", inputs) == [wd.get_input_port(i).get_name()
                                             for i in range(wd.num_input_ports())]
    assert re.findall(r"- (\w+)", outputs) == [wd.get_output_port(i).get_name()
                                              for i in range(wd.num_output_ports())]
    for i in range(wd.num_input_ports()):
        port = wd.get_input_port(i)
        assert getattr(wd, f"get_{port.get_name()}_input_port")().get_index() == i
    for i in range(wd.num_output_ports()):
        port = wd.get_output_port(i)
        assert getattr(wd, f"get_{port.get_name()}_output_port")().get_index() == i


def set_status(fixed, stamp, fault=0.0, value=0.0):
    fixed["status"].GetMutableData().set_value(np.array([stamp, fault, value]))


def test_a_torque_of_1e300_leaves_clipped_to_the_limits():
    wd, sim, ctx, fixed = make()
    fixed["tau"].GetMutableData().set_value(np.array([1e300, -1e300, 2.5]))
    advance_tick(sim, 0)
    tau, reason = out(wd, ctx)
    assert reason == ""
    np.testing.assert_array_equal(tau, [5.0, -6.0, 2.5])


def test_before_the_first_status_only_the_safe_command_leaves_and_q_checked_is_the_start():
    def gravity(q):
        return np.array([1.0, 2.0 * q[1], 3.0])

    start = np.array([0.1, -0.2, 0.3])
    wd, sim, ctx, fixed = make(safe_command="hold", hold_torque=gravity)
    fixed["q"].GetMutableData().set_value(np.array([0.0, 0.0, 0.0]))   # what a receiver reads
    set_status(fixed, math.nan, STATUS_NONE)                           # ... before any status
    fixed["tau"].GetMutableData().set_value(np.array([4.0, 4.0, 4.0]))
    wd.set_initial_state(ctx, start)
    q_checked = wd.get_q_checked_output_port()
    k_trip = next(k for k in range(10) if k * H > 0.02)
    for k in range(k_trip):
        advance_tick(sim, k)
        tau, reason = out(wd, ctx)
        assert reason == "", k
        np.testing.assert_allclose(tau, [1.0, -0.4, 3.0])      # g(start), not the controller's
        np.testing.assert_array_equal(q_checked.Eval(ctx), start)
    advance_tick(sim, k_trip)                                   # none within max_status_age
    assert out(wd, ctx)[1] == TRIP_REASONS[1]


def test_the_first_valid_status_lets_the_torque_through_at_its_tick():
    wd, sim, ctx, fixed = make()
    set_status(fixed, math.nan, STATUS_NONE)
    wd.set_initial_state(ctx, np.zeros(N))
    advance_tick(sim, 0)
    np.testing.assert_array_equal(out(wd, ctx)[0], 0.0)
    set_status(fixed, 5e-3)
    advance_tick(sim, 1)
    np.testing.assert_array_equal(out(wd, ctx)[0], [1.0, -2.0, 3.0])


@pytest.mark.parametrize("fault, value, words", [
    (2, 29, "another message type, 29 bytes"),
    (3, 100, "truncated status (100 bytes)"),
    (4, 0, "status of 0 joints, the arm has 3"),
    (4, 7, "status of 7 joints, the arm has 3"),
    (5, 231, "wrong size (231 bytes)"),
    (6, 0, "non-finite joint position"),
])
def test_a_malformed_status_trips_at_its_tick_naming_what_was_wrong(fault, value, words):
    wd, sim, ctx, fixed = make()
    advance_tick(sim, 0)
    assert fault in STATUS_FAULTS
    set_status(fixed, 1e-3, fault, value)
    advance_tick(sim, 1)
    tau, reason = out(wd, ctx)
    assert reason.startswith(TRIP_REASONS[7]) and words in reason, reason
    np.testing.assert_array_equal(tau, np.zeros(N))


@pytest.mark.parametrize("stamp", [math.nan, math.inf])
def test_a_non_finite_stamp_counts_as_stale_at_once(stamp):
    wd, sim, ctx, fixed = make()
    advance_tick(sim, 0)
    set_status(fixed, stamp)
    advance_tick(sim, 1)
    tau, reason = out(wd, ctx)
    assert reason == TRIP_REASONS[6]
    np.testing.assert_array_equal(tau, np.zeros(N))


@pytest.mark.parametrize("dq, trips", [(0.5, True), (0.099, False), (0.101, True)])
def test_a_jump_beyond_the_velocity_limits_over_the_stamps_interval_trips(dq, trips):
    # v_max = 10 rad/s on joint 1, 10 ms between the statuses' stamps: 0.1 rad allowed
    wd, sim, ctx, fixed = make(velocity_limits=[math.inf, 10.0, 10.0])
    set_status(fixed, 0.100)
    advance_tick(sim, 0)
    q = np.array([0.1, -0.2, 0.3])
    fixed["q"].GetMutableData().set_value(q + [0.0, dq, 0.0])
    set_status(fixed, 0.110)
    advance_tick(sim, 1)
    tau, reason = out(wd, ctx)
    if trips:
        assert reason.startswith(TRIP_REASONS[8]) and "joint 1" in reason, reason
        np.testing.assert_array_equal(tau, np.zeros(N))
    else:
        assert reason == ""


def test_a_joint_with_an_infinite_velocity_limit_is_not_jump_checked():
    wd, sim, ctx, fixed = make(velocity_limits=[math.inf, 10.0, 10.0],
                               q_min=[-9.0] * N, q_max=[9.0] * N)
    set_status(fixed, 0.100)
    advance_tick(sim, 0)
    fixed["q"].GetMutableData().set_value(np.array([3.0, -0.2, 0.3]))
    set_status(fixed, 0.101)
    advance_tick(sim, 1)
    assert out(wd, ctx)[1] == ""


@pytest.mark.parametrize("safe_command", ["zero_torque", "hold"])
def test_tau_latched_is_tau_safe_after_every_tick_and_tripped_is_the_reason_code(safe_command):
    """Random readings and torques, some beyond the limits, the torque changed only before
    a tick (as a controller that latches it does), a bad reading at tick 12: after every tick
    the state output equals the live one, and ``tripped`` carries the code the reason names."""
    rng = np.random.default_rng(3)
    wd, sim, ctx, fixed = make(safe_command=safe_command,
                               hold_torque=lambda q: np.array([q[0], 2 * q[1], -q[2]]),
                               velocity_limits=[10.0] * N)
    code_of = {text: code for code, text in TRIP_REASONS.items()}
    for k in range(16):
        q = np.array([0.1, -0.2, 0.3]) + rng.normal(scale=0.01, size=N)
        if k == 12:
            q[1] = 1.5                                  # out of range: trips
        fixed["q"].GetMutableData().set_value(q)
        fixed["tau"].GetMutableData().set_value(rng.normal(scale=8.0, size=N))
        set_status(fixed, k * H)
        advance_tick(sim, k)
        live = wd.get_tau_safe_output_port().Eval(ctx)
        latched = wd.get_tau_latched_output_port().Eval(ctx)
        assert latched.tolist() == live.tolist(), k
        reason = wd.reason(ctx)
        assert wd.get_tripped_output_port().Eval(ctx)[0] == code_of[reason], k
        assert (reason != "") == (k >= 12)
