"""Run an experiment: initial state, grasp/release segments, divergence guards, logs.

The run follows its :class:`~drake_coop.experiment.plan.RunPlan`. The simulator stops only
where the plant changes: the grasp constraints are switched on exactly at the first held
control tick ``k_grasp h`` and off at ``k_release h`` (between two ``AdvanceTo`` calls, before
that tick's updates), so the plant and the controllers change form at the same instant. The
divergence guards run between ``AdvanceTo`` chunks of ``guards.check_period`` (rounded to whole
control ticks), after the step that reaches each chunk's end (in ``contact`` mode with
``plant.stand_clearance`` > 0, the stand is lowered at the first chunk's end in the circle
phase and put back at the first after it:
:meth:`~drake_coop.plant.grasp.ContactObject.set_stand_lowered`): a non-finite state, a joint past
its limit or a force beyond ``guards.max_force`` ends the run with ``status = "diverged"`` and
whatever was logged so far; so does an exception inside Drake. The failure guards
(:mod:`drake_coop.experiment.failure`: a pad off its path, the squeeze far from its reference,
the held box tilted or off its path, the grasp lost) read the plant's state at the same chunk
ends and end the run with ``status = "failed"``; once the run is over they also read every
logged tick, so a failure between two chunk ends is not called completed. No Python call
happens at the plant's steps for the guards (a Simulator monitor would be one per plant step).

The ground truth: with the offline path (:attr:`Experiment.ground_truth`, the default when no
controller reads the F/T sensor in ``planes`` and ``rigid`` modes), ``F_meas``,
``lambda_meas`` and ``lambda_sensor`` are computed by :func:`collect_logs` from plant data
held at every tick, and the guards read the force of the plant step before the checked tick
from the held data (no plant solve); in ``contact`` mode likewise from the pads' forces held at
every plant step (:class:`~drake_coop.plant.ground_truth.PadForceLog`); with the live path
they are logged latches and the guards read the live force port.
"""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass, field
from typing import Callable, ContextManager

import numpy as np
from pydrake.systems.analysis import Simulator, SimulatorStatus

from drake_coop.experiment.diagram import Experiment, build_experiment
from drake_coop.experiment.failure import failure_check, first_failure_in_logs, plant_sample
from drake_coop.experiment.plan import RunPlan, plan_run
from drake_coop.experiment.ticks import check_run_size
from drake_coop.experiment.references import start_posture
from drake_coop.scenario.task_path import cartesian_reference
from drake_coop.plant.cooperative import initialize_plant_context
from drake_coop.kinematics.rotations import pad_contact_components
from drake_coop.scenario.loading import dump_scenario
from drake_coop.scenario.schema import Scenario
from drake_coop.control.timing import tick_of
from drake_coop.sensing.encoders import Encoders

#: Logged signals latched at a tick by its own updates (the torque, the force of the step
#: taken): a logger publishing at :math:`t_{k+1}` holds the value of tick ``k``.
LATCHED_SIGNALS = ("tau", "tau_cmd", "F_meas", "lambda_meas", "tau_ff", "f_load")


@dataclass
class RunResult:
    """Logs of a run (schema of :mod:`drake_coop.results.logs`) and its metadata.

    Attributes
    ----------
    logs : dict of str to dict of str to numpy.ndarray
        ``logs[robot][array]``.
    meta : dict
        The run's metadata (``run.json``).
    wall_time : float
        The simulation's wall time, s.
    experiment : Experiment or None
        The built experiment.
    """

    logs: dict[str, dict[str, np.ndarray]]
    meta: dict
    wall_time: float = 0.0
    experiment: Experiment | None = field(default=None, repr=False)

    @property
    def ok(self) -> bool:
        """Whether the run completed (``meta["status"] == "ok"``)."""
        return self.meta["status"] == "ok"


def phases(scenario: Scenario) -> list[list]:
    """``[name, t_start, t_end]`` (s) of each of the five phases of Section IV.

    Parameters
    ----------
    scenario : Scenario
        The scenario whose task times them.
    """
    t = scenario.task
    return [["free", 0.0, t.t_grasp], ["lift", t.t_grasp, t.t_circle_start],
            ["circle", t.t_circle_start, t.t_circle_end],
            ["put_down", t.t_circle_end, t.t_release], ["return", t.t_release, t.t_end]]


def initialize(exp: Experiment, context) -> None:
    """Arms at rest at ``q_d(0)``, observers at ``q̂(0) = q(0)``, ``q̇̂_o(0) = 0``, no grasp.

    ``q(0)`` as the encoders read it at rest (quantized, no noise; the exact ``q(0)`` with
    ideal encoders).

    Parameters
    ----------
    exp : Experiment
        The experiment.
    context : Context
        The root context.
    """
    set_rest_state(exp, context, *rest_posture(exp.plan))


def rest_posture(plan: RunPlan) -> tuple[list[np.ndarray], float]:
    """The run's start: each arm's ``q_d(0)`` (one posture per robot, with the plan's control
    points) and the height of the object's sliders at the grasp (the plan's ``z_grasp``,
    ``circle_top_z − lift_height``).

    Parameters
    ----------
    plan : RunPlan
        The run's plan.

    Returns
    -------
    q0 : list of numpy.ndarray
        Each arm's ``q_d(0)`` (n,), rad.
    z_grasp : float
        The sliders' height, m.
    """
    task = plan.scenario.task
    q0 = [start_posture(resolved.arm, task, resolved.control_point) for resolved in plan.robots]
    return q0, plan.z_grasp


def set_rest_state(exp: Experiment, context, q0: list[np.ndarray], z_grasp: float) -> None:
    """Arms at rest at ``q0`` (one posture per robot), the object's sliders at the grasp
    height ``z_grasp``, encoders' delay lines holding the reading at rest and the velocity
    observers at ``q̂ = `` that reading, ``q̇̂_o = 0``.

    Parameters
    ----------
    exp : Experiment
        The experiment.
    context : Context
        The root context.
    q0 : list of numpy.ndarray
        Each arm's posture (n,), rad.
    z_grasp : float
        The sliders' height, m.
    """
    plant_context = exp.coop.plant.GetMyMutableContextFromRoot(context)
    initialize_plant_context(exp.coop, plant_context, q0, z_grasp)
    for rs, q in zip(exp.robots, q0):
        if isinstance(rs.encoders, Encoders):   # the delay line holds the reading at rest
            rs.encoders.set_initial_state(rs.encoders.GetMyMutableContextFromRoot(context), q)
            q = rs.encoders.initial_reading(q)   # what the controller knows of q(0)
        rs.velocity_observer.set_initial_state(
            rs.velocity_observer.GetMyMutableContextFromRoot(context), q)


def _check_guards(exp: Experiment, context, forces: list | None = None) -> str | None:
    """A message if a divergence guard trips, else None; ``forces`` (a list) gets each arm's
    measured force ``F`` read here, for the failure guards.

    At a tick ``t_k`` (before its updates). The measured force is, with the offline ground
    truth, the force of the plant step ``[t_k − Δt, t_k)`` from the held data and the current
    state (:meth:`~drake_coop.plant.ground_truth.GroundTruthLog.force_before_tick`, no plant
    solve); on the live path, the live ``F_meas`` port (the step from ``t_k`` under the torque
    still applied, solved for the read)."""
    g = exp.scenario.guards
    plant = exp.coop.plant
    pc = plant.GetMyContextFromRoot(context)
    x = plant.GetPositionsAndVelocities(pc)
    if not np.all(np.isfinite(x)):
        return "non-finite plant state"
    offline = (exp.ground_truth.force_before_tick(context)
               if exp.ground_truth is not None else None)
    margin = math.radians(g.joint_limit_margin_deg)
    for i, rs in enumerate(exp.robots):
        arm = exp.coop.arms[i].arm
        q = exp.coop.arm_positions(pc, i)
        lo, hi = arm.q_min - margin, arm.q_max + margin
        bad = np.flatnonzero((q < lo - 1e-6) | (q > hi + 1e-6))
        if bad.size:
            j = int(bad[0])
            return (f"{rs.name} joint{j + 1} = {math.degrees(q[j]):.1f} deg passed its limit "
                    f"[{math.degrees(lo[j]):.0f}, {math.degrees(hi[j]):.0f}] deg")
        lam_hat = rs.control.GetOutputPort("lambda_hat").Eval(
            rs.control.GetMyContextFromRoot(context))
        if offline is not None:
            F = offline[i]
        else:
            F = rs.force_sensor.GetOutputPort("F_meas").Eval(
                rs.force_sensor.GetMyContextFromRoot(context))
        if forces is not None:
            forces.append(np.asarray(F, dtype=float))
        for label, value in (("estimated force", float(np.max(np.abs(lam_hat)))),
                             ("measured force", float(np.linalg.norm(F)))):
            if not math.isfinite(value) or value > g.max_force:
                return (f"{rs.name} {label} {value:.1f} N exceeds guards.max_force = "
                        f"{g.max_force} N")
    return None


def guard_chunks(plan: RunPlan, check_period: float) -> list[int]:
    """The ticks where the run stops: every ``check_period`` (whole ticks, at least one) and at
    the plan's stops (grasp, release, end), in increasing order.

    Parameters
    ----------
    plan : RunPlan
        The run's plan.
    check_period : float
        The guards' period, s.
    """
    chunk = max(1, int(round(check_period / plan.h)))
    return sorted({*range(chunk, plan.k_end, chunk), *plan.stops})


def finish_last_tick(exp: Experiment, simulator, status: str) -> None:
    """Run the events of the tick the simulator stopped at, so that its latched signals exist.

    ``AdvanceTo(k h)`` ends with the loggers' publish at ``t_k``, *before* that tick's updates:
    ``τ(k)`` and the force of the step from ``t_k`` are not latched yet. A run that ended
    normally or by a guard takes half a plant step more (the tick's updates, among them the
    plant's step from ``t_k`` and the offline ground truth's tick hold; nothing is published,
    the reported end stays ``t_k``). A run that stopped
    inside a step (an exception, Ctrl-C) is left as it is; :func:`collect_logs` then keeps only
    the ticks whose signals were latched.

    Parameters
    ----------
    exp : Experiment
        The experiment.
    simulator : Simulator
        The run's simulator.
    status : str
        The run's status (``ok``, ``diverged``, …).
    """
    context = simulator.get_context()
    if status not in ("ok", "diverged", "failed") or not exp.robots:
        return
    ctrl = exp.robots[0].controller
    t = context.get_time()
    k = tick_of(t, exp.h)
    if k is None or ctrl.latched_tick(ctrl.GetMyContextFromRoot(context)) == k:
        return
    try:
        simulator.AdvanceTo(t + 0.5 * exp.dt)
    except RuntimeError:      # the blown-up state of a diverged run: keep what was latched
        pass


def collect_logs(exp: Experiment, context) -> dict[str, dict[str, np.ndarray]]:
    """The loggers' data in the schema of :mod:`drake_coop.results.logs`, one row per tick.

    Alignment: loggers publish at ``t_k`` before the tick's updates. The signals of
    :data:`LATCHED_SIGNALS` (``τ(k)`` and the force of the step taken from ``t_k``) are
    latched by those updates, so the sample published at :math:`t_{k+1}` holds tick ``k``: they
    are shifted back by one sample, and the last published tick's come from the logged ports'
    current values when its updates have run (:func:`finish_last_tick`). Rule for a run that
    stopped before the last published tick's updates ran (an exception or Ctrl-C during them):
    its logs end one tick earlier, at the last tick whose torque is known.

    With the offline ground truth (:attr:`Experiment.ground_truth`), ``F_meas``,
    ``lambda_meas`` and ``lambda_sensor`` are computed here from the held plant data
    (:meth:`~drake_coop.plant.ground_truth.GroundTruthLog.evaluate`), under the same rules:
    the holds of tick ``k`` are published at :math:`t_{k+1}`, the last tick's are the holds'
    current values, and the rows end where the torque's do.

    Parameters
    ----------
    exp : Experiment
        The experiment.
    context : Context
        The root context after the run.
    """
    logs = {}
    task = exp.scenario.task
    offline: dict[tuple[int, bool], list] = {}
    for i, rs in enumerate(exp.robots):
        times, raw = rs.log.raw(context)
        published = times.size
        ctrl_context = rs.controller.GetMyContextFromRoot(context)
        complete = published > 0 and rs.controller.latched_tick(ctrl_context) == \
            tick_of(times[published - 1], exp.h)
        n = published if complete else max(published - 1, 0)
        t = times[:n]
        data = {}
        for key, r in raw.items():
            if key not in LATCHED_SIGNALS:
                data[key] = r[:, :n].T
                continue
            rows = r[:, 1:published].T
            if complete:
                rows = np.vstack([rows, np.reshape(rs.log.now(context, key), (1, -1))])
            data[key] = rows[:n]
        if exp.ground_truth is not None:
            if (n, complete) not in offline:
                offline[(n, complete)] = exp.ground_truth.evaluate(context, n, complete)
            for key, value in offline[(n, complete)][i].items():
                data.setdefault(key, value)     # (a live F/T model's reading is logged)
        arm = exp.coop.arms[i].arm
        arm_dofs = rs.law.n
        layout = rs.law.layout
        robot = exp.scenario.robots[i]
        ref = data["reference"]

        def forces(a: np.ndarray) -> np.ndarray:
            """λ logs: (N,) for one constraint (the paper), (N, m) for more."""
            return a[:, 0].copy() if layout.m == 1 else a.copy()

        logs[rs.name] = {
            "t": t.copy(),
            "q": data["q"],
            "q_hat": data["q_hat"],
            "q_d": layout.column(ref, "q_d").copy(),
            "x": arm.fk(data["q"]),
            "x_d": cartesian_reference(task, robot, t)[0],
            "F_meas": data["F_meas"],
            "lambda_meas": forces(data["lambda_meas"]),
            "lambda_hat": forces(data["lambda_hat"]),
            "lambda_d": forces(layout.column(ref, "lambda_d")),
            "tau": data["tau"],
        }
        optional = {   # sensing: sensors, velocity estimate, commanded torque
            "qdot": data["state"][:, arm_dofs:] if "state" in data else None,
            "qdot_hat": data.get("qdot_hat"),
            "lambda_sensor": forces(data["lambda_sensor"]) if "lambda_sensor" in data
            else None,
            "tau_cmd": data.get("tau_cmd"),
            # object_model known / estimated: the load feedforward, the arm's load, its
            # mass share (the estimate available at the tick when estimated)
            "tau_ff": data.get("tau_ff"),
            "f_load": data.get("f_load"),
            "mass_share": data["mass_share"][:, 0].copy() if "mass_share" in data else None,
        }
        logs[rs.name].update({k: v for k, v in optional.items() if v is not None})
        if "object_state" in data:              # contact mode: the box and this pad
            pose = data["object_state"][:, :7].copy()
            faces = exp.coop.grasp.face_normals
            f_n, f_t, p_B = pad_contact_components(data["F_meas"], logs[rs.name]["x"], pose,
                                                   None if faces is None else faces[i])
            logs[rs.name].update({"object_pose": pose, "pad_normal_force": f_n,
                                  "pad_tangential_force": f_t, "pad_in_object": p_B,
                                  "pad_rotation": _pad_rotations(exp, i, data["q"])})
    return logs


def _pad_rotations(exp: Experiment, i: int, q: np.ndarray) -> np.ndarray:
    """``R_WE`` ``(K, 3, 3)`` of arm ``i``'s end-effector body (the pad) at the logged ``q``."""
    plant = exp.coop.plant
    handles = exp.coop.arms[i]
    context = plant.CreateDefaultContext()
    out = np.empty((q.shape[0], 3, 3))
    for k, qk in enumerate(q):
        plant.SetPositions(context, handles.instance, qk)
        out[k] = plant.EvalBodyPoseInWorld(context, handles.ee_body).rotation().matrix()
    return out


def simulate(scenario: Scenario, *, t_end: float | None = None,
             progress: Callable[[float, float, float], None] | None = None,
             before_build=None, on_start=None,
             hold_signals: Callable[[], ContextManager] | None = None,
             live_ground_truth: bool | None = None, clocks=None) -> RunResult:
    """Simulate the experiment and return its logs.

    Parameters
    ----------
    scenario : Scenario
        A validated scenario.
    t_end : float, optional
        Stop earlier than ``scenario.task.t_end``.
    progress : callable, optional
        ``progress(t, t_end, wall_seconds)`` after every chunk.
    before_build : callable, optional
        Passed to :func:`~drake_coop.experiment.diagram.build_experiment` (visualizers).
    on_start : callable, optional
        ``on_start(experiment, simulator)`` just before the first step (start recordings); a
        monitor it sets with ``simulator.set_monitor`` is called at every step (a termination
        it returns ends the run as diverged, with its message).
    hold_signals : callable, optional
        A context manager factory entered once the loop has stopped, around the collection of
        the logs (the command line defers SIGINT/SIGTERM there, so that a second Ctrl-C cannot
        lose what was logged).
    live_ground_truth : bool, optional
        Passed to :func:`~drake_coop.experiment.diagram.build_experiment`: where the ground
        truth and the F/T sensor model are computed (None: inside the loop only when a
        controller reads the sensor or outside the ``planes`` and ``rigid`` modes; otherwise
        after the run).
    clocks : sequence of (Clock or None), optional
        Each robot's controller-side clock (:meth:`RunPlan.with_clocks
        <drake_coop.experiment.plan.RunPlan.with_clocks>`); None: every robot on the run's
        grid.

    Returns
    -------
    RunResult
        ``meta["status"]`` is ``"ok"``, ``"diverged"``, ``"failed"`` (a failure guard, with
        ``meta["failure"]``: the guard, robot or ``box``, time, value and bound) or
        ``"interrupted"`` (Ctrl-C), with ``meta["message"]``; the logs hold everything up to
        the stop.

    Raises
    ------
    ScenarioError
        If the run's work exceeds :data:`~drake_coop.experiment.ticks.MAX_TICKS` or
        :data:`~drake_coop.experiment.ticks.MAX_PLANT_STEPS` (checked before anything is built),
        or, in ``contact`` mode, if an arm's squeeze and load need more than its torque limits
        somewhere along the path (:mod:`drake_coop.experiment.squeeze_check`, also before).
    """
    plan = plan_run(scenario, t_end)
    if clocks is not None:
        plan = plan.with_clocks(clocks)
    T = plan.t_end
    check_run_size(scenario, T)
    # The plan's references run only to the run's end: a long task stopped early stays cheap.
    from drake_coop.experiment.squeeze_check import check_squeeze_limits
    check_squeeze_limits(plan)      # contact mode: refused before anything is built
    exp = build_experiment(plan, before_build=before_build,
                           live_ground_truth=live_ground_truth)
    simulator = Simulator(exp.diagram)
    context = simulator.get_mutable_context()
    initialize(exp, context)
    simulator.Initialize()
    if on_start is not None:
        on_start(exp, simulator)
    status, message, failure = "ok", "", None
    failures = failure_check(exp)
    plant_context = exp.coop.plant.GetMyMutableContextFromRoot(context)
    grasp = exp.coop.grasp
    stand = grasp if grasp is not None and grasp.stand_drop > 0 else None
    start = time.perf_counter()
    try:
        # Stop where the plant changes (grasp, release), at the end, and every guard period,
        # at control ticks (k h, computed as Drake computes event times).
        stops = guard_chunks(plan, scenario.guards.check_period)
        # The pads' desired positions at every stop, the task's path evaluated once a robot.
        x_d = [cartesian_reference(scenario.task, robot, np.asarray(stops) * plan.h)[0]
               for robot in scenario.robots]
        for j, k_stop in enumerate(stops):
            try:
                result = simulator.AdvanceTo(k_stop * plan.h)
            except RuntimeError as exc:   # e.g. the contact solver failing on a blown-up state
                status, message = "diverged", (
                    f"simulation failed at t = {context.get_time():.3f} s: "
                    f"{' '.join(str(exc).split())[:300]}")
                break
            if result.reason() == SimulatorStatus.ReturnReason.kReachedTerminationCondition:
                status, message = "diverged", result.message()   # a monitor of on_start
                break
            forces: list = []
            reason = _check_guards(exp, context, forces)
            if reason is not None:
                status = "diverged"
                message = f"diverged at t = {context.get_time():.3f} s: {reason}"
                break
            failure = failures.check(plant_sample(exp, context, forces,
                                                  [x[j] for x in x_d]))
            if failure is not None:
                status, message = "failed", failure.message
                break
            if k_stop in plan.switches:
                exp.coop.set_held(plant_context, plan.switches[k_stop])
            if stand is not None:     # lowered while the box goes around the circle
                t_now = context.get_time()
                stand.set_stand_lowered(plant_context, scenario.task.t_circle_start <= t_now
                                        < scenario.task.t_circle_end)
            if progress is not None and k_stop != plan.k_end:
                progress(context.get_time(), T, time.perf_counter() - start)
        if status == "ok" and progress is not None:
            progress(context.get_time(), T, time.perf_counter() - start)
    except KeyboardInterrupt:     # Ctrl-C, wherever it lands: stop, keep what was logged
        status, message = "interrupted", f"interrupted at t = {context.get_time():.3f} s"
    wall = time.perf_counter() - start
    t_stop = float(context.get_time())
    with hold_signals() if hold_signals is not None else contextlib.nullcontext():
        finish_last_tick(exp, simulator, status)
        logs = collect_logs(exp, context)
        if status == "ok":     # a failure between two chunks: every logged tick checked
            failure = first_failure_in_logs(failures, logs)
            if failure is not None:
                status, message = "failed", failure.message
    meta = {
        "status": status,
        "message": message or f"completed {T:g} s",
        **({"failure": failure.as_dict()} if failure is not None else {}),
        "phases": phases(scenario),
        "robots": [rs.name for rs in exp.robots],
        "control_period": plan.h,
        "plant_time_step": scenario.plant.time_step,
        "object_mode": scenario.plant.object_mode,
        "friction": scenario.plant.friction,
        "object_mass": scenario.plant.object_mass,
        **({"object_size": [float(v) for v in exp.coop.grasp.size]}
           if exp.coop.grasp is not None else {}),
        # l >= 3 pads (the prism): each pad's face, [n_x, n_y, n_z, offset] in the object's frame
        **({"object_faces": [[*map(float, n), float(d)] for n, d in zip(
            exp.coop.grasp.face_normals, exp.coop.grasp.face_offsets)]}
           if exp.coop.grasp is not None and exp.coop.grasp.face_normals is not None else {}),
        "t_end": t_stop,
        "wall_time_s": wall,
        "realtime_factor": t_stop / wall if wall > 0 else None,
        "scenario_yaml": dump_scenario(scenario),
    }
    return RunResult(logs=logs, meta=meta, wall_time=wall, experiment=exp)
