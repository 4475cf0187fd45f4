"""The watchdog: each trip (stale status, NaN reading, out-of-range reading, force guard,
NaN torque) gives the safe command at the tick it is detected; torque limits; never NaN."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

from drake_coop.control.watchdog import TRIP_REASONS, Watchdog

H = 0.009
N = 3


def make(**kw):
    args = dict(max_status_age=0.02, q_min=[-1.0] * N, q_max=[1.0] * N, max_force=100.0,
                torque_limits=[5.0, 6.0, 7.0])
    args.update(kw)
    wd = Watchdog(N, 1, H, **args)
    sim = Simulator(wd)
    ctx = sim.get_mutable_context()
    ports = {"q": np.array([0.1, -0.2, 0.3]), "status_stamp": np.array([0.0]),
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
        fixed["status_stamp"].GetMutableData().set_value(np.array([k * 1e-3]))
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
        fixed["status_stamp"].GetMutableData().set_value(np.array([k * H]))
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
    fixed["status_stamp"].GetMutableData().set_value(np.array([1e-3]))
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
    fixed["status_stamp"].GetMutableData().set_value(np.array([2e-3]))
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
    fixed["status_stamp"].GetMutableData().set_value(np.array([1e-3]))
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
    (dict(safe_command="brake"), "safe_command"),
    (dict(safe_command="hold"), "hold_torque"),
])
def test_bad_arguments_name_the_field(kw, field):
    args = dict(max_status_age=0.02, q_min=[-1.0] * N, q_max=[1.0] * N, max_force=100.0)
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
