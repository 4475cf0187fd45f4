"""Cost of one robot's tick of the equations on the fast and the general path:
``python bench/general_path.py``.

One tick = (15)/(8), (22), (13) and (16) of one robot at one held sample, timed with ``timeit``
outside the diagram (as :func:`bench.harness._tick_costs`), for:

* the paper's arm (CRS A465, n = 3, m = 1, scalar ξ): the fast path on plain floats;
* the same arm with Drake's kinematics (``closed_form=False``): the general path at m = 1;
* the same arm with m = 2 and m = 3 constraint normals and a ξ matrix: the general path;
* the six-joint arm of ``scenarios/six_joint.yaml`` (n = 6, m = 1, orientation held): general;
* a seven-joint arm of our own (:mod:`bench.seven_joint`, n = 7, m = 1): general.

Each general row is timed twice, alternated in this process, in CPU time: now (one
kinematics evaluation per tick, ``J̇_φ`` from the closed-form derivative of the geometric
Jacobian, plain floats at ``m = 1``) and before (the previous general path: NumPy matrices at
any ``m`` and ``J̇_φ`` by forward-mode AutoDiff, ``ArmModel.J_phi_and_derivative_autodiff``),
so the ratio holds on a loaded machine even when the absolute numbers do not.
"""

import sys
import tempfile
import time
import timeit
from pathlib import Path

import numpy as np

from drake_coop.control.arm_model import ArmModel
from drake_coop.control.arm_plant import make_arm_controller_plant
from drake_coop.control.finger import FingerLaw
from drake_coop.control.reference_layout import Reference
from drake_coop.control.params import Gains
from drake_coop.plant.arms import Arm, arm_model
from drake_coop.scenario import load_scenario
from drake_coop.scenario.resources import find_scenario

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # the checkout: bench.*
from bench.seven_joint import write_seven_joint_urdf  # noqa: E402

NORMALS = {2: [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
           3: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]}


def law_tick_cost(law: FingerLaw, q=None, n_calls=2000, autodiff: bool = False) -> float:
    """Microseconds of one held tick of ``law`` (best of 3 repeats); ``autodiff``: ``J̇_φ``
    by forward-mode AutoDiff instead of the closed form."""
    n, m = law.n, law.m
    model = law.model
    fast = law.fast
    if autodiff:     # the previous general path: NumPy matrices, J̇_φ by AutoDiff
        model.J_phi_and_derivative = model.J_phi_and_derivative_autodiff   # this instance only
        law.fast = law.fast and model.closed_form
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

    try:
        timer = timeit.Timer(tick, timer=time.process_time)    # CPU time: a shared machine
        return 1e6 * min(timer.repeat(number=n_calls, repeat=3)) / n_calls
    finally:
        if autodiff:
            del model.J_phi_and_derivative
            law.fast = fast


def tick_cost(robot, task, closed_form=None, q=None, n_calls=2000, autodiff=False):
    """Microseconds of one held tick of ``robot``'s equations and whether it is the fast path."""
    law = FingerLaw(arm_model(Arm(robot, task), closed_form=closed_form), robot.gains)
    return law_tick_cost(law, q, n_calls, autodiff), law.fast


def seven_joint_law(folder) -> FingerLaw:
    """The law of :mod:`bench.seven_joint`'s arm: one constraint along x at its pad."""
    plant = make_arm_controller_plant(write_seven_joint_urdf(folder), "base_link")
    model = ArmModel(plant, "pad", [[1.0, 0.0, 0.0]], [0.5, 0.0, 0.5])
    return FingerLaw(model, Gains(K_R=[50.0] * 7))


def main() -> None:
    paper = load_scenario()
    robot = paper.robots[0]
    print(f"{'':48s} {'now':>22s} {'before (AutoDiff)':>20s}")
    us, fast = tick_cost(robot, paper.task)
    print(f"{'paper arm n=3 m=1 (fast path)':48s} {us:18.1f} us  (fast path: {fast})")
    rows = [("paper arm n=3 m=1, Drake kinematics (general)",
             lambda ad: tick_cost(robot, paper.task, closed_form=False, autodiff=ad)[0])]
    for m in (2, 3):
        r = load_scenario().robots[0]
        r.normals = NORMALS[m]
        r.gains.xi_matrix = (np.eye(m) * r.gains.xi).tolist()
        rows.append((f"paper arm n=3 m={m}, xi matrix (general)",
                     lambda ad, r=r: tick_cost(r, paper.task, autodiff=ad)[0]))
    six = load_scenario(find_scenario("six_joint"))
    rows.append(("coop6 n=6 m=1 (general)",
                 lambda ad: tick_cost(six.robots[0], six.task, q=six.robots[0].q_seed,
                                      autodiff=ad)[0]))
    with tempfile.TemporaryDirectory() as folder:
        law7 = seven_joint_law(folder)
        q7 = np.array([0.1, 0.6, 0.0, -1.2, 0.0, 0.8, 0.0])
        rows.append(("seven_joint n=7 m=1 (general)",
                     lambda ad: law_tick_cost(law7, q7, autodiff=ad)))
        for label, cost in rows:
            new, old = cost(False), cost(True)
            print(f"{label:48s} {new:18.1f} us {old:17.1f} us")


if __name__ == "__main__":
    main()
