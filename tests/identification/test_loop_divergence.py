"""A closed loop that diverges in the closed-loop estimators ends their iterations with one
line, before a non-finite state reaches Drake (:class:`~drake_coop.identification.
instrumental.ClosedLoopDiverged`)."""

import dataclasses

import numpy as np
import pytest

from drake_coop.identification.estimate import Estimate
from drake_coop.identification.instrumental import (
    MAX_LOOP_SPEED,
    ClosedLoopDiverged,
    ModelDynamics,
    estimate_parameters_didim,
    simulate_tracking,
)
from drake_coop.identification.regressor import Regressor
from drake_coop.identification.report import closed_loop, identify_robot
from drake_coop.scenario.loading import load_scenario


@pytest.fixture(scope="module")
def unstable_loop():
    """The paper arm's identification loop with its PD gains negated (positive feedback)."""
    from drake_coop.plant.arms import Arm
    from drake_coop.plant.model_error import controller_arm_model

    sc = load_scenario("scenarios/paper.yaml")
    ident = identify_robot(sc, 0, 2.0)
    nominal = controller_arm_model(Arm(sc.robots[0], sc.task), sc.robots[0].model_error)
    loop = closed_loop(sc, 0, ident.excitation, nominal, ident.data)
    return ident, dataclasses.replace(loop, kp=-50 * loop.kp, kv=-50 * loop.kv,
                                      torque_limits=None)


def test_a_diverging_loop_stops_in_one_line_before_drake_sees_it(unstable_loop):
    ident, loop = unstable_loop
    with pytest.raises(ClosedLoopDiverged) as err:
        simulate_tracking(ModelDynamics(ident.structure, ident.theta_true), loop.q_d, loop.v_d,
                          loop.feedforward, loop.kp, loop.kv, loop.h, loop.substeps)
    text = str(err.value)
    assert "\n" not in text and text.startswith("the closed loop simulated with the estimate "
                                                "diverged at t = ")
    assert f"bound {MAX_LOOP_SPEED:g} rad/s" in text


def test_didim_whose_loop_diverges_keeps_its_start_and_says_why(unstable_loop):
    ident, loop = unstable_loop
    theta = ident.theta_true
    start = Estimate(theta=theta, theta_ls=theta, residual_rms=np.zeros(3),
                     condition_number=1.0, rank=22, samples=0, solver="none")
    tau = np.zeros_like(loop.q_d)
    est = estimate_parameters_didim(Regressor(ident.structure), tau, theta, loop,
                                    iterations=3, start=start)
    assert est.stopped.startswith("the closed loop simulated with the estimate diverged")
    np.testing.assert_array_equal(est.theta, theta)
