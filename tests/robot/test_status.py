"""The status read from its bytes (:mod:`drake_coop.robot.status`): checked against the
message's own generated decoder (an independent reading), never raising, whatever the bytes."""

import math

import numpy as np
import pytest

from drake import lcmt_panda_command, lcmt_panda_status
from drake_coop.control.watchdog import STATUS_FAULTS, STATUS_NONE, STATUS_OK
from drake_coop.robot.status import check_panda_status, panda_status_size


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
    msg.control_command_success_rate = 0.5
    return msg.encode()


@pytest.mark.parametrize("n", [1, 3, 7])
def test_a_valid_status_reads_as_the_generated_decoder_reads_it(n):
    rng = np.random.default_rng(n)
    data = status(rng.normal(size=n), utime=987_654_321)
    assert len(data) == panda_status_size(n)
    ref = lcmt_panda_status.decode(data)
    q, stamp, fault, _ = check_panda_status(data, n)
    assert fault == STATUS_OK
    assert q.tolist() == list(ref.joint_position) and stamp == ref.utime * 1e-6


def test_no_message_yet():
    q, stamp, fault, _ = check_panda_status(b"", 3)
    assert fault == STATUS_NONE and np.all(np.isnan(q)) and math.isnan(stamp)


@pytest.mark.parametrize("data, fault, value", [
    (status([0.1, 0.2, 0.3], joints=0), 4, 0),
    (status([0.1, 0.2, 0.3], joints=7), 4, 7),
    (status([0.1, 0.2, 0.3])[:100], 3, 100),
    (status([0.1, 0.2, 0.3])[:12], 3, 12),
    (status([0.1, 0.2, 0.3])[:5], 2, 5),
    (status([0.1, 0.2, 0.3]) + b"\0", 5, 231),
    (lcmt_panda_command().encode(), 2, 29),
    (status([0.1, math.nan, 0.3]), 6, 0),
    (status([math.inf, 0.2, 0.3]), 6, 0),
    (status([0.1, 0.2, -math.inf]), 6, 0),
])
def test_a_malformed_status_is_a_fault_with_nan_positions(data, fault, value):
    q, _, got, v = check_panda_status(data, 3)
    assert (got, v) == (fault, value) and fault in STATUS_FAULTS
    assert np.all(np.isnan(q)) and q.shape == (3,)


def test_any_bytes_give_a_result_never_an_exception():
    rng = np.random.default_rng(0)
    good = status([0.1, 0.2, 0.3])
    cases = [rng.bytes(k) for k in range(0, 300, 7)]
    cases += [good[:k] for k in range(len(good))]
    cases += [good[:20] + rng.bytes(210) for _ in range(50)]
    for data in cases:
        q, _, fault, _ = check_panda_status(data, 3)
        assert q.shape == (3,)
        assert fault != STATUS_OK or np.all(np.isfinite(q))


def test_the_quick_check_agrees_with_the_full_reading_on_any_bytes():
    """``panda_status_ok`` (every message at the driver's rate) says valid exactly when
    ``check_panda_status`` does, on valid, malformed and random bytes."""
    from drake_coop.robot.status import panda_status_ok

    rng = np.random.default_rng(1)
    good = status([0.1, 0.2, 0.3])
    cases = [good, status([0.1, math.nan, 0.3]), status([0.1, 0.2, 0.3], joints=7),
             status([0.1, 0.2, 0.3], joints=0), good + b"\0", lcmt_panda_command().encode()]
    cases += [rng.bytes(k) for k in range(0, 300, 7)] + [good[:k] for k in range(len(good))]
    cases += [good[:20] + rng.bytes(210) for _ in range(50)]
    cases += [status(rng.normal(size=3), utime=int(u)) for u in rng.integers(0, 2**40, 20)]
    for data in cases:
        assert panda_status_ok(data, 3) == (check_panda_status(data, 3)[2] == STATUS_OK)
    assert sum(panda_status_ok(d, 3) for d in cases) >= 21          # valid ones among them
