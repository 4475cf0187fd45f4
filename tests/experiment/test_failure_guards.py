"""The failure guards (:mod:`drake_coop.experiment.failure`): each trips on a sample made to
fail it and names the robot or the box, the time and the quantity; the tilt against the run
metric's independent computation; a simulated run made to fail ends ``failed``, exit 1."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from drake_coop.experiment.failure import (
    SETTLE_TIME,
    SQUEEZE_SETTLE,
    FailureCheck,
    GraspSample,
    first_failure_in_logs,
    tilt_about_line,
)
from drake_coop.results.object_metrics import turn_and_tilt
from drake_coop.scenario.schema import Guards

W = 0.05          # the box's half width


def _quat(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * a])


def _check(**guards):
    return FailureCheck(Guards(**guards), ["robot1", "robot2"], 1.0, 7.0, contact=True,
                        half_width=W)


def _sample(t, *, dx=0.0, lam=(10.0, 10.0), lam_d=(10.0, 10.0), q=(1, 0, 0, 0),
            box_shift=(0.0, 0.0, 0.0), f_n=(10.0, 10.0)):
    """Pads at the box's ±x faces (centres 15 mm out), the box at the origin + shift."""
    x_d = [np.array([-W - 0.015, 0.0, 0.5]), np.array([W + 0.015, 0.0, 0.5])]
    box = np.array([0.0, 0.0, 0.5]) + np.asarray(box_shift)
    x = [x_d[0] + [dx, 0, 0] + box_shift, x_d[1] + box_shift]
    # the box's force on each pad: along the face's outward normal (pushing the pad away)
    F = [np.array([-f_n[0], 0.0, 0.0]), np.array([f_n[1], 0.0, 0.0])]
    return GraspSample(t, x, x_d, [np.array([v]) for v in lam], [np.array([v]) for v in lam_d],
                       np.concatenate([q, box]), F)


def test_the_tilt_is_the_swing_normal_to_the_grasp_line_as_the_metric_computes_it():
    rng = np.random.default_rng(3)
    axis = np.array([1.0, 0.0, 0.0])
    # closed forms: a turn about the line is no tilt, a rotation about a normal all tilt
    assert tilt_about_line(np.array([1.0, 0, 0, 0]), _quat(axis, 0.7), axis) == pytest.approx(0)
    assert tilt_about_line(np.array([1.0, 0, 0, 0]), _quat([0, 1, 0], 0.7), axis) == \
        pytest.approx(0.7)
    q0 = _quat(rng.normal(size=3), 1.1)
    qs = np.array([q0] + [_quat(rng.normal(size=3), rng.uniform(0, 3)) for _ in range(50)])
    _, expected = turn_and_tilt(qs, 0, axis)          # results' independent computation
    got = [tilt_about_line(q0, q, axis) for q in qs]
    np.testing.assert_allclose(got, expected, atol=1e-9)


def test_a_pad_off_its_path_fails_naming_the_robot_time_and_distance():
    check = _check(max_pad_error=0.02)
    assert check.check(_sample(0.5, dx=0.019)) is None
    f = check.check(_sample(0.6, dx=0.021))
    assert (f.guard, f.who, f.t) == ("max_pad_error", "robot1", 0.6)
    assert f.message == ("failed at t = 0.600 s: robot1 pad 21.0 mm off its path "
                         "(guards.max_pad_error = 20 mm)")


def test_the_squeeze_is_checked_while_held_once_settled():
    check = _check(max_squeeze_error=5.0)
    assert check.check(_sample(0.9, lam=(0.0, 0.0))) is None          # before the grasp
    assert check.check(_sample(1.0 + SQUEEZE_SETTLE - 0.01, lam=(0.0, 10.0))) is None
    f = check.check(_sample(1.0 + SQUEEZE_SETTLE, lam=(10.0, 16.0)))
    assert (f.guard, f.who, f.value) == ("max_squeeze_error", "robot2", pytest.approx(6.0))
    assert "squeeze 6.0 N from its reference (guards.max_squeeze_error = 5 N)" in f.message
    assert _check(max_squeeze_error=5.0).check(_sample(7.0, lam=(0.0, 0.0))) is None  # released


def test_a_box_off_its_path_or_tilted_fails_naming_the_box():
    check = _check(max_object_position_error=0.02, max_pad_error=1.0)   # pads and box fall
    check.check(_sample(1.0))                       # the grasp: the box's reference
    assert check.check(_sample(1.5, box_shift=(0.0, 0.0, -0.019))) is None
    f = check.check(_sample(1.6, box_shift=(0.0, 0.0, -0.021)))
    assert (f.guard, f.who) == ("max_object_position_error", "box")
    assert "box 21.0 mm off its path" in f.message
    check = _check(max_object_tilt_deg=10.0)
    check.check(_sample(1.0))
    assert check.check(_sample(1.5, q=_quat([1, 0, 0], math.radians(40)))) is None   # a turn
    f = check.check(_sample(1.6, q=_quat([0, 1, 0], math.radians(11))))
    assert (f.guard, f.who, f.value) == ("max_object_tilt_deg", "box", pytest.approx(11.0))
    assert "box tilted 11.0 deg (guards.max_object_tilt_deg = 10)" in f.message


def test_a_pad_letting_go_of_the_box_off_its_stand_loses_the_grasp():
    check = _check(max_pad_error=1.0)
    check.check(_sample(1.0))
    assert check.check(_sample(1.05, f_n=(0.0, 10.0), box_shift=(0, 0, 0.005))) is None  # not
    assert check.check(_sample(1.1)) is None                   # established yet
    assert check.check(_sample(1.1 + SETTLE_TIME)) is None     # now established
    # set down on its stand: letting go is fine
    assert check.check(_sample(1.3, f_n=(0.1, 10.0), box_shift=(0, 0, 0.0005))) is None
    f = check.check(_sample(1.4, f_n=(10.0, 0.1), box_shift=(0, 0, 0.005)))
    assert (f.guard, f.who) == ("grasp_lost", "robot2")
    assert "robot2 lost the grasp: its pad presses 0.10 N" in f.message
    assert _check(grasp_lost=False).check(_sample(1.0)) is None


def test_the_logs_are_swept_tick_by_tick_for_what_a_chunk_end_missed():
    t = np.arange(0.0, 2.0, 0.01)
    x_d = np.zeros((t.size, 3))
    x = x_d.copy()
    x[123, 0] = 0.03                                  # one tick off its path
    logs = {r: {"t": t, "x": x if r == "robot2" else x_d, "x_d": x_d,
                "lambda_meas": np.zeros(t.size), "lambda_d": np.zeros(t.size)}
            for r in ("robot1", "robot2")}
    check = FailureCheck(Guards(), ["robot1", "robot2"], 1.0, 7.0)
    f = first_failure_in_logs(check, logs)
    assert (f.guard, f.who, f.t) == ("max_pad_error", "robot2", pytest.approx(1.23))
    x[123, 0] = 0.0
    assert first_failure_in_logs(check, logs) is None


@pytest.mark.parametrize("field, value, text", [
    ("max_pad_error", -0.1, "guards.max_pad_error"),
    ("max_object_tilt_deg", 200.0, "guards.max_object_tilt_deg"),
    ("max_squeeze_error", 0.0, "guards.max_squeeze_error"),
    ("grasp_lost", "yes", "guards.grasp_lost must be true or false"),
])
def test_a_bad_guard_field_is_refused_in_one_line(field, value, text):
    from drake_coop.scenario import default_scenario, validate
    from drake_coop.scenario.schema import ScenarioError

    s = default_scenario()
    setattr(s.guards, field, value)
    with pytest.raises(ScenarioError) as err:
        validate(s)
    assert text in str(err.value) and "\n" not in str(err.value)


def test_a_run_whose_pads_leave_their_path_fails_exits_1_and_keeps_its_logs(tmp_path, capsys,
                                                                           monkeypatch):
    """The paper's arms, no object, each with an unknown 10 kg payload: they sag, and the run
    stops failed within a guard chunk of a pad passing 20 mm, exit 1, one line; logs,
    run.json and figures written (only the figure checked is drawn:
    :func:`tests.conftest.draw_only`). The squeeze is not checked without an object."""
    from drake_coop.cli import main
    from drake_coop.scenario import dump_scenario
    from tests.conftest import draw_only, short_scenario

    draw_only(monkeypatch, "fig2_tracking_errors")
    s = short_scenario("none", 0.003)
    for r in s.robots:
        r.model_error.payload_mass = 10.0
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(s))
    out = tmp_path / "o"
    code = main(["run", str(path), "--out", str(out), "--quiet", "--no-replay",
                 "--t-end", "2"])
    assert code == 1
    err = [line for line in capsys.readouterr().err.splitlines() if "failed at" in line]
    assert len(err) == 1 and "pad" in err[0] and "guards.max_pad_error = 20 mm" in err[0]
    meta = json.loads((out / "run.json").read_text())
    assert meta["status"] == "failed" and meta["failure"]["guard"] == "max_pad_error"
    t_fail = meta["failure"]["t"]
    log = np.load(out / f"{meta['failure']['who']}.npz")
    e = np.linalg.norm(log["x"] - log["x_d"], axis=1)
    # the truth passed the bound no earlier than one chunk before the stop
    assert e[-1] > 0.02 and log["t"][np.argmax(e > 0.02)] > t_fail - 0.09 - 1e-9
    assert (out / "fig2_tracking_errors.png").exists()


def test_an_unknown_payload_makes_the_squeeze_fail_its_guard():
    """The paper's planes, each arm with an unknown 3 kg payload: the squeeze leaves its
    reference by more than 20 N after the grasp; the run stops failed there."""
    from drake_coop.experiment.simulate import simulate
    from tests.conftest import short_scenario

    s = short_scenario("planes", 0.003)
    for r in s.robots:
        r.model_error.payload_mass = 3.0
    result = simulate(s, t_end=3.0)
    failure = result.meta["failure"]
    assert result.meta["status"] == "failed" and failure["guard"] == "max_squeeze_error"
    assert failure["value"] > 20.0 and 1.0 + SQUEEZE_SETTLE <= failure["t"] < 2.0
    log = result.logs[failure["who"]]
    e = np.abs(log["lambda_meas"] - log["lambda_d"])
    assert e[-1] > 20.0                     # the truth at the stop is past the bound


def _logs_of(samples):
    """Logs (``collect_logs``'s arrays) holding the samples, row by row."""
    names = ["robot1", "robot2"]
    t = np.array([s.t for s in samples])
    return {r: {"t": t, "x": np.array([s.x[i] for s in samples]),
                "x_d": np.array([s.x_d[i] for s in samples]),
                "lambda_meas": np.array([s.lam[i][0] for s in samples]),
                "lambda_d": np.array([s.lam_d[i][0] for s in samples]),
                "object_pose": np.array([s.pose for s in samples]),
                "F_meas": np.array([s.F[i] for s in samples])} for i, r in enumerate(names)}


@pytest.mark.parametrize("event", ["none", "pad", "squeeze", "position", "tilt", "lost",
                                   "lost_before_established", "set_down"])
def test_the_sweep_of_the_logs_is_the_sample_by_sample_check(event):
    """The arrays' sweep (after the run) reports what the stateful check fed every tick in
    order reports (during the run): the same guard, robot and tick."""
    rng = np.random.default_rng(len(event))
    samples = []
    for k in range(300):
        t = 0.9 + 0.01 * k
        kw = dict(q=_quat(rng.normal(size=3), 0.002), box_shift=tuple(1e-4 * rng.normal(size=3)))
        if t >= 1.2:
            kw["box_shift"] = (0.0, 0.0, 0.003)       # lifted
        if event == "pad" and t > 2.0:
            kw["dx"] = 0.03
        if event == "squeeze" and t > 1.2:
            kw["lam"] = (10.0, 40.0)
        if event == "position" and t > 2.2:
            kw["box_shift"] = (0.0, 0.0, -0.03)
        if event == "tilt" and t > 2.5:
            kw["q"] = _quat([0, 1, 0], math.radians(20))
        if event == "lost" and t > 2.0:
            kw["f_n"] = (0.1, 10.0)
        if event == "lost_before_established" and 1.0 < t < 1.05:
            kw["f_n"] = (0.1, 10.0)
        if event == "set_down" and t > 3.0:
            kw["box_shift"], kw["f_n"] = (0.0, 0.0, 0.0), (0.1, 0.1)
        samples.append(_sample(t, **kw))
    stateful = _check(max_pad_error=0.02, max_object_position_error=0.02)
    expected = next((f for f in map(stateful.check, samples) if f is not None), None)
    got = first_failure_in_logs(_check(max_pad_error=0.02, max_object_position_error=0.02),
                                _logs_of(samples))
    if expected is not None:
        assert (got.guard, got.who, got.t) == (expected.guard, expected.who, expected.t)
        assert got.value == pytest.approx(expected.value, rel=1e-12)
    else:
        assert got is None
    assert (expected is None) == (event in ("none", "lost_before_established", "set_down"))
