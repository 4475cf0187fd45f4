"""The held object's metrics (drake_coop.results.object_metrics) on constructed motions whose
slip, pose error, cone use and drops are known in closed form."""

from __future__ import annotations

import numpy as np
import pytest

from drake_coop.kinematics.rotations import pad_contact_components, quaternion_rotations
from drake_coop.results.metrics import compute_metrics
from drake_coop.results.object_metrics import (
    DROP_DISTANCE,
    SLIP_DISTANCE,
    object_signals,
)

PHASES = [["free", 0.0, 1.0], ["lift", 1.0, 4.0], ["circle", 4.0, 8.0], ["put_down", 8.0, 9.0],
          ["return", 9.0, 10.0]]
HALF_WIDTH, DEPTH, MU = 0.1, 0.014, 0.8
GAMMA = 0.3                     # the box's constant yaw (rad)


def _rz(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _quaternion_z(a: float) -> np.ndarray:
    return np.array([np.cos(a / 2), 0.0, 0.0, np.sin(a / 2)])


def _run(slide: float = 0.0, fall: float = 0.0, release_pad: bool = False,
         bounce: tuple[float, float] | None = None, set_down: bool = False):
    """Two pads on the box's ±x faces, rolling (the pads' bodies turn about the box's y axis
    while the material points at the contacts stay put); pad 1 slides ``slide`` along the
    face's z during 5-6 s; the box falls ``fall`` (with both pads) from 7 s; with
    ``release_pad``, pad 2 stops pressing at 7 s. With ``set_down``, the box (and the path) is
    back at its height of the grasp (on its stand) from 8.5 s."""
    t = np.arange(0.0, 10.0 + 1e-9, 0.01)
    K = t.size
    R_B = _rz(GAMMA)
    p = np.column_stack([0.7 + 0.0 * t, 0.05 * np.sin(t), 0.5 + 0.01 * t])
    if set_down:
        p[t >= 8.5, 2] = 0.5 + 0.01 * 1.0
    p[:, 2] -= fall * np.clip(t - 7.0, 0.0, 1.0)
    alpha = 0.2 * np.sin(0.7 * t)                          # the pads' rolling angle
    s = slide * np.clip(t - 5.0, 0.0, 1.0)                 # pad 1's slide along the face
    logs = {}
    for name, side in (("robot1", -1.0), ("robot2", 1.0)):
        n = side * R_B[:, 0]                               # the face's outward normal
        z_axis = R_B[:, 2]
        # Rolling without sliding: the centre moves by d·α along the face when the pad turns
        # by α about the box's y axis (sign: the contact point sits at −d n from the centre).
        roll = -side * DEPTH * alpha
        E = p + (HALF_WIDTH + DEPTH) * n + np.outer(roll + (s if side < 0 else 0.0), z_axis)
        R_P = np.array([R_B @ _ry(a) for a in alpha])
        f_n = np.where((t >= 1.0) & (t < 9.0), 20.0, 0.0)
        if release_pad and side > 0:
            f_n = np.where(t >= 7.0, 0.0, f_n)
        if bounce is not None and side > 0:                # pad 2 leaves the box a moment
            f_n = np.where((t >= bounce[0]) & (t < bounce[1]), 0.0, f_n)
        f_t = 0.4 * f_n
        F = np.outer(f_n, n) + np.outer(f_t, z_axis)
        pose = np.column_stack([np.tile(_quaternion_z(GAMMA), (K, 1)), p])
        f_n_log, f_t_log, p_B = pad_contact_components(F, E, pose)
        x_d = E - np.outer(s, z_axis) if side < 0 else E.copy()
        x_d[:, 2] += fall * np.clip(t - 7.0, 0.0, 1.0)     # the path did not fall
        logs[name] = {"t": t, "x": E, "x_d": x_d, "F_meas": F, "object_pose": pose,
                      "pad_normal_force": f_n_log, "pad_tangential_force": f_t_log,
                      "pad_in_object": p_B, "pad_rotation": R_P,
                      # the arm's own signals (not used by the object's metrics)
                      "q": np.zeros((K, 3)), "q_hat": np.zeros((K, 3)),
                      "lambda_meas": f_n, "lambda_hat": f_n, "lambda_d": f_n}
    meta = {"phases": PHASES, "friction": MU, "object_size": [2 * HALF_WIDTH, 0.08, 0.1]}
    return t, logs, meta


def test_quaternion_rotations_match_closed_form():
    R = quaternion_rotations(np.array([_quaternion_z(GAMMA), [0.0, 0.0, 1.0, 0.0]]))
    np.testing.assert_allclose(R[0], _rz(GAMMA), atol=1e-15)
    np.testing.assert_allclose(R[1], np.diag([-1.0, 1.0, -1.0]), atol=1e-15)


def test_contact_components_and_cone_use():
    t, logs, meta = _run()
    sig = object_signals(logs, meta)
    held = (t >= 1.0) & (t < 9.0)
    for name in logs:
        np.testing.assert_allclose(logs[name]["pad_normal_force"][held], 20.0, rtol=1e-12)
        np.testing.assert_allclose(logs[name]["pad_tangential_force"][held], 8.0, rtol=1e-12)
        np.testing.assert_allclose(sig[name]["friction_use"][held], 0.4 / MU, rtol=1e-12)
        assert np.isnan(sig[name]["friction_use"][~held]).all()
        # The pad's centre sits d outside the face, on its own side.
        np.testing.assert_allclose(np.abs(logs[name]["pad_in_object"][held, 0]),
                                   HALF_WIDTH + DEPTH, atol=1e-12)


def test_rolling_is_not_slip_and_a_slide_is_counted():
    t, logs, meta = _run()
    sig = object_signals(logs, meta)
    for name in logs:
        assert np.nanmax(sig[name]["slip"]) < 1e-6, name       # rolling only
        assert sig[name]["slip_events"].size == 0
        assert sig[name]["drop_events"].size == 0
        assert np.nanmax(sig[name]["object_position_error"]) < 1e-12
    slide = 2.5 * SLIP_DISTANCE
    t, logs, meta = _run(slide=slide)
    sig = object_signals(logs, meta)
    assert np.nanmax(sig["robot1"]["slip"]) == pytest.approx(slide, rel=1e-3)
    assert np.nanmax(sig["robot2"]["slip"]) < 1e-6
    events = t[sig["robot1"]["slip_events"]]
    assert events.size == 2 and (events > 5.0).all() and (events <= 6.0).all()
    metrics = compute_metrics(logs, meta)
    assert metrics["robot1"]["circle"]["slips"]["count"] == 2
    assert metrics["robot1"]["lift"]["slips"]["count"] == 0
    assert metrics["robot2"]["circle"]["slips"]["count"] == 0
    assert metrics["robot1"]["circle"]["slip"]["max"] == pytest.approx(slide, rel=1e-3)


def test_a_fall_and_a_lost_pad_are_drops():
    t, logs, meta = _run(fall=2 * DROP_DISTANCE)
    sig = object_signals(logs, meta)
    (k,) = sig["robot1"]["drop_events"]
    assert t[k] == pytest.approx(7.5, abs=0.02)              # error passes DROP_DISTANCE
    assert np.nanmax(sig["robot1"]["object_position_error"]) == pytest.approx(
        2 * DROP_DISTANCE, rel=1e-9)
    metrics = compute_metrics(logs, meta)
    assert metrics["robot2"]["circle"]["drops"]["count"] == 1
    assert metrics["robot2"]["lift"]["drops"]["count"] == 0
    t, logs, meta = _run(release_pad=True)
    (k,) = object_signals(logs, meta)["robot1"]["drop_events"]
    assert t[k] == pytest.approx(7.0, abs=1e-9)


def test_mass_convergence_is_the_time_from_which_the_carried_estimate_stays_within_5_percent():
    """A constructed estimate: a prior 50 % high decaying as exp(−t/τ) from the grasp (1 s),
    then, in the put-down (8-9 s), the stand taking the box's weight back. The closed form:
    0.5 exp(−(t − 1)/τ) <= 0.05 from t = 1 + τ ln 10; the put-down does not undo it."""
    t, logs, meta = _run()
    m, tau = 0.5, 0.7
    share = m * (1.0 + 0.5 * np.exp(-np.clip(t - 1.0, 0.0, None) / tau)) / 2.0
    share = np.where(t >= 8.0, 0.2 * share, share)         # the stand carries the box
    for log in logs.values():
        log["mass_share"] = share
    meta = dict(meta, object_mass=m)
    out = object_signals(logs, meta)
    expected = tau * np.log(10.0)
    dt = t[1] - t[0]
    assert out["robot1"]["mass_convergence_time"] == pytest.approx(expected, abs=dt + 1e-9)
    # Never within 5 %: null.
    for log in logs.values():
        log["mass_share"] = np.full_like(t, 0.6 * m / 2.0)
    assert object_signals(logs, meta)["robot1"]["mass_convergence_time"] is None


def test_a_bounce_at_the_first_touch_is_not_a_drop_but_a_later_one_is():
    """Pad 2 leaves the box for 30 ms: 20 ms after the first touch (the grasp not yet settled,
    SETTLE_TIME = 0.1 s) no drop is counted; at 5 s (the box carried) one is."""
    t, logs, meta = _run(bounce=(1.02, 1.05))
    assert object_signals(logs, meta)["robot1"]["drop_events"].size == 0
    t, logs, meta = _run(bounce=(5.0, 5.03))
    (k,) = object_signals(logs, meta)["robot1"]["drop_events"]
    assert t[k] == pytest.approx(5.0, abs=1e-9)


@pytest.mark.parametrize("set_down, drops", [(True, 0), (False, 1)])
def test_a_pad_letting_go_of_a_box_set_down_on_its_stand_is_not_a_drop(set_down, drops):
    """Pad 2 stops pressing at 8.9 s, 0.1 s before the release: a drop while the box is
    carried (1.0 cm above its height at the grasp), none once it rests again at that
    height (the stand carries it: the put-down's last moments)."""
    t, logs, meta = _run(bounce=(8.9, 9.0), set_down=set_down)
    events = object_signals(logs, meta)["robot1"]["drop_events"]
    assert events.size == drops
    assert compute_metrics(logs, meta)["robot1"]["put_down"]["drops"]["count"] == drops
    if drops:
        assert t[events[0]] == pytest.approx(8.9, abs=1e-9)
