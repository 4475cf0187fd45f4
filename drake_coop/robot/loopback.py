"""The paper's experiment split at the cable, in one process: the controller side and the
simulated driver in one Diagram, joined only through LCM publishers and subscribers on one
``DrakeLcm`` (``memq://``: in-process), advanced by one unpaced Simulator.

:func:`run_loopback` reproduces a simulated run over the driver's messages; the ground truth
of the squeeze (``lambda_meas``) comes from the plant's held data, as in
:func:`~drake_coop.experiment.simulate.simulate` (:mod:`drake_coop.plant.ground_truth`): in
``planes`` and ``rigid`` modes the offline ground truth, in ``contact`` mode the pads' contact
forces along the constraint normals (:func:`pad_squeeze`); so :func:`squeeze_error` compares
the two runs with one formula.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Context, DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput

from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.experiment.plan import RunPlan, plan_run
from drake_coop.experiment.ticks import check_run_size
from drake_coop.experiment.simulate import guard_chunks, phases, rest_posture
from drake_coop.plant.cooperative import initialize_plant_context
from drake_coop.plant.ground_truth import add_ground_truth
from drake_coop.results.metrics import phase_masks
from drake_coop.robot.drivers import (
    ControllerSide,
    DriverSide,
    add_controller_side,
    add_driver_side,
    add_lcm_interface,
)
from drake_coop.robot.torque_driver import DriverClock
from drake_coop.scenario.schema import Scenario, ScenarioError
from drake_coop.sensing.force_sensor import FTModel


@dataclass
class LoopbackResult:
    """Per robot ``t``, ``lambda_meas`` (the plant's squeeze), ``lambda_d``,
    ``tau_commanded`` (the command the driver held at ``t``: the wire's; zero before the
    first), ``tau_external`` (the status's external-torque estimate at ``t``: zeros but in the
    emulation) and ``q`` (the arm's positions at ``t``); the status (``ok`` or ``stopped``,
    with the watchdog's one-line
    reason) and the wall time.

    Attributes
    ----------
    logs : dict of str to dict of str to numpy.ndarray
        ``logs[robot][array]``: ``t`` (s), ``lambda_meas``, ``lambda_d`` (N),
        ``tau_commanded``, ``tau_external`` (N·m), ``q`` (rad).
    status : str
        ``ok`` or ``stopped``.
    message : str
        The watchdog's reason, or ``''``.
    wall_time : float
        The run's wall time, s.
    """

    logs: dict[str, dict[str, np.ndarray]]
    status: str
    message: str
    wall_time: float


def initialize_sides(plan: RunPlan, context: Context, driver: DriverSide | None,
                     controller: ControllerSide | None,
                     q0: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """The run's start: the driver's arms at rest at ``q_d(0)`` (sliders at the grasp
    height), the controller's observers at ``q̂ = q0`` and its watchdogs untripped with
    ``q0`` as their last good reading (default ``q0``: ``q_d(0)``, the arms' rest).

    Parameters
    ----------
    plan : RunPlan
        The run's plan.
    context : Context
        The root context.
    driver : DriverSide or None
        The driver's side, if in this Diagram.
    controller : ControllerSide or None
        The controller's side, if in this Diagram.
    q0 : list of numpy.ndarray or None
        Each arm's start reading (n,), rad; None for ``q_d(0)``.

    Returns
    -------
    list of numpy.ndarray
        The start readings ``q0`` used (n,), rad.
    """
    rest, z_grasp = rest_posture(plan)
    if driver is not None:
        initialize_plant_context(driver.coop,
                                 driver.coop.plant.GetMyMutableContextFromRoot(context),
                                 rest, z_grasp)
    q0 = rest if q0 is None else q0
    if controller is not None:
        for arm, q in zip(controller.arms, q0):
            source = arm.block.velocity_source
            if hasattr(source, "set_initial_state"):
                source.set_initial_state(source.GetMyMutableContextFromRoot(context),
                                         np.asarray(q, dtype=float))
            arm.watchdog.set_initial_state(arm.watchdog.GetMyMutableContextFromRoot(context), q)
    return q0


def add_squeeze_truth(builder: DiagramBuilder, scenario: Scenario, driver: DriverSide,
                      h: float):
    """The offline ground truth of the squeeze on the driver's plant (``planes`` or
    ``rigid``), sampling each arm's applied torque from its driver: the loopback run's and
    ``sim-driver --log``'s, one formula with :func:`~drake_coop.experiment.simulate.simulate`.

    Parameters
    ----------
    builder : DiagramBuilder
        The driver's builder.
    scenario : Scenario
        The scenario.
    driver : DriverSide
        The simulated driver.
    h : float
        The control period, s.

    Returns
    -------
    GroundTruthLog
        The log (:func:`squeeze_truth` reads it after the run).
    """
    return add_ground_truth(
        builder, driver.coop, h,
        [FTModel.from_settings(r.force_sensor, h, i, arm.arm.m)
         for i, (r, arm) in enumerate(zip(scenario.robots, driver.coop.arms))],
        [arm.driver.get_output_port(0) for arm in driver.arms], tick_forces=False)


def add_pad_truth(builder: DiagramBuilder, driver: DriverSide, h: float):
    """The ``contact`` mode's ground truth of the squeeze on the driver's plant: each arm's
    pad contact force of the plant step before every tick (the C++ hold of
    :func:`~drake_coop.plant.ground_truth.add_pad_force_log`), logged every tick: the loopback
    run's and ``sim-driver --log``'s (:func:`pad_squeeze`).

    Parameters
    ----------
    builder : DiagramBuilder
        The driver's builder.
    driver : DriverSide
        The simulated driver (its plant in ``contact`` mode).
    h : float
        The control period, s.

    Returns
    -------
    VectorLogSink
        The log of the pads' forces (ticks × 3 per arm, N, world frame).
    """
    from drake_coop.plant.ground_truth import add_pad_force_log

    pads = add_pad_force_log(builder, driver.coop, h, [], log=False)
    return LogVectorOutput(pads.hold, builder, publish_period=h)


def pad_squeeze(forces: np.ndarray, normals: list) -> np.ndarray:
    """``λ_i = N_i F_i`` of each tick from the pads' forces: the squeeze along each arm's
    constraint normals.

    Parameters
    ----------
    forces : numpy.ndarray
        The pads' forces, (ticks, 3 per arm), N.
    normals : list of numpy.ndarray
        Each arm's constraint normals ``N_i``, (m, 3).

    Returns
    -------
    numpy.ndarray
        (ticks, arms, m), N.
    """
    forces = np.atleast_2d(np.asarray(forces, dtype=float))
    return np.stack([(np.atleast_2d(N) @ forces[:, 3 * i:3 * i + 3].T).T
                     for i, N in enumerate(normals)], axis=1)


def squeeze_truth(truth, context: Context) -> tuple[int, list]:
    """``(n, forces)``: the ticks logged and, per robot, the ground truth of each
    (``forces[i]["lambda_meas"]``, ``(n, m)`` N).

    Parameters
    ----------
    truth : GroundTruthLog
        The log of :func:`add_squeeze_truth`.
    context : Context
        The root context after the run.

    Returns
    -------
    tuple
        ``n`` and the per-robot dicts.
    """
    published = truth.logger.FindLog(context).sample_times().size
    n = max(published - 1, 0)
    return n, truth.evaluate(context, n, False)


def tripped(controller: ControllerSide, context: Context) -> str | None:
    """``"<robot>: <reason> on <status channel>"`` of the first tripped watchdog, else None.

    Parameters
    ----------
    controller : ControllerSide
        The controller's side.
    context : Context
        The root context.

    Returns
    -------
    str or None
        The line, or None.
    """
    for arm in controller.arms:
        wd = arm.watchdog
        wd_context = wd.GetMyContextFromRoot(context)
        if wd.is_tripped(wd_context):
            return f"{arm.spec.robot}: {wd.reason(wd_context)} on {arm.spec.status_channel}"
    return None


def run_loopback(scenario: Scenario, t_end: float | None = None, *,
                 lcm_url: str = "memq://", emulate: str | None = None,
                 low_pass_hz: float | None = None) -> LoopbackResult:
    """Run the experiment with the controller and the simulated driver joined by LCM only.

    Parameters
    ----------
    scenario : Scenario
        The scenario (any object mode).
    t_end : float or None
        The run's end, s; None for the task's.
    lcm_url : str
        The LCM URL (``memq://``: in-process).
    emulate : str or None
        ``drake-franka-driver``: the simulated driver emulates it
        (:class:`~drake_coop.robot.torque_driver.TorqueDriver`); None: the plain one.
    low_pass_hz : float or None
        The emulation's torque cutoff, Hz; None: the driver's default (30 Hz).

    Returns
    -------
    LoopbackResult
        The logs and the status.

    Raises
    ------
    ScenarioError
        A scenario the drivers cannot serve, or a run too large (as :func:`simulate`).
    """
    plan = plan_run(scenario, t_end)
    check_run_size(scenario, plan.t_end)
    lcm = DrakeLcm(lcm_url)
    builder = DiagramBuilder()
    add_lcm_interface(builder, lcm)
    clock = DriverClock("epoch")          # one simulated clock: the drivers' and the stamps'
    extra = {} if low_pass_hz is None else {"low_pass_hz": low_pass_hz}
    driver = add_driver_side(builder, plan, lcm, clock=clock, emulate=emulate, **extra)
    controller = add_controller_side(builder, plan, lcm, clock=clock)
    contact = driver.coop.mode == "contact"
    truth = (add_pad_truth(builder, driver, plan.h) if contact
             else add_squeeze_truth(builder, scenario, driver, plan.h))
    wire = [LogVectorOutput(arm.driver.get_output_port(1), builder,
                            publish_period=plan.h) for arm in driver.arms]
    external = [LogVectorOutput(arm.driver.get_output_port(2), builder,
                                publish_period=plan.h) for arm in driver.arms]
    states = [LogVectorOutput(driver.coop.plant.get_state_output_port(arm.instance), builder,
                              publish_period=plan.h) for arm in driver.coop.arms]
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    initialize_sides(plan, context, driver, controller)
    simulator.Initialize()
    plant_context = driver.coop.plant.GetMyMutableContextFromRoot(context)
    status, message = "ok", f"completed {plan.t_end:g} s"
    start = time.perf_counter()
    for k_stop in guard_chunks(plan, scenario.guards.check_period):
        simulator.AdvanceTo(k_stop * plan.h)
        reason = tripped(controller, context)
        if reason is not None:
            status, message = "stopped", f"watchdog at t = {context.get_time():.3f} s: {reason}"
            break
        if k_stop in plan.switches:
            driver.coop.set_held(plant_context, plan.switches[k_stop])
    wall = time.perf_counter() - start
    if contact:          # the force of the step before each tick; the last tick's left out
        n = max(truth.FindLog(context).sample_times().size - 1, 0)
        lams = pad_squeeze(truth.FindLog(context).data().T[:n],
                           [np.asarray(a.arm.N, dtype=float) for a in driver.coop.arms])
        forces = [{"lambda_meas": lams[:, i]} for i in range(lams.shape[1])]
    else:
        n, forces = squeeze_truth(truth, context)
    logs = {}
    for i, robot in enumerate(scenario.robots):
        t = np.arange(n) * plan.h
        m = driver.coop.arms[i].arm.m
        layout = ReferenceLayout(controller.arms[i].spec.n, m)
        traj = plan.robots[i].reference
        lam_d = np.array([layout.column(traj.value(tk).reshape(1, -1), "lambda_d")[0]
                          for tk in t]).reshape(n, m)
        lam = np.asarray(forces[i]["lambda_meas"]).reshape(n, m)
        tau = wire[i].FindLog(context).data().T[:n]
        logs[robot.name] = {"t": t, "lambda_meas": lam[:, 0] if m == 1 else lam,
                            "lambda_d": lam_d[:, 0] if m == 1 else lam_d,
                            "tau_commanded": tau,
                            "tau_external": external[i].FindLog(context).data().T[:n],
                            "q": states[i].FindLog(context).data().T[:n, :layout.n]}
    return LoopbackResult(logs=logs, status=status, message=message, wall_time=wall)


def squeeze_error(logs: dict[str, dict[str, np.ndarray]], scenario: Scenario,
                  phase: str = "circle") -> dict[str, float]:
    """RMS of ``λ − λ_d`` over a phase, per robot (the norm per sample for ``m >= 2``).

    Parameters
    ----------
    logs : dict
        ``logs[robot][array]`` of :class:`LoopbackResult`.
    scenario : Scenario
        The scenario (its phases).
    phase : str
        The phase.

    Returns
    -------
    dict of str to float
        Robot → the RMS, N.
    """
    out = {}
    for name, log in logs.items():
        e = np.asarray(log["lambda_meas"], dtype=float) - np.asarray(log["lambda_d"], dtype=float)
        if e.ndim == 2:
            e = np.linalg.norm(e, axis=1)
        mask = phase_masks(log["t"], phases(scenario))[phase]
        out[name] = float(np.sqrt(np.mean(e[mask] ** 2))) if mask.any() else float("nan")
    return out
