"""The box's turn about the grasp line and its tilt (drake_coop.results.object_metrics), against
the box's logged pose built with Drake's AngleAxis: a known angle about a known line (the line
through the pads' contact points, computed here from the constructed pads) and a known tilt
about axes normal to it."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RotationMatrix

from drake_coop.results.metrics import compute_metrics
from drake_coop.results.object_metrics import object_signals, turn_and_tilt
from tests.results.test_object_metrics import DEPTH, GAMMA, _run


def _turn(t):
    return np.where(t >= 1.0, 0.04 * np.sin(1.3 * (t - 1.0)), 0.0)


def _tilt(t):
    return np.where(t >= 1.0, 0.02 * (1.0 - np.cos(0.9 * (t - 1.0))), 0.0)


def _with_rotation(t, logs):
    """The run's box turned by _turn about the grasp line and tilted by _tilt about a normal
    axis that itself turns about the line (R = R0 R_tilt R_turn, body frame)."""
    k0 = int(np.searchsorted(t, 1.0 - 1e-9))
    first = logs["robot1"]
    R0 = RotationMatrix(AngleAxis(GAMMA, [0.0, 0.0, 1.0]))
    p0 = first["object_pose"][k0, 4:]
    contacts = []
    for name, side in (("robot1", -1.0), ("robot2", 1.0)):
        n = side * R0.matrix()[:, 0]
        contact_world = logs[name]["x"][k0] - DEPTH * n         # the pad's point on the face
        contacts.append(R0.inverse().matrix() @ (contact_world - p0))
    a = (contacts[1] - contacts[0]) / np.linalg.norm(contacts[1] - contacts[0])
    assert abs(a[2]) > 1e-3                     # the line is not the box's x axis
    u = np.cross(a, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    pose = first["object_pose"].copy()
    for k, tk in enumerate(t):
        phi = 0.5 * tk
        b = np.cos(phi) * u + np.sin(phi) * v
        R = (R0 @ RotationMatrix(AngleAxis(float(_tilt(tk)), b))
             @ RotationMatrix(AngleAxis(float(_turn(tk)), a)))
        pose[k, :4] = R.ToQuaternion().wxyz()
    for log in logs.values():
        log["object_pose"] = pose
    return a


def test_turn_and_tilt_are_recovered_from_the_logged_pose():
    t, logs, meta = _run()
    _with_rotation(t, logs)
    sig = object_signals(logs, meta)
    held = (t >= 1.0) & (t < 9.0)
    for name in logs:
        np.testing.assert_allclose(sig[name]["object_turn"][held], _turn(t[held]), atol=1e-9)
        np.testing.assert_allclose(sig[name]["object_tilt"][held], _tilt(t[held]), atol=1e-9)
        assert np.isnan(sig[name]["object_turn"][~held]).all()
    circle = (t >= 4.0) & (t < 8.0)
    m = compute_metrics(logs, meta)["robot1"]["circle"]
    assert m["object_turn"]["rms"] == pytest.approx(np.sqrt(np.mean(_turn(t[circle]) ** 2)),
                                                    rel=1e-7)
    assert m["object_turn"]["max"] == pytest.approx(np.max(np.abs(_turn(t[circle]))), rel=1e-7)
    assert m["object_tilt"]["max"] == pytest.approx(np.max(_tilt(t[circle])), rel=1e-7)
    assert m["object_turn"]["unit"] == m["object_tilt"]["unit"] == "rad"


def test_a_turn_alone_is_no_tilt_and_a_tilt_alone_no_turn():
    a = np.array([0.6, 0.0, 0.8])
    b = np.array([0.8, 0.0, -0.6])
    q = np.array([RotationMatrix(AngleAxis(x, axis)).ToQuaternion().wxyz()
                  for x, axis in ((0.0, a), (0.3, a), (-0.2, a), (0.25, b), (0.1, [0, 1, 0]))])
    turn, tilt = turn_and_tilt(q, 0, a)
    np.testing.assert_allclose(turn, [0.0, 0.3, -0.2, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(tilt, [0.0, 0.0, 0.0, 0.25, 0.1], atol=1e-12)
    # The sign of the stored quaternion (q and -q are one rotation) changes nothing.
    turn2, tilt2 = turn_and_tilt(q * np.array([[1], [-1], [1], [-1], [1]]), 0, a)
    np.testing.assert_allclose(turn2, turn, atol=1e-12)
    np.testing.assert_allclose(tilt2, tilt, atol=1e-12)


def test_the_creep_floor_is_stated_beside_the_slip():
    from drake_coop.results.object_metrics import CREEP_RATE, creep_floor

    t, logs, meta = _run()
    meta["plant_time_step"] = 0.001
    m = compute_metrics(logs, meta)["robot1"]["circle"]["slip"]
    circle = t[(t >= 4.0) & (t < 8.0)]
    assert m["floor"] == pytest.approx(CREEP_RATE / 3 * (circle[-1] - circle[0]), rel=1e-12)
    assert creep_floor(0.003, 90.0) == pytest.approx(90 * CREEP_RATE, rel=1e-12)


def test_the_summary_prints_the_box_line_with_its_turn_and_floor():
    from drake_coop.results.summary import summary_lines

    t, logs, meta = _run()
    _with_rotation(t, logs)
    meta["plant_time_step"] = 0.003
    metrics = compute_metrics(logs, meta)
    (line,) = [x for x in summary_lines(metrics, meta) if x.strip().startswith("object:")]
    circle = (t >= 4.0) & (t < 8.0)
    turn = np.degrees(_turn(t[circle]))
    assert f"turn {np.sqrt(np.mean(turn ** 2)):.3g} / {np.max(np.abs(turn)):.3g}°" in line
    assert "creep floor" in line and line.endswith(" slips, 0 drops")
