"""Identification over the wire (:mod:`drake_coop.robot.wire_identify`,
:mod:`drake_coop.identification.recording`): the checks before the first command, the recording
against what the wire carried (a spy on the channels), the recording's format, and the
identification from a recording against the simulated experiment's own."""

import numpy as np
import pytest
from pydrake.lcm import DrakeLcm

from drake import lcmt_panda_command, lcmt_panda_status
from drake_coop.identification.clearance import first_contact
from drake_coop.identification.recording import (
    FORMAT,
    read_recording,
    recording_from_data,
    write_recording,
)
from drake_coop.identification.report import identify_recording, identify_robot
from drake_coop.identification.setup import identification_setup
from drake_coop.robot.wire_identify import Lockstep, WireRefusal, _Arm, drive, preflight
from drake_coop.robot.driver_spec import driver_specs
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.model_check import check_models
from drake_coop.scenario.driver import Driver


def status_bytes(q, v=None, utime=0):
    msg = lcmt_panda_status()
    msg.utime = int(utime)
    msg.num_joints = len(q)
    msg.joint_position = [float(x) for x in q]
    msg.joint_velocity = [float(x) for x in (np.zeros(len(q)) if v is None else v)]
    for f in ("joint_torque", "joint_torque_external", "joint_position_desired",
              "joint_velocity_desired", "joint_acceleration_desired", "joint_torque_desired"):
        setattr(msg, f, [0.0] * len(q))
    return msg.encode()


def spy(lcm, channels):
    got = {c: [] for c in channels}
    for c in channels:
        lcm.Subscribe(c, lambda data, c=c: got[c].append(bytes(data)))
    return got


def arms_of(s, robots=(0, 1)):
    specs = driver_specs(s, check_models(s))
    return [_Arm(index=i, spec=specs[i], setup=identification_setup(s, i)) for i in robots]


def rest(s):
    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.simulate import rest_posture

    return rest_posture(plan_run(s))[0]


def test_robot_adds_is_refused_before_the_first_command():
    """With the robot adding its own g(q) the torque on the arm is unknown to the estimator:
    refused in one line naming the field, nothing sent."""
    s = load_scenario()
    lcm = DrakeLcm("memq://")
    specs = driver_specs(s, check_models(s))
    commands = spy(lcm, [sp.command_channel for sp in specs])
    with pytest.raises(WireRefusal, match=r"^robots\[0\]\.driver\.gravity: robot_adds .*no "
                                          "command sent$"):
        drive(s, [0, 1], lcm, Lockstep(s, lcm, specs), duration=2.0, specs=specs)
    lcm.HandleSubscriptions(0)
    assert all(not v for v in commands.values())


@pytest.mark.parametrize("case, message", [
    ("moving", r"^robots\[0\] \(robot1\): the arm is moving \(0\.05 rad/s"),
    ("invalid", r"^robots\[0\] \(robot1\): the status on PANDA_STATUS_robot1 is not valid"),
    ("outside", r"^robots\[0\] \(robot1\): joint 2 reads .* outside the URDF's limits"),
    ("silent", r"^robots\[1\] \(robot2\): no status on PANDA_STATUS_robot2"),
])
def test_each_arm_is_checked_before_the_first_command(case, message):
    s = load_scenario()
    q = [np.asarray(x, float) for x in rest(s)]
    first = {0: status_bytes(q[0]), 1: status_bytes(q[1])}
    if case == "moving":
        first[0] = status_bytes(q[0], v=[0.0, 0.05, 0.0])
    elif case == "invalid":
        first[0] = status_bytes([np.nan, 0.0, 0.0])
    elif case == "outside":
        a = identification_setup(s, 0).arm
        first[0] = status_bytes(np.r_[q[0][0], a.q_max[1] + 0.1, q[0][2]])
    else:
        del first[1]
    with pytest.raises(WireRefusal, match=message) as err:
        preflight(s, arms_of(s), first, 2.0, 0)
    assert "\n" not in str(err.value) and str(err.value).endswith("no command sent")


def test_arms_that_would_touch_are_refused_by_the_geometry_query():
    """The paper's arms with their links taken 0.5 m thick (capsules of radius 0.25 m): the
    forearms, 0.4 m apart at rest, overlap; the line names both arms. At the default radius
    nothing touches at rest."""
    s = load_scenario()
    q = [np.asarray(x, float) for x in rest(s)]
    line = first_contact(s, {}, q, 1.0, radius=0.25)
    assert line is not None and "robot1" in line and "robot2" in line
    assert line.endswith("mm)") and "\n" not in line
    assert first_contact(s, {}, q, 1.0) is None


def _known_torque(s):
    """The arms' drivers with the torque on the arm known to identification (the wire's
    own: nobody adds gravity), as identification over the wire requires."""
    for r in s.robots:
        r.driver = Driver(gravity="none")
    return load_scenario(data=dump_scenario(s))


def test_a_refusal_sends_no_command():
    s = _known_torque(load_scenario())
    lcm = DrakeLcm("memq://")
    specs = driver_specs(s, check_models(s))
    commands = spy(lcm, [sp.command_channel for sp in specs])
    with pytest.raises(WireRefusal, match="touch at t = .*no command sent$"):
        drive(s, [0, 1], lcm, Lockstep(s, lcm, specs), duration=2.0, specs=specs,
              clearance_radius=0.25)
    lcm.HandleSubscriptions(0)
    assert all(not v for v in commands.values())


def test_the_recording_format_round_trips_and_refuses_a_foreign_file(tmp_path):
    s = load_scenario()
    setup = identification_setup(s, 0)
    from drake_coop.identification.setup import design_for
    from drake_coop.identification.collect import ExcitationData

    e = design_for(setup, 2.0, 0)
    t = np.arange(5) * 0.009
    data = ExcitationData(t=t, q=np.random.default_rng(0).normal(size=(5, 3)),
                          tau=np.ones((5, 3)), h=0.009, torque_limits=np.full(3, 50.0),
                          q_true=np.zeros((5, 3)), v_true=np.zeros((5, 3)))
    path = tmp_path / "recording.npz"
    write_recording(path, [recording_from_data("robot1", 0, e, data)])
    back = read_recording(path)["robot1"]
    np.testing.assert_array_equal(back.q, data.q)
    np.testing.assert_array_equal(back.excitation.a, e.a)
    assert back.source == "simulation" and back.h == 0.009 and back.index == 0
    assert list(back.status_utime) == [0, 9000, 18000, 27000, 36000]
    np.savez(tmp_path / "other.npz", format=np.array("something else"))
    with pytest.raises(ValueError, match=f"format must be '{FORMAT}'"):
        read_recording(tmp_path / "other.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(ValueError, match="not a readable .npz file"):
        read_recording(tmp_path / "junk.npz")


def test_identification_from_a_recording_of_the_simulated_experiment_is_the_same(tmp_path):
    """The same estimator path: the simulated experiment's data written as a recording and
    read back identify to exactly the model identified from the simulation itself."""
    s = load_scenario()
    s.robots[0].model_error.mass_scale = 1.3
    s.robots[0].model_error.coulomb_friction = [0.5, 0.5, 0.5]
    s = load_scenario(data=dump_scenario(s))
    sim = identify_robot(s, 0, 3.0)
    path = tmp_path / "recording.npz"
    write_recording(path, [recording_from_data("robot1", 0, sim.excitation, sim.data)])
    wire = identify_recording(s, read_recording(path)["robot1"])
    np.testing.assert_array_equal(wire.estimate.theta, sim.estimate.theta)
    assert wire.urdf_text == sim.urdf_text and wire.validation == sim.validation


@pytest.mark.slow
def test_over_the_wire_the_recording_is_what_the_wire_carried_and_identifies_the_arm():
    """Both paper arms, 30 % heavy nominal models, Coulomb friction in the truth: 3 s driven
    through the in-process simulated driver in lockstep. The recording's torques are the
    commands a spy on the channels saw (bytes decoded), its positions the statuses'; the
    model identified from it predicts the truth's torques far better than the nominal one."""
    s = load_scenario()
    for r in s.robots:
        r.model_error.mass_scale = 1.3
        r.model_error.coulomb_friction = [0.5, 0.5, 0.5]
    s = _known_torque(s)
    lcm = DrakeLcm("memq://")
    specs = driver_specs(s, check_models(s))
    wire = spy(lcm, [sp.command_channel for sp in specs] + [sp.status_channel for sp in specs])
    recordings = drive(s, [0, 1], lcm, Lockstep(s, lcm, specs), duration=3.0, specs=specs)
    for rec, spec in zip(recordings, specs):
        sent = [np.array(lcmt_panda_command.decode(d).joint_torque)
                for d in wire[spec.command_channel]]
        assert len(sent) == len(rec.t) + 1                     # and the safe command last
        np.testing.assert_array_equal(np.array(sent[:-1]), rec.tau)
        stamps = {lcmt_panda_status.decode(d).utime: np.array(
            lcmt_panda_status.decode(d).joint_position) for d in wire[spec.status_channel]}
        for k in (0, 100, len(rec.t) - 1):
            np.testing.assert_array_equal(stamps[int(rec.status_utime[k])], rec.q[k])
        assert np.all(np.diff(rec.command_utime) > 0)
        ident = identify_recording(s, rec)
        v = ident.validation
        assert v["torque_error_rms_identified"] < 0.2 * v["torque_error_rms_nominal"], v


@pytest.mark.parametrize("args, message", [
    (["--wire", "memq://"], "--wire memq:// is in-process only"),
    (["--wire", "bogus://x"], "--wire 'bogus://x': unknown LCM provider"),
    (["--wire", "lockstep", "--recording", "r.npz"], "--wire and --recording: give one"),
    (["--recording", "missing.npz"], "--recording missing.npz: not a readable .npz file"),
])
def test_identify_wire_and_recording_bad_input_is_one_line_exit_2(tmp_path, capsys, args,
                                                                   message):
    from drake_coop.cli import main

    assert main(["identify", "paper", "--out", str(tmp_path / "out"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err
    assert not (tmp_path / "out").exists()
