"""The benchmark's single runs, timed: the experiment, the plant alone (constant torques, no
Python) and the plant alone replaying a run's torques; and the spread of repeated measures."""

from __future__ import annotations

import statistics
import time

import numpy as np


def _plant_alone(scenario, t_end: float, extras=None) -> tuple[float, float]:
    """Wall and CPU seconds of the plant alone (held constraints, constant torques).

    ``extras(builder, coop, h, dt)``, if given, adds systems to that diagram before it is built
    (the ground truth and sensor models of :func:`_sensing_attribution`); if it returns a
    callable, ``finish(context)`` runs after the simulation, inside the timing (the offline
    ground truth's evaluation)."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    from drake_coop.plant.arms import arm_model
    from drake_coop.experiment.plan import plan_run
    from drake_coop.plant.cooperative import build_plant, initialize_plant_context

    b = DiagramBuilder()
    plan = plan_run(scenario, 0.0)
    coop = build_plant(b, plan)
    q0 = [robot.layout.column(robot.samples[1], "q_d")[0] for robot in plan.robots]
    for i, h in enumerate(coop.arms):
        src = b.AddNamedSystem(f"{h.arm.name}_torque",
                               ConstantVectorSource(arm_model(h.arm).g(q0[i])))
        b.Connect(src.get_output_port(), coop.plant.get_actuation_input_port(h.instance))
    finish = None
    if extras is not None:
        finish = extras(b, coop, plan.h, plan.dt)
    diagram = b.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    pc = coop.plant.GetMyMutableContextFromRoot(ctx)
    initialize_plant_context(coop, pc, q0, scenario.task.circle_top_z - scenario.task.lift_height)
    coop.set_held(pc, True)
    sim.Initialize()
    wall, cpu = time.perf_counter(), time.process_time()
    sim.AdvanceTo(t_end)
    if finish is not None:
        finish(ctx)
    return time.perf_counter() - wall, time.process_time() - cpu


def _experiment(scenario, t_end: float, keep: list | None = None) -> tuple[float, float]:
    """Wall and CPU seconds of the simulation loop of :func:`~drake_coop.experiment.simulate.simulate`.

    ``keep``, if given, receives the run's :class:`~drake_coop.experiment.simulate.RunResult`
    (for :func:`_plant_replay`)."""
    from drake_coop.experiment.simulate import simulate

    start: list[float] = []
    result = simulate(scenario, t_end=t_end,
                      on_start=lambda exp, sim: start.append(time.process_time()))
    cpu = time.process_time() - start[0]    # the loop and the logs' collection
    if not result.ok:
        raise RuntimeError(f"benchmark run failed: {result.meta['message']}")
    if keep is not None:
        keep.append(result)
    return result.wall_time, cpu


def _plant_replay(scenario, t_end: float, result) -> tuple[float, float, float]:
    """The plant alone replaying a run's applied torques: wall and CPU seconds, and the largest
    deviation (rad) of its joint angles from the run's at the run's ticks.

    The same plant, initial state and grasp/release switches as the run, each arm driven by
    a C++ :class:`~pydrake.systems.primitives.TrajectorySource` holding the run's logged
    ``tau`` (the actuators' output, ``τ(k)`` on ``[t_k, t_{k+1})``) as a zero-order hold, no
    Python system. Its steps are the run's own physics (the deviation shows it: 0 when every
    torque is reproduced bit for bit), so its cost is what the plant alone costs on the
    run's trajectory: SAP needs more iterations per step there than under the constant
    torques of :func:`_plant_alone`.

    It stops where :func:`~drake_coop.experiment.simulate.simulate` stops (every guard
    period, the grasp, release and end) and changes the plant there as the run does: the
    grasp switches and, in ``contact`` mode with ``plant.stand_clearance`` > 0, the stand
    lowered during the circle. In ``contact`` mode the deviation also covers the box's logged
    pose (``object_pose``: quaternion and position, at every tick).
    """
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
    from pydrake.trajectories import PiecewisePolynomial

    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.simulate import guard_chunks, rest_posture
    from drake_coop.plant.cooperative import build_plant, initialize_plant_context

    plan = plan_run(scenario, t_end)
    b = DiagramBuilder()
    coop = build_plant(b, plan)
    loggers = []
    for h in coop.arms:
        log = result.logs[h.arm.name]
        t, tau = log["t"], log["tau"]
        pp = PiecewisePolynomial.ZeroOrderHold(np.append(t, t[-1] + plan.h), np.vstack(
            [tau, tau[-1:]]).T)
        src = b.AddSystem(TrajectorySource(pp))
        b.Connect(src.get_output_port(), coop.plant.get_actuation_input_port(h.instance))
        loggers.append(LogVectorOutput(coop.plant.get_state_output_port(h.instance), b,
                                       publish_period=plan.h))
    box_log = None
    if coop.grasp is not None:     # contact mode: the box's state (quaternion, position, ...)
        box_log = LogVectorOutput(coop.plant.get_state_output_port(
            coop.plant.GetModelInstanceByName("object")), b, publish_period=plan.h)
    diagram = b.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    pc = coop.plant.GetMyMutableContextFromRoot(ctx)
    initialize_plant_context(coop, pc, *rest_posture(plan))
    sim.Initialize()
    grasp = coop.grasp
    stand = grasp if grasp is not None and grasp.stand_drop > 0 else None
    task = scenario.task
    wall, cpu = time.perf_counter(), time.process_time()
    for k_stop in guard_chunks(plan, scenario.guards.check_period):
        sim.AdvanceTo(k_stop * plan.h)
        if k_stop in plan.switches:
            coop.set_held(pc, plan.switches[k_stop])
        if stand is not None:     # as simulate(): lowered while the box goes around the circle
            t_now = ctx.get_time()
            stand.set_stand_lowered(pc, task.t_circle_start <= t_now < task.t_circle_end)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    deviation = 0.0
    for h, logger in zip(coop.arms, loggers):
        q_run = result.logs[h.arm.name]["q"]
        q = logger.FindLog(ctx).data()[:h.arm.kinematics.n].T
        k = min(len(q), len(q_run))
        deviation = max(deviation, float(np.max(np.abs(q[:k] - q_run[:k]))))
        if box_log is not None:
            pose_run = result.logs[h.arm.name]["object_pose"]
            pose = box_log.FindLog(ctx).data()[:7].T
            k = min(len(pose), len(pose_run))
            deviation = max(deviation, float(np.max(np.abs(pose[:k] - pose_run[:k]))))
    return wall, cpu, deviation


def _spread(values: list[float]) -> dict[str, float]:
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}
