"""The cheap parts of ``serve``'s tick against the ones they stand for: the statuses of a tick
checked at once (:func:`~drake_coop.robot.status.first_bad_panda_status`) find the first
message that the message-by-message check (``panda_status_ok``, itself checked against the
full reading) rejects; the watchdog run by the loop (``Watchdog(periodic=False).tick``) gives,
tick by tick, the state and outputs of its periodic update on the same inputs; the messages
of a tick are kept unchecked until the tick looks, and a bad one among good ones is still the
one the tick takes."""

import math

import numpy as np
import pytest
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator

from drake import lcmt_panda_command, lcmt_panda_status
from drake_coop.control.watchdog import STATUS_NONE, STATUS_OK, Watchdog
from drake_coop.robot.pacing import StatusArrivals
from drake_coop.robot.status import first_bad_panda_status, panda_status_ok


def status(q, utime=123_456, joints=None):
    joints = len(q) if joints is None else joints
    msg = lcmt_panda_status()
    msg.utime = utime
    msg.num_joints = joints
    msg.joint_position = list(np.resize(np.asarray(q, dtype=float), joints))
    for f in ("joint_velocity", "joint_torque", "joint_torque_external",
              "joint_position_desired", "joint_velocity_desired",
              "joint_acceleration_desired", "joint_torque_desired"):
        setattr(msg, f, list(np.arange(joints) + 7.0))
    return msg.encode()


def hostile(rng, good):
    """Bad messages of every kind, and valid ones the byte test must not take for bad."""
    return [status([0.1, math.nan, 0.3]), status([math.inf, 0.2, 0.3]),
            status([0.1, 0.2, -math.inf]), status([0.1, 0.2, 0.3], joints=7),
            status([0.1, 0.2, 0.3], joints=0), good + b"\0", good[:-1], b"",
            lcmt_panda_command().encode(), rng.bytes(len(good)),
            good[:8] + rng.bytes(len(good) - 8), good[:20] + b"\x7f\xf8" + good[22:]]


def test_the_statuses_of_a_tick_checked_at_once_find_the_first_one_rejected_alone():
    rng = np.random.default_rng(4)
    good = [status(rng.normal(size=3), utime=int(u)) for u in rng.integers(0, 2**40, 12)]
    # valid but huge readings (first byte 0x7f / 0xff): checked one by one, still valid
    good += [status([1e300, -0.2, 0.3]), status([0.1, -1e300, 0.3]), status([0.0, -0.0, 5e-324])]
    assert all(panda_status_ok(d, 3) for d in good)
    assert first_bad_panda_status(good, 3) == -1
    assert first_bad_panda_status([], 3) == -1
    for bad in hostile(rng, good[0]):
        assert not panda_status_ok(bad, 3)
        for at in (0, 4, len(good)):
            messages = good[:at] + [bad] + good[at:] + [bad]
            assert first_bad_panda_status(messages, 3) == at, (bad, at)
    for _ in range(200):                                      # random mixes, any bytes
        messages = [good[int(i)] if rng.random() < 0.8 else rng.bytes(int(rng.integers(0, 300)))
                    for i in rng.integers(0, len(good), 9)]
        expected = next((i for i, d in enumerate(messages) if not panda_status_ok(d, 3)), -1)
        assert first_bad_panda_status(messages, 3) == expected


def test_a_bad_status_among_good_ones_is_the_one_the_tick_takes():
    lcm = DrakeLcm("memq://")
    arrivals = StatusArrivals(lcm, ["S"], check_many={"S": lambda m: first_bad_panda_status(m, 3)})
    good, bad = status([0.1, 0.2, 0.3]), status([0.1, 0.2, 0.3], joints=0)
    for data in (good, good, bad, good, bad, good):
        lcm.Publish("S", data)
    lcm.HandleSubscriptions(0)
    assert arrivals.count["S"] == 6 and arrivals.message["S"] == good
    assert arrivals.faulty["S"] == bad                    # checked when looked at
    assert arrivals.take("S") == bad                      # the first bad one, then forgotten
    assert arrivals.take("S") == good
    lcm.Publish("S", good)
    lcm.HandleSubscriptions(0)
    assert arrivals.take("S") == good


def test_statuses_nobody_looks_at_are_checked_in_bounded_batches():
    """While the loop waits (before the first tick) nobody looks: the kept messages are checked
    every 1000, so memory stays bounded and a bad one among thousands is still found."""
    from drake_coop.robot import pacing

    lcm = DrakeLcm("memq://")
    arrivals = StatusArrivals(lcm, ["S"], check_many={"S": lambda m: first_bad_panda_status(m, 3)})
    good, bad = status([0.1, 0.2, 0.3]), status([0.1, 0.2, math.nan])
    for j in range(2500):
        lcm.Publish("S", bad if j == 1500 else good)
        if j % 100 == 99:
            lcm.HandleSubscriptions(0)
    lcm.HandleSubscriptions(0)
    assert len(arrivals._pending["S"]) < pacing._MAX_PENDING
    assert arrivals.faulty["S"] == bad and arrivals.take("S") == bad
    assert arrivals.take("S") == good


H, N = 0.009, 3


def watchdog(periodic, **kw):
    args = dict(max_status_age=0.02, q_min=[-1.0] * N, q_max=[1.0] * N, max_force=100.0,
                torque_limits=[5.0, 6.0, 7.0], velocity_limits=[5.0, 5.0, 5.0],
                safe_command="hold", hold_torque=lambda q: 3.0 * np.sin(q) + 1.0)
    args.update(kw)
    return Watchdog(N, 1, H, periodic=periodic, **args)


@pytest.mark.parametrize("case", ["clean", "nan", "range", "jump", "force", "tau", "fault",
                                  "stale", "none"])
def test_the_loops_watchdog_tick_is_the_periodic_update_on_the_same_inputs(case):
    rng = np.random.default_rng(7)
    ticks, trip_at = 12, 8
    inputs = []
    for k in range(ticks):
        q = 0.3 * np.sin(0.1 * k + np.arange(N))
        status = np.array([k * H, float(STATUS_OK), 0.0])
        tau, lam = rng.normal(scale=4.0, size=N), np.array([20.0 + k])
        if k == 0 and case == "none":
            status = np.array([math.nan, float(STATUS_NONE), 0.0])
        if k >= trip_at:
            if case == "nan":
                q[1] = math.nan
                status[1] = 6.0
            elif case == "range":
                q[0] = 1.5
            elif case == "jump":
                q[2] += 0.5
            elif case == "force":
                lam[0] = 150.0
            elif case == "tau":
                tau[0] = math.nan
            elif case == "fault":
                status = np.array([math.nan, 3.0, 120.0])
            elif case == "stale":
                status[0] = (trip_at - 1) * H
        inputs.append((q, status, tau, lam))

    ref = watchdog(True)
    sim = Simulator(ref)
    ctx = sim.get_mutable_context()
    fixed = {p: ref.GetInputPort(p).FixValue(ctx, v) for p, v in
             zip(("q", "status", "tau", "lambda_hat"), inputs[0])}
    q0 = np.array([0.0, 0.3, 0.6])
    ref.set_initial_state(ctx, q0)
    sim.Initialize()

    loop = watchdog(False)
    lctx = loop.CreateDefaultContext()
    loop.set_initial_state(lctx, q0)

    for k, (q, status, tau, lam) in enumerate(inputs):
        for p, v in zip(("q", "status", "tau", "lambda_hat"), (q, status, tau, lam)):
            fixed[p].GetMutableData().set_value(v)
        sim.AdvanceTo(k * H + 1e-4)                           # the update at t_k
        lctx.SetTime(k * H + 1e-4)
        tripped = loop.tick(lctx, k * H, status.tolist(), q.tolist(), lam.tolist(),
                            tau.tolist())
        assert tripped == ref.is_tripped(ctx)
        for port in ("tau_latched", "tripped"):
            np.testing.assert_array_equal(loop.GetOutputPort(port).Eval(lctx),
                                          ref.GetOutputPort(port).Eval(ctx))
        assert loop.reason(lctx) == ref.reason(ctx)
        np.testing.assert_array_equal(loop.last_good_position(lctx),
                                      ref.last_good_position(ctx))
    assert ref.is_tripped(ctx) == (case not in ("clean", "none")), ref.reason(ctx)
    tau_out = loop.GetOutputPort("tau_latched").Eval(lctx)
    assert np.all(np.abs(tau_out) <= [5.0, 6.0, 7.0]) and np.all(np.isfinite(tau_out))
