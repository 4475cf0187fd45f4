"""A driver's conventions declared in the scenario's ``driver:`` section (time base, gravity,
damping, safe command) and the command lines that use them: bad input is one line naming
the field or the option; no multicast unless asked for."""

import copy

import numpy as np
import pytest

from drake_coop.cli import main
from drake_coop.robot import cli as robot_cli
from drake_coop.robot import torque_driver
from drake_coop.robot.driver_spec import driver_specs
from drake_coop.scenario.driver import FRANKA_DAMPING
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.model_check import check_models
from drake_coop.scenario.driver import Driver
from drake_coop.scenario.schema import ScenarioError


def with_driver(**fields):
    s = copy.deepcopy(load_scenario())
    s.robots[1].driver = Driver(**fields)
    return dump_scenario(s)


@pytest.mark.parametrize("fields, match", [
    ({"time_base": "gps"}, r"^robots\[1\]\.driver\.time_base"),
    ({"gravity": "robot"}, r"^robots\[1\]\.driver\.gravity"),
    ({"safe_command": "zero_torque"}, r"^robots\[1\]\.driver\.safe_command: zero_torque "
                                      r"would send -g\(q\)"),
    ({"damping": [1.0, 2.0]}, r"^robots\[1\]\.driver\.damping must list 3 gains"),
    ({"damping": [1.0, -2.0, 1.0]}, r"robots\[1\]\.driver\.damping"),
])
def test_bad_conventions_are_refused_naming_the_field(fields, match):
    with pytest.raises(ScenarioError, match=match) as exc:
        load_scenario(data=with_driver(**fields))
    assert "\n" not in str(exc.value)


def test_the_defaults_are_drake_franka_drivers():
    s = load_scenario(data=with_driver())
    spec = driver_specs(s, check_models(s))[1]
    assert (spec.time_base, spec.gravity, spec.safe_command, spec.command_timeout) == (
        "epoch", "robot_adds", "hold", 0.1)
    np.testing.assert_array_equal(spec.damping, [min(FRANKA_DAMPING)] * 3)   # 3 joints
    s = load_scenario(data=with_driver(gravity="none", safe_command="zero_torque",
                                       time_base="run", damping=[1.0, 2.0, 3.0]))
    spec = driver_specs(s, check_models(s))[1]
    assert (spec.time_base, spec.gravity, spec.safe_command) == ("run", "none", "zero_torque")
    np.testing.assert_array_equal(spec.damping, [1.0, 2.0, 3.0])


@pytest.mark.parametrize("command", ["serve", "sim-driver"])
def test_no_lcm_url_is_refused_never_multicast_by_default(tmp_path, capsys, command):
    extra = ["--out", str(tmp_path / "o")] if command == "serve" else []
    assert main([command, "paper", "--quiet", *extra]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--lcm-url is required" in err[0], err
    assert "tcpq://" in err[0] and "memq://" in err[0]
    assert not (tmp_path / "o").exists()


def test_the_emulation_refuses_an_arm_without_seven_joints(capsys):
    assert main(["sim-driver", "paper", "--lcm-url", "memq://", "--emulate",
                 "drake-franka-driver", "--quiet", "--command-wait", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith(
        "robots: robot1 has 3 joints; drake-franka-driver serves 7 only"), err


@pytest.mark.parametrize("value", ["0", "-1", "inf", "nan"])
def test_a_bad_cutoff_is_refused_naming_the_option(capsys, value):
    assert main(["sim-driver", "paper", "--lcm-url", "memq://", "--low-pass-freq", value,
                 "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--low-pass-freq" in err[0], err


def test_the_command_lines_names_are_the_emulations():
    assert robot_cli.EMULATE == torque_driver.EMULATE
    assert robot_cli.FRANKA_LOW_PASS_HZ == torque_driver.FRANKA_LOW_PASS_HZ
    assert robot_cli.FRANKA_NO_FILTER_HZ == torque_driver.FRANKA_NO_FILTER_HZ
