"""The ground truth's two reads per tick against the plant's own steps (second pass).

With a control period, :class:`~drake_coop.plant.wrist_dynamics.WristDynamics` serves two steps at
every tick ``t_k`` without solving any plant step twice: the latch ``<robot>_lambda_step`` of
the step from ``t_k`` (shared with the plant's update at ``t_k``) and ``lambda_last_step``,
the step ``[t_k − Δt, t_k)``, rebuilt from the state held at ``t_k − 3Δt/2`` and the state the
plant's update produced. The ideal F/T sensor model is a C++ hold of the latter. The reference
is independent of that path: the live ``lambda_meas`` (the plant's acceleration port, i.e. the
plant's own solve) recorded by a monitor at every plant step time ``j Δt``.
"""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ZeroOrderHold

from drake_coop.plant.arms import arm_model
from drake_coop.scenario.task_path import waypoints
from drake_coop.experiment.plan import plan_run
from drake_coop.plant.cooperative import build_plant, initialize_plant_context
from drake_coop.plant.wrist import add_force_sensors
from drake_coop.scenario import default_scenario
from drake_coop.scenario.schema import ForceSensorModel
from drake_coop.control.timing import aligned_periods
from drake_coop.sensing.force_sensor import FTSensor, add_ft_sensor
from tests.plant.test_cooperative import TorqueSource

TICKS = 40
H, DT = aligned_periods(0.009, 0.001)      # the experiment's grid (h = 9 Δt exactly)


@pytest.fixture(scope="module")
def run():
    """Both arms squeezing the object from rest in ``planes`` mode (the constraint force
    builds up over the first ticks), a state-dependent torque (joint damping in the law, as an
    actuator's friction would be); per plant step the live λ, per tick the logged signals."""
    s = default_scenario()
    s.plant.time_step = DT
    b = DiagramBuilder()
    coop = build_plant(b, plan_run(s))
    sensors = add_force_sensors(b, coop, H)
    for h in coop.arms:
        src = b.AddSystem(TorqueSource(arm_model(h.arm), 30.0, damping=0.5))
        b.Connect(coop.plant.get_state_output_port(h.instance), src.get_input_port())
        b.Connect(src.get_output_port(), coop.plant.get_actuation_input_port(h.instance))
    fts = [add_ft_sensor(b, h.arm.name, H, DT, settings, i, h.arm.m,
                         sensors[i].GetOutputPort("lambda_meas"), sensors[i].lambda_last_step)
           for i, (h, settings) in enumerate(zip(coop.arms, (None, ForceSensorModel(bias=0.5))))]
    sim = Simulator(b.Build())
    ctx = sim.get_mutable_context()
    pc = coop.plant.GetMyMutableContextFromRoot(ctx)
    grasp = [waypoints(s.task, robot)["grasp"] for robot in s.robots]
    initialize_plant_context(coop, pc, [h.arm.ik(grasp[i]) for i, h in enumerate(coop.arms)],
                             z_grasp=grasp[0][2])
    coop.set_held(pc, True)
    steps, ticks = {}, {}

    def record(context):
        t = context.get_time()
        j = int(round(t / DT))
        if t == j * DT and j not in steps:      # publishes run before the updates at t
            steps[j] = [sensor.GetOutputPort("lambda_meas").Eval(
                sensor.GetMyContextFromRoot(context))[0] for sensor in sensors]
        k = int(round(t / H))
        if t == k * H and k not in ticks:
            ticks[k] = [(port.Eval(port.get_system().GetMyContextFromRoot(context))[0],
                         sensor.lambda_step.Eval(sensor.lambda_step.get_system()
                                                 .GetMyContextFromRoot(context))[0])
                        for (_, port), sensor in zip(fts, sensors)]
    sim.set_monitor(record)
    sim.Initialize()
    sim.AdvanceTo(TICKS * H)
    return fts, steps, ticks


def test_ideal_ft_sensor_is_a_cpp_hold_and_a_filtered_one_reads_half_a_step_before_the_tick(run):
    fts, _, _ = run
    assert isinstance(fts[0][0], ZeroOrderHold)
    assert isinstance(fts[1][0], FTSensor) and fts[1][0].read_lead == pytest.approx(DT / 2)


def test_ft_reading_of_every_tick_is_the_plant_step_before_it(run):
    _, steps, ticks = run
    N = round(H / DT)
    lam = np.array([[steps[N * k - 1][i] for i in range(2)] for k in range(1, TICKS + 1)])
    read = np.array([[ticks[k][i][0] for i in range(2)] for k in range(1, TICKS + 1)])
    assert np.ptp(lam[:, 0]) > 1.0                 # the force moves from tick to tick
    np.testing.assert_allclose(read[:, 0], lam[:, 0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(read[:, 1], lam[:, 1] + 0.5, rtol=1e-12, atol=1e-12)


def test_latched_force_of_every_tick_is_the_step_the_plant_takes_from_it(run):
    _, steps, ticks = run
    N = round(H / DT)
    # Published at t_{k+1}: the latch of tick k, the step [t_k, t_k + Δt).
    latched = np.array([[ticks[k + 1][i][1] for i in range(2)] for k in range(TICKS)])
    lam = np.array([[steps[N * k][i] for i in range(2)] for k in range(TICKS)])
    assert np.ptp(lam[:, 0]) > 1.0
    np.testing.assert_allclose(latched, lam, rtol=1e-12, atol=1e-12)


def test_three_by_three_solve_of_the_ground_truth_satisfies_its_equation():
    """``_solve_transposed3`` (the adjugate on floats) against the equation itself: the
    residual ``Jᵀ F − b`` over random, also ill-conditioned, 3×3 Jacobians."""
    from drake_coop.plant.wrist_dynamics import _solve_transposed3

    rng = np.random.default_rng(7)
    for scale in (1.0, 1e-3):
        for _ in range(500):
            J = rng.normal(size=(3, 3))
            J[:, 2] = J[:, 1] + scale * J[:, 2]          # columns close to dependent
            b = rng.normal(size=3)
            F = _solve_transposed3(J.tolist(), b.tolist())
            residual = np.abs(J.T @ F - b).max()
            assert residual <= 1e-13 * np.abs(J).max() * np.abs(F).max(), (scale, residual)
