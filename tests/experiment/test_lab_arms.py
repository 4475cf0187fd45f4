"""The shipped lab-arm scenarios (two Pandas, two UR5s from example-robot-data) hold the object
in the planes mode and build in the contact mode.

Compressed phases (free 1 s, lift 1 s, circle 10 s instead of 40 s, put-down 1 s, return 1 s)
keep the runs short (a 4 s circle, 100 times the paper's accelerations, gives the Pandas
0.22 mm); the measured errors against the simulated plant's own end-effector positions and
constraint forces (the logs' ground truth) must stay within the issue's targets, 0.1 mm and
0.1 N RMS in the circle phase. Skipped without example-robot-data (the ``robots`` extra).
"""

import dataclasses

import numpy as np
import pytest
from pydrake.common.yaml import yaml_load_typed

from drake_coop.control.arm_model import description_packages
from drake_coop.scenario import Scenario, Task, validate
from drake_coop.scenario.resources import scenarios_dir

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif("example-robot-data" not in description_packages(),
                       reason='example-robot-data is not installed (pip install -e ".[robots]")'),
]

SHORT = dict(t_pregrasp=0.6, t_grasp=1.0, t_circle_start=2.0, t_circle_end=12.0,
             t_release=13.0, t_end=14.0)


def short(name: str, mode: str = "planes") -> Scenario:
    s = yaml_load_typed(schema=Scenario, data=(scenarios_dir() / f"{name}.yaml").read_text())
    s.task = dataclasses.replace(s.task, **SHORT)
    s.plant.object_mode = mode
    validate(s)
    return s


@pytest.mark.parametrize("name", ["two_pandas", "two_ur5"])
def test_the_lab_arms_hold_the_object_around_the_circle(name):
    from drake_coop.experiment.simulate import simulate
    from drake_coop.results.metrics import compute_metrics

    result = simulate(short(name))
    assert result.ok
    metrics = compute_metrics(result.logs, result.meta)
    for robot in ("robot1", "robot2"):
        circle = metrics[robot]["circle"]
        worst_axis = max(circle[k]["rms"] for k in ("x_tilde", "y_tilde", "z_tilde"))
        assert worst_axis < 1e-4, (robot, worst_axis)
        assert circle["force_error"]["rms"] < 0.1, (robot, circle["force_error"])
        log = result.logs[robot]
        held = (log["t"] >= SHORT["t_circle_start"]) & (log["t"] < SHORT["t_circle_end"])
        # The squeeze is really there: the plant's constraint force follows (29).
        assert np.mean(log["lambda_meas"][held]) > 10.0


@pytest.mark.parametrize("name", ["two_pandas", "two_ur5"])
def test_the_lab_arms_build_and_run_in_the_contact_mode(name):
    from drake_coop.experiment.simulate import simulate

    result = simulate(short(name, "contact"), t_end=0.3)
    assert result.ok
    for robot in ("robot1", "robot2"):
        assert np.all(np.isfinite(result.logs[robot]["q"]))
