"""Benchmark: the control loop's cost against the plant's, measured as ratios in one process.

``python bench/benchmark.py`` measures, on this machine:

1. **ratio**: the paper's experiment (``planes`` mode, everything logged, progress off) against
   the plant alone (the same plant and constraints, stepped the same way at the same step,
   with constant gravity-compensating torques and no Python system), alternated ``repeats``
   times in this process; wall time and CPU time (``time.process_time``: less sensitive to the
   other processes of a shared machine). Reported: every pair's ratio, the median and range.
2. **ground truth and sensor models**: their Python callbacks' time per tick (from 3.) over
   the plant alone's cost per tick.
3. **per-system breakdown**: one run with every Python callback of the control block and the
   force sensor timed (exclusive time: a callback's time minus that of the Python callbacks it
   triggers); per robot and per tick. C++ work a callback triggers stays in its time (e.g. the
   sensor's first read at a tick triggers the plant's solve of that step, which the plant's
   own update then reuses).
4. **isolated tick cost**: one tick's equations of one robot (controller (13), force observer
   (22), velocity observer (15)-(16)) timed with ``timeit`` outside the diagram.
5. **scaling**: cost per control tick (full run and plant alone) at plant steps of 1, 3 and
   9 ms, and the paper run's cost per robot; the growth with the number of robots is measured
   by :mod:`bench.robots_scaling` (``python bench/robots.py``).
6. optionally the realtime factor of another scenario (e.g. ``scenarios/contact.yaml``).
"""

from __future__ import annotations

import contextlib
import functools
import json
import platform
import statistics
import time
import timeit
from collections import defaultdict

import numpy as np


# ---------------------------------------------------------------------------- single runs
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
    from drake_coop.experiment.references import reference_samples
    from drake_coop.experiment.plan import time_grid
    from drake_coop.plant.cooperative import build_plant, initialize_plant_context

    b = DiagramBuilder()
    coop = build_plant(b, scenario, time_step=time_grid(scenario)[1])
    q0 = [reference_samples(scenario, i, 0.0)[1][0, :h.arm.kinematics.n]
          for i, h in enumerate(coop.arms)]
    for i, h in enumerate(coop.arms):
        src = b.AddNamedSystem(f"{h.arm.name}_torque",
                               ConstantVectorSource(arm_model(h.arm).g(q0[i])))
        b.Connect(src.get_output_port(), coop.plant.get_actuation_input_port(h.instance))
    finish = None
    if extras is not None:
        finish = extras(b, coop, *time_grid(scenario))
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
    coop = build_plant(b, scenario, time_step=plan.dt)
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
    initialize_plant_context(coop, pc, *rest_posture(scenario, [h.arm for h in coop.arms]))
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


# ------------------------------------------------------------- ground truth and sensors
def _hold(port_of, offset_of):
    """``extras`` for :func:`_plant_alone`: a C++ ``ZeroOrderHold`` of one plant port, period
    ``h``, at ``offset_of(h, dt)`` (no Python: what a read of that port costs the plant)."""
    def extras(b, coop, h, dt):
        from pydrake.systems.primitives import ZeroOrderHold

        port = port_of(coop.plant)
        hold = b.AddSystem(ZeroOrderHold(h, port.size(), offset_of(h, dt)))
        b.Connect(port, hold.get_input_port())
    return extras


def _ground_truth(with_models: bool):
    """``extras`` for :func:`_plant_alone`: the experiment's ground truth
    (:func:`~drake_coop.plant.wrist.add_force_sensors`, latched at every tick) and, with
    ``with_models``, the F/T sensor models wired as in the experiment."""
    def extras(b, coop, h, dt):
        from drake_coop.plant.wrist import add_force_sensors
        from drake_coop.sensing import force_sensor

        sensors = add_force_sensors(b, coop, h)
        if with_models:
            for i, (handles, sensor) in enumerate(zip(coop.arms, sensors)):
                live = sensor.GetOutputPort("lambda_meas")
                if hasattr(force_sensor, "add_ft_sensor"):
                    force_sensor.add_ft_sensor(b, handles.arm.name, h, dt, None, i,
                                               handles.arm.m, live, sensor.lambda_last_step)
                else:     # the first pass's wiring (for a before/after run of this bench)
                    ft = b.AddSystem(force_sensor.FTSensor(h, dt, None, i, handles.arm.m))
                    b.Connect(live, ft.GetInputPort("lambda_true"))
    return extras


def _contact_reaction_ground_truth(b, coop, h, dt):
    """``extras`` for :func:`_plant_alone` in ``contact`` mode: the ground truth as it was
    before ``pad_forces`` (Newton's law on the reaction forces and body lists,
    :class:`~drake_coop.plant.wrist.WristKinematics`, latched at every tick, and the F/T
    models reading the live force at ``t_k − 3Δt/2``), for the before/after comparison."""
    from drake_coop.plant.wrist import ForceSensor, WristKinematics
    from drake_coop.sensing.force_sensor import FTSensor

    plant = coop.plant
    wrist = b.AddSystem(WristKinematics(plant, coop.arms))
    for name in ("reaction_forces", "body_poses", "body_spatial_velocities",
                 "body_spatial_accelerations"):
        b.Connect(plant.GetOutputPort(name), wrist.GetInputPort(name))
    for i, handles in enumerate(coop.arms):
        sensor = b.AddSystem(ForceSensor(plant, handles, h))
        b.Connect(wrist.GetOutputPort(f"{handles.arm.name}_wrist"), sensor.GetInputPort("wrist"))
        ft = b.AddSystem(FTSensor(h, dt, None, i, handles.arm.m))
        b.Connect(sensor.GetOutputPort("lambda_meas"), ft.GetInputPort("lambda_true"))


def _contact_pad_force_log(b, coop, h, dt):
    """``extras`` for :func:`_plant_alone` in ``contact`` mode: the experiment's ground truth
    (:func:`~drake_coop.plant.ground_truth.add_pad_force_log`: the pads' forces read by a C++
    hold at every plant step and logged) and, after the run, its evaluation of every tick
    (``F_meas``, ``lambda_meas``, ideal F/T models' ``lambda_sensor``)."""
    from drake_coop.plant.ground_truth import add_pad_force_log
    from drake_coop.sensing.force_sensor import FTModel

    truth = add_pad_force_log(b, coop, h, [FTModel.from_settings(None, h, i, a.arm.m)
                                           for i, a in enumerate(coop.arms)])
    steps = int(round(h / dt))

    def finish(context):
        published = truth.logger.FindLog(context).num_samples()
        truth.evaluate(context, max((published - 2) // steps, 0), False)
    return finish


#: :func:`_sensing_attribution`'s additions for a ``contact`` scenario.
_CONTACT_ATTRIBUTION = {
    "contact ground truth now: pad forces held and logged at every plant step (C++), "
    "evaluated after the run":
        _contact_pad_force_log,
    "contact ground truth before issue 25: reaction forces + body lists at t_k and t_k - 3dt/2":
        _contact_reaction_ground_truth,
}


def _offline_ground_truth(b, coop, h, dt):
    """``extras`` for :func:`_plant_alone`: the offline ground truth's C++ holds and log
    (:func:`~drake_coop.plant.ground_truth.add_ground_truth`, ideal F/T models) and, after
    the run, its evaluation of every tick (``F_meas``, ``lambda_meas``, ``lambda_sensor``)."""
    from drake_coop.plant.ground_truth import add_ground_truth
    from drake_coop.sensing.force_sensor import FTModel

    gt = add_ground_truth(b, coop, h, [FTModel.from_settings(None, h, i, a.arm.m)
                                       for i, a in enumerate(coop.arms)],
                          [b.GetSubsystemByName(f"{a.arm.name}_torque").get_output_port()
                           for a in coop.arms])

    def finish(context):
        published = gt.logger.FindLog(context).num_samples()
        gt.evaluate(context, max(published - 1, 0), False)
    return finish


#: Diagrams of :func:`_sensing_attribution`: the plant alone plus one addition each.
_ATTRIBUTION = {
    "C++ hold of the plant state at t_k - 3dt/2 (an event, no solve)":
        _hold(lambda plant: plant.get_state_output_port(), lambda h, dt: h - 1.5 * dt),
    "C++ hold of the acceleration port at t_k - 3dt/2 (a solve off the plant's update)":
        _hold(lambda plant: plant.get_generalized_acceleration_output_port(),
              lambda h, dt: h - 1.5 * dt),
    "C++ hold of the acceleration port at t_k (the plant's own update's solve)":
        _hold(lambda plant: plant.get_generalized_acceleration_output_port(),
              lambda h, dt: 0.0),
    "ground truth, latched at every tick": _ground_truth(False),
    "ground truth + both F/T sensor models (the live chain, force_source: sensor)":
        _ground_truth(True),
    "offline ground truth: C++ holds + evaluation after the run (the paper's run)":
        _offline_ground_truth,
}



def _sensing_attribution(scenario, t_end: float, repeats: int,
                         additions: dict | None = None) -> dict:
    """CPU seconds of the plant alone and of the plant with each addition of
    :data:`_ATTRIBUTION`, alternated ``repeats`` times in this process; each addition's extra
    cost per control tick (median of its pairs with the plant alone run just before it) and as
    a share of the plant alone's cost per tick."""
    from drake_coop.experiment.plan import num_ticks_until
    from drake_coop.experiment.plan import time_grid

    h, _ = time_grid(scenario)
    ticks = num_ticks_until(t_end, h)
    extra: dict[str, list[float]] = defaultdict(list)
    plant: list[float] = []
    for _ in range(max(1, repeats)):
        for label, extras in (_ATTRIBUTION if additions is None else additions).items():
            alone = _plant_alone(scenario, t_end)[1]
            with_it = _plant_alone(scenario, t_end, extras)[1]
            plant.append(alone)
            extra[label].append(1e6 * (with_it - alone) / ticks)
    plant_us = 1e6 * statistics.median(plant) / ticks
    rows = {label: {**_spread(v), "share": statistics.median(v) / plant_us}
            for label, v in extra.items()}
    return {"plant_alone_us_per_tick": plant_us, "extra_us_per_tick": rows}


# ------------------------------------------------------------------- object-aware blocks
def _object_blocks_cost(scenario, t_end: float, repeats: int) -> dict:
    """What the object-aware blocks (``object_model``: ``LoadFeedforward`` and, when
    ``estimated``, ``MassEstimator``) add to a run, apart from the plant's own changed work.

    CPU seconds of the scenario with ``object_model.mode`` ``none``, ``known`` and
    ``estimated``, alternated ``repeats`` times in this process, each run followed by the
    plant alone replaying that run's applied torques (:func:`_plant_replay`, its deviation
    from the run's joint angles and box pose reported). The runs differ physically (other
    torques, other contact states), so the plain ratio ``run_X / run_none`` mixes the blocks'
    cost with the plant's. Per repeat:

    * ``ratio_to_none`` = ``run_X / run_none`` (the plain ratio);
    * ``blocks_own`` = ``(run_X / replay_X) / (run_none / replay_none) − 1``: what the blocks
      add to the loop's cost over its own plant;
    * ``plant_difference`` = ``replay_X / replay_none − 1``: the plant's own extra work on
      the object-aware run's trajectory.

    And, from one instrumented ``estimated`` run, the blocks' own Python time per tick. The
    load average (1 min) is recorded at the start and the end."""
    import copy
    import os

    from drake_coop.experiment.plan import num_ticks_until, time_grid

    load_start = os.getloadavg()[0]
    modes = ("none", "known", "estimated")
    variants = {}
    for mode in modes:
        variants[mode] = copy.deepcopy(scenario)
        variants[mode].object_model.mode = mode
    cpu: dict[str, list[float]] = defaultdict(list)
    replay: dict[str, list[float]] = defaultdict(list)
    deviation = 0.0
    for _ in range(max(1, repeats)):
        for mode in modes:
            kept: list = []
            cpu[mode].append(_experiment(variants[mode], t_end, kept)[1])
            r = _plant_replay(variants[mode], t_end, kept[0])
            kept.clear()
            replay[mode].append(r[1])
            deviation = max(deviation, r[2])
    ratios, own, plant = defaultdict(list), defaultdict(list), defaultdict(list)
    for k in range(len(cpu["none"])):
        base, base_replay = cpu["none"][k], replay["none"][k]
        for mode in modes[1:]:
            ratios[mode].append(cpu[mode][k] / base)
            own[mode].append((cpu[mode][k] / replay[mode][k]) / (base / base_replay) - 1.0)
            plant[mode].append(replay[mode][k] / base_replay - 1.0)
    totals: dict = defaultdict(float)
    with _timed_callbacks(totals):
        _experiment(variants["estimated"], t_end)
    ticks = num_ticks_until(t_end, time_grid(scenario)[0])
    blocks = {label: 1e6 * sum(v for (lab, _), v in totals.items() if lab == label) / ticks
              for label in ("load feedforward (object_model)",
                            "mass estimator (object_model: estimated)")}
    return {"cpu_s": {k: _spread(v) for k, v in cpu.items()},
            "replay_cpu_s": {k: _spread(v) for k, v in replay.items()},
            "run_over_replay": {k: _spread([c / r for c, r in zip(cpu[k], replay[k])])
                                for k in modes},
            "ratio_to_none": {k: _spread(v) for k, v in ratios.items()},
            "blocks_own": {k: _spread(v) for k, v in own.items()},
            "plant_difference": {k: _spread(v) for k, v in plant.items()},
            "replay_max_deviation": deviation,
            "per_repeat": {"cpu_s": dict(cpu), "replay_cpu_s": dict(replay)},
            "python_us_per_tick": blocks, "simulated_s": t_end, "repeats": repeats,
            "load_average_1min": [load_start, os.getloadavg()[0]]}


# ----------------------------------------------------------------------- per-system timing
_TIMED = {
    "velocity observer (15)-(16)": ("drake_coop.control.observers", "VelocityObserver",
                                    ("_calc_qdot_hat", "_calc_qdot_o", "_update_observer")),
    "force observer (22)": ("drake_coop.control.observers", "ForceObserver",
                            ("_calc_lambda_hat", "_update_integral")),
    "controller (13)": ("drake_coop.control.controller", "Controller",
                        ("_update_latch",)),
    "force sensor (ground truth)": ("drake_coop.plant.wrist", "ForceSensor",
                                    ("_calc_force_cache", "_calc_force", "_calc_lambda",
                                     "_update_step")),
    "F/T sensor model": ("drake_coop.sensing.force_sensor", "FTSensor", ("_update_reading",)),
    "wrist kinematics (all arms)": ("drake_coop.plant.wrist", "WristKinematics",
                                    ("_calc_signals",)),
    "wrist dynamics (all arms)": ("drake_coop.plant.wrist", "WristDynamics",
                                  ("_calc_signals", "_calc_last_step", "_update_step")),
    "pad forces (contact ground truth, all arms)": ("drake_coop.plant.grasp", "PadForces",
                                                    ("_calc_forces",)),
    "load feedforward (object_model)": ("drake_coop.control.object", "LoadFeedforward",
                                        ("_update",)),
    "mass estimator (object_model: estimated)": ("drake_coop.control.object", "MassEstimator",
                                                 ("_update",)),
}


@contextlib.contextmanager
def _timed_callbacks(totals: dict):
    """Time the Python callbacks of the systems in :data:`_TIMED` (exclusive time).

    ``totals[(label, system name)]`` accumulates seconds. Systems built inside the block are
    timed (their callbacks are bound when they are declared).
    """
    import importlib

    stack: list[float] = []     # time spent in nested timed callbacks, per open frame
    # CPU time of this thread: the other processes of a shared machine do not count.
    patched = []

    def wrap(label, fn):
        @functools.wraps(fn)
        def timed(self, *args):
            stack.append(0.0)
            start = time.thread_time()
            try:
                return fn(self, *args)
            finally:
                elapsed = time.thread_time() - start
                nested = stack.pop()
                totals[(label, self.get_name())] += elapsed - nested
                if stack:
                    stack[-1] += elapsed
        return timed

    for label, (module, cls_name, methods) in _TIMED.items():
        cls = getattr(importlib.import_module(module), cls_name)
        for m in methods:
            original = getattr(cls, m, None)
            if original is None:     # an older version of the system (before/after runs)
                continue
            patched.append((cls, m, original))
            setattr(cls, m, wrap(label, original))
    try:
        yield
    finally:
        for cls, m, original in patched:
            setattr(cls, m, original)


def _builtin(callable_):
    """The compiled function a call reaches (a builtin, a pybind11 or nanobind function), or
    None for anything else (a Python function, a class): a bound method's function is
    unwrapped, as the interpreter does before calling it."""
    import types

    func = callable_.__func__ if isinstance(callable_, types.MethodType) else callable_
    if isinstance(func, (types.BuiltinFunctionType, types.MethodDescriptorType)) \
            or type(func).__module__ == "nanobind":      # drake >= 1.52 binds with nanobind
        return func
    return None


@contextlib.contextmanager
def _calls_from_builtins(count):
    """Call ``count(frame)`` for every Python frame entered directly from inside a builtin
    (pybind) call while the block runs.

    Drake 1.51 (Python 3.11) binds with pybind11, whose functions are builtins that
    ``sys.setprofile`` reports (``c_call``/``c_return``). Drake 1.58 (Python 3.12+) binds with
    nanobind, whose functions ``sys.setprofile`` does not report at all (and 3.12 drops the
    ``c_call`` of any bound builtin method), so from 3.12 on the calls are taken from
    ``sys.monitoring``, whose ``CALL``/``C_RETURN`` events see every callable.
    """
    import sys

    inside: list = []        # (frame, builtin) of the builtin calls in progress

    if sys.version_info < (3, 12):
        def hook(frame, event, arg):
            if event == "c_call":
                inside.append((frame, arg))
            elif event in ("c_return", "c_exception"):
                if inside:
                    inside.pop()
            elif event == "call" and inside and inside[-1][0] is frame.f_back:
                count(frame)

        sys.setprofile(hook)
        try:
            yield
        finally:
            sys.setprofile(None)
        return

    mon = sys.monitoring
    E = mon.events
    tool = next((i for i in range(mon.PROFILER_ID, 6) if mon.get_tool(i) is None), None)
    if tool is None:
        raise RuntimeError("no free sys.monitoring tool id to count callbacks")

    def on_call(code, offset, callable_, arg0):
        func = _builtin(callable_)
        if func is not None:
            inside.append((sys._getframe(1), func))

    def on_c_end(code, offset, callable_, arg0, *exc):
        if inside and inside[-1][1] is _builtin(callable_):
            inside.pop()

    def on_start(code, offset):
        frame = sys._getframe(1)
        if inside and inside[-1][0] is frame.f_back:
            count(frame)

    mon.use_tool_id(tool, "drake_coop bench")
    try:
        mon.register_callback(tool, E.CALL, on_call)
        mon.register_callback(tool, E.C_RETURN, on_c_end)
        mon.register_callback(tool, E.C_RAISE, on_c_end)
        mon.register_callback(tool, E.PY_START, on_start)
        mon.set_events(tool, E.CALL | E.C_RETURN | E.C_RAISE | E.PY_START)
        yield
    finally:
        mon.set_events(tool, 0)
        mon.free_tool_id(tool)


def _count_callbacks(scenario, t_end: float) -> dict:
    """Python callbacks per control tick of a run to ``t_end``: every Python function that
    C++ calls (an event, an output port, a cache entry, a monitor), counted as a call of a
    ``drake_coop`` function (not a generator) made directly from inside a builtin (pybind)
    call (:func:`_calls_from_builtins`).
    Returns the total per tick and the count per tick of each function (``module.qualname``).
    """
    import inspect

    from drake_coop.experiment.plan import num_ticks_until
    from drake_coop.experiment.simulate import simulate
    from drake_coop.experiment.plan import time_grid

    counts: dict[str, int] = defaultdict(int)
    counting = contextlib.ExitStack()

    def count(frame):
        code, module = frame.f_code, frame.f_globals.get("__name__", "?")
        # Not a generator resumed by sum()/tuple(), not NumPy's own Python.
        if module.startswith("drake_coop") and not code.co_flags & inspect.CO_GENERATOR:
            counts[f"{module}.{code.co_qualname}"] += 1

    def start(exp, simulator):
        counts.clear()
        counting.enter_context(_calls_from_builtins(count))

    with counting:
        result = simulate(scenario, t_end=t_end, on_start=start)
    if not result.ok:
        raise RuntimeError(f"benchmark run failed: {result.meta['message']}")
    h, _ = time_grid(scenario)
    ticks = num_ticks_until(t_end, h)
    return {"per_tick": sum(counts.values()) / ticks,
            "by_function": {k: v / ticks for k, v in sorted(counts.items(),
                                                          key=lambda kv: -kv[1])}}


def _tick_costs(scenario) -> dict[str, float]:
    """Microseconds per tick of each system's equations on held samples of robot 1.

    Two postures alternate from call to call, as ``q`` changes from tick to tick (the model
    keeps its kinematics while ``q`` is unchanged). The last entry is one whole tick of the
    robot: (15)/(8), (22), (13) and (16) at the same sample.
    """
    from drake_coop.plant.arms import arm_model
    from drake_coop.control.finger import FingerLaw
    from drake_coop.experiment.references import reference_samples
    from drake_coop.plant.arms import Arm

    robot = scenario.robots[0]
    law = FingerLaw(arm_model(Arm(robot, scenario.task)), robot.gains)
    _, r = reference_samples(scenario, 0)
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


def _spread(values: list[float]) -> dict[str, float]:
    return {"median": statistics.median(values), "min": min(values), "max": max(values)}


# ------------------------------------------------------------------------------ the bench
def run_benchmark(t_end: float = 90.0, repeats: int = 1, out: str | None = None,
                  t_scaling: float = 20.0, extra_scenario: str | None = None,
                  t_extra: float | None = None, t_attribution: float = 10.0,
                  attribution_repeats: int = 5, t_callbacks: float = 16.2,
                  object_repeats: int = 0) -> dict:
    """Run the benchmark, print its tables and return the numbers.

    Parameters
    ----------
    t_end : float
        Simulated seconds of the ratio runs (90 s = the paper's experiment).
    repeats : int
        Pairs (experiment, plant alone) alternated for the ratio; the spread is reported.
    out : str, optional
        Also write the numbers as JSON to this file.
    t_scaling : float
        Simulated seconds of each run of the plant-step scaling (0 skips it).
    extra_scenario : str, optional
        A scenario file whose realtime factor is also measured (e.g. the contact mode).
    t_extra : float, optional
        Simulated seconds of that run (default: the scenario's whole task).
    t_attribution, attribution_repeats : float, int
        Simulated seconds and alternated repeats of the ground truth's attribution
        (:func:`_sensing_attribution`; 0 s skips it).
    t_callbacks : float
        Simulated seconds of the run whose Python callbacks are counted
        (:func:`_count_callbacks`; 0 skips it).
    object_repeats : int
        With a ``contact`` extra scenario: alternated repeats of the object-aware blocks'
        cost (:func:`_object_blocks_cost`, ``t_extra`` seconds each, every run followed by
        its plant replay; 0 skips it).
    """
    from drake_coop.experiment.plan import num_ticks_until
    from drake_coop.scenario.loading import default_scenario, load_scenario
    from drake_coop.experiment.plan import time_grid

    scenario = default_scenario()
    h, _ = time_grid(scenario)
    ticks = num_ticks_until(t_end, h)
    line = "-" * 78

    # 1. ratio, alternated in this process
    pairs = []
    for _ in range(max(1, repeats)):
        kept: list = []
        full = _experiment(scenario, t_end, kept)
        plant = _plant_alone(scenario, t_end)
        replay = _plant_replay(scenario, t_end, kept[0])
        kept.clear()
        pairs.append({"full_wall_s": full[0], "full_cpu_s": full[1], "plant_wall_s": plant[0],
                      "plant_cpu_s": plant[1], "ratio_wall": full[0] / plant[0],
                      "ratio_cpu": full[1] / plant[1], "replay_cpu_s": replay[1],
                      "replay_max_q_deviation_rad": replay[2],
                      "ratio_cpu_replay": full[1] / replay[1]})
    print(line)
    print(f"paper experiment ({t_end:g} s, planes, plant step "
          f"{1e3 * scenario.plant.time_step:g} ms, h = {1e3 * h:g} ms) vs plant alone")
    for i, p in enumerate(pairs):
        print(f"  run {i + 1}: experiment {p['full_wall_s']:6.2f} s wall / {p['full_cpu_s']:6.2f}"
              f" s CPU; plant alone {p['plant_wall_s']:5.2f} / {p['plant_cpu_s']:5.2f} s;"
              f" ratio {p['ratio_wall']:.2f} wall, {p['ratio_cpu']:.2f} CPU")
    ratio_wall = _spread([p["ratio_wall"] for p in pairs])
    ratio_cpu = _spread([p["ratio_cpu"] for p in pairs])
    best = min(p["full_wall_s"] for p in pairs)
    print(f"  ratio (median [min, max]): wall {ratio_wall['median']:.2f} "
          f"[{ratio_wall['min']:.2f}, {ratio_wall['max']:.2f}], CPU {ratio_cpu['median']:.2f} "
          f"[{ratio_cpu['min']:.2f}, {ratio_cpu['max']:.2f}]   (target <= 1.4, aim 1.3)")
    print(f"  experiment realtime factor x{t_end / best:.2f} (best run)")
    ratio_replay = _spread([p["ratio_cpu_replay"] for p in pairs])
    print("  plant alone replaying the run's torques: "
          + ", ".join(f"{p['replay_cpu_s']:.2f} s CPU" for p in pairs)
          + f" (joint angles within {max(p['replay_max_q_deviation_rad'] for p in pairs):.1e}"
          f" rad of the run's); ratio CPU {ratio_replay['median']:.2f} "
          f"[{ratio_replay['min']:.2f}, {ratio_replay['max']:.2f}]")

    # 3. per-system breakdown (instrumented run)
    totals: dict = defaultdict(float)
    with _timed_callbacks(totals):
        instrumented = _experiment(scenario, t_end)
    per_system: dict[str, dict[str, float]] = defaultdict(dict)
    for (label, name), seconds in sorted(totals.items()):
        per_system[label][name.split("_")[0]] = 1e6 * seconds / ticks
    python_us = sum(sum(v.values()) for v in per_system.values())
    print(line)
    print(f"per-system breakdown, us per control tick (instrumented run, "
          f"{1e6 * instrumented[1] / ticks:.0f} us CPU per tick in all)")
    for label, robots in per_system.items():
        print(f"  {label:30s} " + "  ".join(f"{r} {v:7.1f}" for r, v in robots.items()))
    robots = [r.name for r in scenario.robots]       # (the wrist kinematics serve them all)
    control = {r: sum(per_system[k].get(r, 0.0) for k in _TIMED if "sensor" not in k)
               for r in robots}
    print("  controller + both observers, per robot: "
          + ", ".join(f"{r} {v:.1f} us" for r, v in control.items())
          + "   (target <= 60 us)")
    plant_tick = 1e6 * statistics.median(p["plant_cpu_s"] for p in pairs) / ticks
    framework = 1e6 * instrumented[1] / ticks - plant_tick - python_us
    print(f"  plant alone {plant_tick:.0f} us; Python callbacks {python_us:.0f} us; the rest "
          f"(events, ports, loggers, timing) {framework:.0f} us")
    sensing_us = sum(sum(per_system[k].values()) for k in per_system if "sensor" in k
                     or "wrist" in k)
    log_share = sensing_us / plant_tick
    if sensing_us > 0:
        print(f"  ground truth + sensor models {sensing_us:.0f} us per tick = "
              f"{100 * log_share:.1f} % of the plant's cost (target <= 10 %)")
    else:     # the offline ground truth: C++ holds in the loop, evaluated after the run
        print("  ground truth + sensor models: no Python in the loop (C++ holds, evaluated "
              "after the run: see the attribution's 'offline ground truth' row)")

    # 2b. the ground truth's and the sensor models' true extra cost (plant alone + each)
    attribution = None
    if t_attribution > 0:
        attribution = _sensing_attribution(scenario, t_attribution, attribution_repeats)
        print(line)
        print(f"extra CPU per control tick over the plant alone "
              f"({attribution['plant_alone_us_per_tick']:.0f} us), {attribution_repeats} "
              f"alternated pairs of {t_attribution:g} s, median [min, max]:")
        for label, r in attribution["extra_us_per_tick"].items():
            print(f"  {r['median']:7.1f} us [{r['min']:7.1f}, {r['max']:7.1f}] "
                  f"= {100 * r['share']:5.1f} %  {label}")
    callbacks = None
    if t_callbacks > 0:
        callbacks = _count_callbacks(scenario, t_callbacks)
        print(f"Python callbacks per control tick (both robots, 0-{t_callbacks:g} s): "
              f"{callbacks['per_tick']:.1f}")
        for name, c in callbacks["by_function"].items():
            print(f"  {c:5.2f}  {name}")

    # 4. one tick's equations in isolation
    costs = _tick_costs(scenario)
    print("isolated equations, us per tick (timeit, held samples of robot 1; target for all "
          "three <= 40 us):")
    for k, v in costs.items():
        print(f"  {k:34s} {v:8.1f} us")

    # 5. scaling with the plant step and the number of robots
    scaling = []
    if t_scaling > 0:
        print(line)
        print(f"cost per control tick vs plant step ({t_scaling:g} s runs, CPU):")
        for step in (0.001, 0.003, 0.009):
            s = default_scenario()
            s.plant.time_step = step
            n = num_ticks_until(t_scaling, h)
            full_s = _experiment(s, t_scaling)[1]
            plant_s = _plant_alone(s, t_scaling)[1]
            row = {"plant_step_s": step, "experiment_us_per_tick": 1e6 * full_s / n,
                   "plant_alone_us_per_tick": 1e6 * plant_s / n,
                   "control_loop_us_per_tick": 1e6 * (full_s - plant_s) / n,
                   "ratio": full_s / plant_s}
            scaling.append(row)
            print(f"  {1e3 * step:3g} ms: experiment {row['experiment_us_per_tick']:6.0f}, plant "
                  f"alone {row['plant_alone_us_per_tick']:6.0f}, control loop "
                  f"{row['control_loop_us_per_tick']:6.0f} us per tick (ratio {row['ratio']:.2f})")
    full_cpu = statistics.median(p["full_cpu_s"] for p in pairs)
    loop_us = 1e6 * (full_cpu - statistics.median(p["plant_cpu_s"] for p in pairs)) / ticks
    per_robot = loop_us / len(robots)
    print(f"per robot: the control loop costs {per_robot:.0f} us per tick per robot "
          f"({loop_us:.0f} us for {len(robots)}); l robots ~ plant(l) + l x {per_robot:.0f} us "
          f"per tick (measured for l = 2..6 by bench/robots.py)")

    # 6. another scenario's realtime factor, and how much of it is the Python callbacks
    extra = None
    if extra_scenario:
        s = load_scenario(extra_scenario)
        T = s.task.t_end if t_extra is None else t_extra
        wall, cpu = _experiment(s, T)
        totals = defaultdict(float)
        with _timed_callbacks(totals):
            timed_cpu = _experiment(s, T)[1]
        python_s = sum(totals.values())
        by_label: dict[str, float] = defaultdict(float)
        for (label, _), seconds in totals.items():
            by_label[label] += seconds
        s_h, _ = time_grid(s)
        extra_ticks = num_ticks_until(T, s_h)
        profile = {label: 1e6 * v / extra_ticks for label, v in by_label.items()}
        profile["plant, framework and C++ systems (the rest)"] = \
            1e6 * (timed_cpu - python_s) / extra_ticks
        extra = {"scenario": extra_scenario, "simulated_s": T, "wall_s": wall, "cpu_s": cpu,
                 "realtime_factor_wall": T / wall, "realtime_factor_cpu": T / cpu,
                 "python_callbacks_share": python_s / timed_cpu,
                 "instrumented_us_per_tick": profile}
        print(line)
        print(f"{extra_scenario}: {T:g} s in {wall:.2f} s wall / {cpu:.2f} s CPU "
              f"(realtime x{T / wall:.2f} wall, x{T / cpu:.2f} CPU); the Python callbacks are "
              f"{100 * python_s / timed_cpu:.0f} % of an instrumented run, the rest is the plant "
              f"and the framework")
        print(f"  where a tick goes (instrumented run, {1e6 * timed_cpu / extra_ticks:.0f} us "
              f"CPU per tick in all; wrist kinematics = the reaction forces and body lists):")
        for label, us in sorted(profile.items(), key=lambda kv: -kv[1]):
            print(f"    {us:8.1f} us  {label}")
        if s.plant.object_mode == "contact" and t_attribution > 0:
            contact = _sensing_attribution(s, t_attribution, attribution_repeats,
                                           _CONTACT_ATTRIBUTION)
            extra["ground_truth_attribution"] = contact
            print(f"  its ground truth: extra CPU per control tick over its plant alone "
                  f"({contact['plant_alone_us_per_tick']:.0f} us: arms held by constant "
                  f"torques, the box on its stand), {attribution_repeats} alternated pairs of "
                  f"{t_attribution:g} s, median [min, max] (target <= 15 %):")
            for label, r in contact["extra_us_per_tick"].items():
                print(f"    {r['median']:7.1f} us [{r['min']:7.1f}, {r['max']:7.1f}] "
                      f"= {100 * r['share']:5.1f} %  {label}")
        if s.plant.object_mode == "contact" and object_repeats > 0:
            blocks = _object_blocks_cost(s, T, object_repeats)
            extra["object_blocks"] = blocks
            load = blocks["load_average_1min"]
            print(f"  the object-aware blocks: object_model none / known / estimated, "
                  f"{object_repeats} alternated triples of {T:g} s, each run followed by its "
                  f"plant alone replaying its torques (joint angles and box pose within "
                  f"{blocks['replay_max_deviation']:.1e} of the run's), CPU, median [min, max],"
                  f" load {load[0]:.1f} -> {load[1]:.1f}:")

            def fmt(r, scale=1.0, digits=3):
                return (f"{scale * r['median']:.{digits}f} [{scale * r['min']:.{digits}f}, "
                        f"{scale * r['max']:.{digits}f}]")
            for mode, r in blocks["run_over_replay"].items():
                print(f"    {mode:9s} run / its replay {fmt(r)}  (run "
                      f"{blocks['cpu_s'][mode]['median']:.2f} s, replay "
                      f"{blocks['replay_cpu_s'][mode]['median']:.2f} s)")
            for mode in blocks["ratio_to_none"]:
                print(f"    {mode:9s} run / run none {fmt(blocks['ratio_to_none'][mode])}; "
                      f"blocks' own cost (run/replay over none's) "
                      f"{fmt(blocks['blocks_own'][mode], 100, 1)} % (target <= 10 %); "
                      f"plant's own difference (replay / replay none) "
                      f"{fmt(blocks['plant_difference'][mode], 100, 1)} %")
            print("    their own Python per tick (instrumented estimated run): "
                  + ", ".join(f"{k} {v:.1f} us"
                              for k, v in blocks["python_us_per_tick"].items()))

    numbers = {
        "machine": f"{platform.processor() or platform.machine()}, Python "
                   f"{platform.python_version()}",
        "simulated_s": t_end,
        "plant_time_step_s": scenario.plant.time_step,
        "control_period_s": scenario.control_period,
        "pairs": pairs,
        "ratio_wall": ratio_wall,
        "ratio_cpu": ratio_cpu,
        "ratio_cpu_replay": ratio_replay,
        "full_realtime_factor": t_end / best,
        "sensing_share_of_plant": log_share,
        "per_system_us_per_tick": per_system,
        "control_us_per_robot_per_tick": control,
        "isolated_us": {k: round(v, 1) for k, v in costs.items()},
        "scaling_plant_step": scaling,
        "control_loop_us_per_robot_per_tick": per_robot,
        "extra": extra,
        "sensing_attribution": attribution,
        "callbacks_per_tick": callbacks,
    }
    if out:
        from drake_coop.results.io import atomic_write_text

        atomic_write_text(out, json.dumps(numbers, indent=2))
    return numbers
