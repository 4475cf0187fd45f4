"""One tick's equations of one robot timed with ``timeit`` outside the diagram
(:func:`_tick_costs`)."""

from __future__ import annotations

import timeit

import numpy as np


def _tick_costs(scenario) -> dict[str, float]:
    """Microseconds per tick of each system's equations on held samples of robot 1.

    Two postures alternate from call to call, as ``q`` changes from tick to tick (the model
    keeps its kinematics while ``q`` is unchanged). The last entry is one whole tick of the
    robot: (15)/(8), (22), (13) and (16) at the same sample.
    """
    from drake_coop.plant.arms import arm_model
    from drake_coop.control.finger import FingerLaw
    from drake_coop.experiment.plan import plan_run
    from drake_coop.plant.arms import Arm

    robot = scenario.robots[0]
    law = FingerLaw(arm_model(Arm(robot, scenario.task)), robot.gains)
    _, r = plan_run(scenario).robots[0].samples
    k = int(np.argmax(law.layout.column(r, "held")[:, 0] > 0.5)) + 1000
    ref = law.layout.unpack(r[k])
    DF = np.full(law.m, 0.1)
    q_hat, qdot_hat_o = ref.q_d.copy(), ref.qdot_d.copy()
    samples = [ref.q_d + 1e-4, ref.q_d - 1e-4]
    state = {"i": 0}

    def q_next():
        state["i"] ^= 1
        return samples[state["i"]]

    def controller():
        q = q_next()
        qdot_hat, qdot_o = law.observer_derivative(q, q_hat, qdot_hat_o)
        return law.control(q, q_hat, qdot_hat, qdot_o, ref.lambda_d, DF, ref)

    def tick():
        q = q_next()
        qdot_hat, qdot_o = law.observer_derivative(q, q_hat, qdot_hat_o)
        lam = law.force_estimate(q, q_hat, qdot_o, ref, DF)
        terms = law.control(q, q_hat, qdot_hat, qdot_o, lam, DF, ref)
        return law.observer_acceleration(q, q_hat, terms["qddot_r_hat"])

    qdot_o = law.observer_derivative(samples[0], q_hat, qdot_hat_o)[1]
    n = 1000
    costs = {
        "controller (13)": controller,
        "force observer (22)": lambda: law.force_estimate(q_next(), q_hat, qdot_o, ref, DF),
        "velocity observer (15)-(16)": lambda: (law.observer_derivative(q_next(), q_hat,
                                                                        qdot_hat_o),
                                                law.observer_acceleration(q_hat, q_hat,
                                                                          ref.qddot_d)),
        "one tick of one robot (all three)": tick,
    }
    return {name: 1e6 * min(timeit.repeat(f, number=n, repeat=3)) / n for name, f in costs.items()}
