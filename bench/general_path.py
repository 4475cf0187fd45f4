"""Cost of one robot's tick of the equations on the fast and the general path:
``python bench/general_path.py``.

One tick = (15)/(8), (22), (13) and (16) of one robot at one held sample, timed with ``timeit``
outside the diagram (as :func:`bench.harness._tick_costs`), for:

* the paper's arm (CRS A465, n = 3, m = 1, scalar ξ): the fast path on plain floats;
* the same arm with Drake's kinematics (``closed_form=False``): the general path at m = 1;
* the same arm with m = 2 and m = 3 constraint normals and a ξ matrix: the general path;
* the six-joint arm of ``scenarios/six_joint.yaml`` (n = 6, m = 1, orientation held): general.
"""

import timeit

import numpy as np

from drake_coop.plant.arms import arm_model
from drake_coop.control.finger import FingerLaw, Reference
from drake_coop.plant.arms import Arm
from drake_coop.scenario import load_scenario
from drake_coop.scenario.resources import find_scenario

NORMALS = {2: [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
           3: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]}


def tick_cost(robot, task, closed_form=None, q=None, n_calls=2000) -> float:
    """Microseconds of one held tick of ``robot``'s equations (best of 3 repeats)."""
    arm = Arm(robot, task)
    law = FingerLaw(arm_model(arm, closed_form=closed_form), robot.gains)
    n, m = law.n, law.m
    rng = np.random.default_rng(0)
    q = np.asarray(q if q is not None else rng.uniform(-0.5, 0.5, n) + 0.7, dtype=float)
    samples = [q + 1e-4, q - 1e-4]
    q_hat, qdot_hat_o = q.copy(), rng.normal(size=n) * 0.01
    ref = Reference(q + 1e-3, rng.normal(size=n) * 0.01, rng.normal(size=n) * 0.01,
                    np.full(m, 20.0), True)
    DF = np.full(m, 0.1)
    state = {"i": 0}

    def tick():
        state["i"] ^= 1
        qs = samples[state["i"]]
        qdot_hat, qdot_o = law.observer_derivative(qs, q_hat, qdot_hat_o)
        lam = law.force_estimate(qs, q_hat, qdot_o, ref, DF)
        terms = law.control(qs, q_hat, qdot_hat, qdot_o, lam, DF, ref)
        return law.observer_acceleration(qs, q_hat, terms["qddot_r_hat"])

    return 1e6 * min(timeit.repeat(tick, number=n_calls, repeat=3)) / n_calls, law.fast


def main() -> None:
    paper = load_scenario()
    robot = paper.robots[0]
    rows = [("paper arm n=3 m=1 (fast path)", tick_cost(robot, paper.task)),
            ("paper arm n=3 m=1, Drake kinematics (general)",
             tick_cost(robot, paper.task, closed_form=False))]
    for m in (2, 3):
        r = load_scenario().robots[0]
        r.normals = NORMALS[m]
        r.gains.xi_matrix = (np.eye(m) * r.gains.xi).tolist()
        rows.append((f"paper arm n=3 m={m}, xi matrix (general)", tick_cost(r, paper.task)))
    six = load_scenario(find_scenario("six_joint"))
    rows.append(("coop6 n=6 m=1 (general)",
                 tick_cost(six.robots[0], six.task, q=six.robots[0].q_seed)))
    for label, (us, fast) in rows:
        print(f"{label:48s} {us:7.1f} us per tick  (fast path: {fast})")


if __name__ == "__main__":
    main()
