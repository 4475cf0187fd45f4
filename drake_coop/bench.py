"""Benchmark: the control loop's cost against the plant's, measured as ratios in one process.

``drake-coop bench`` (or ``python bench/benchmark.py``) measures, on this machine:

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
   by :mod:`drake_coop.bench_robots` (``python bench/robots.py``).
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
def _plant_alone(scenario, t_end: float) -> tuple[float, float]:
    """Wall and CPU seconds of the plant alone (held constraints, constant torques)."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    from drake_coop.control.arm_model import ArmModel
    from drake_coop.experiment.references import reference_samples
    from drake_coop.plant.cooperative import build_plant, initialize_plant_context

    b = DiagramBuilder()
    coop = build_plant(b, scenario)
    q0 = [reference_samples(scenario, i, 0.0)[1][0, :h.arm.kinematics.n]
          for i, h in enumerate(coop.arms)]
    for i, h in enumerate(coop.arms):
        src = b.AddSystem(ConstantVectorSource(ArmModel(h.arm).g(q0[i])))
        b.Connect(src.get_output_port(), coop.plant.get_actuation_input_port(h.instance))
    diagram = b.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    pc = coop.plant.GetMyMutableContextFromRoot(ctx)
    initialize_plant_context(coop, pc, q0, scenario.task.circle_top_z - scenario.task.lift_height)
    coop.set_held(pc, True)
    sim.Initialize()
    wall, cpu = time.perf_counter(), time.process_time()
    sim.AdvanceTo(t_end)
    return time.perf_counter() - wall, time.process_time() - cpu


def _experiment(scenario, t_end: float) -> tuple[float, float]:
    """Wall and CPU seconds of the simulation loop of :func:`~drake_coop.experiment.simulate.simulate`."""
    from drake_coop.experiment.simulate import simulate

    start: list[float] = []
    result = simulate(scenario, t_end=t_end,
                      on_start=lambda exp, sim: start.append(time.process_time()))
    cpu = time.process_time() - start[0]    # the loop and the logs' collection
    if not result.ok:
        raise RuntimeError(f"benchmark run failed: {result.meta['message']}")
    return result.wall_time, cpu


# ----------------------------------------------------------------------- per-system timing
_TIMED = {
    "velocity observer (15)-(16)": ("drake_coop.control.observers", "VelocityObserver",
                                    ("_calc_signals", "_calc_qdot_hat", "_calc_qdot_o",
                                     "_update_observer")),
    "force observer (22)": ("drake_coop.control.observers", "ForceObserver",
                            ("_calc_estimate", "_calc_lambda_hat", "_update_integral")),
    "controller (13)": ("drake_coop.control.controller", "Controller",
                        ("_calc_terms", "_calc_tau", "_calc_qddot_r_hat", "_update_latch")),
    "force sensor (ground truth)": ("drake_coop.plant.wrist", "ForceSensor",
                                    ("_calc_force_cache", "_calc_force", "_calc_lambda",
                                     "_update_step")),
    "F/T sensor model": ("drake_coop.sensing.force_sensor", "FTSensor", ("_update_reading",)),
    "wrist kinematics (all arms)": ("drake_coop.plant.wrist", "WristKinematics",
                                    ("_calc_signals",)),
    "wrist dynamics (all arms)": ("drake_coop.plant.wrist", "WristDynamics",
                                  ("_calc_signals",)),
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


def _tick_costs(scenario) -> dict[str, float]:
    """Microseconds per tick of each system's equations on held samples of robot 1.

    Two postures alternate from call to call, as ``q`` changes from tick to tick (the model
    keeps its kinematics while ``q`` is unchanged). The last entry is one whole tick of the
    robot: (15)/(8), (22), (13) and (16) at the same sample.
    """
    from drake_coop.control.arm_model import ArmModel
    from drake_coop.control.finger import FingerLaw
    from drake_coop.experiment.references import reference_samples
    from drake_coop.plant.arms import Arm

    robot = scenario.robots[0]
    law = FingerLaw(ArmModel(Arm(robot, scenario.task)), robot.gains)
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
                  t_extra: float | None = None) -> dict:
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
    """
    from drake_coop.experiment.plan import num_ticks_until
    from drake_coop.scenario.loading import default_scenario, load_scenario
    from drake_coop.scenario.timing import aligned_periods

    scenario = default_scenario()
    h, _ = aligned_periods(scenario.control_period, scenario.plant.time_step)
    ticks = num_ticks_until(t_end, h)
    line = "-" * 78

    # 1. ratio, alternated in this process
    pairs = []
    for _ in range(max(1, repeats)):
        full = _experiment(scenario, t_end)
        plant = _plant_alone(scenario, t_end)
        pairs.append({"full_wall_s": full[0], "full_cpu_s": full[1], "plant_wall_s": plant[0],
                      "plant_cpu_s": plant[1], "ratio_wall": full[0] / plant[0],
                      "ratio_cpu": full[1] / plant[1]})
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
          f"[{ratio_cpu['min']:.2f}, {ratio_cpu['max']:.2f}]   (target <= 1.3)")
    print(f"  experiment realtime factor x{t_end / best:.2f} (best run)")

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
    print(f"  ground truth + sensor models {sensing_us:.0f} us per tick = "
          f"{100 * log_share:.1f} % of the plant's cost (target <= 10 %)")

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
        extra = {"scenario": extra_scenario, "simulated_s": T, "wall_s": wall, "cpu_s": cpu,
                 "realtime_factor_wall": T / wall, "realtime_factor_cpu": T / cpu,
                 "python_callbacks_share": python_s / timed_cpu}
        print(line)
        print(f"{extra_scenario}: {T:g} s in {wall:.2f} s wall / {cpu:.2f} s CPU "
              f"(realtime x{T / wall:.2f} wall, x{T / cpu:.2f} CPU); the Python callbacks are "
              f"{100 * python_s / timed_cpu:.0f} % of an instrumented run, the rest is the plant "
              f"and the framework")

    numbers = {
        "machine": f"{platform.processor() or platform.machine()}, Python "
                   f"{platform.python_version()}",
        "simulated_s": t_end,
        "plant_time_step_s": scenario.plant.time_step,
        "control_period_s": scenario.control_period,
        "pairs": pairs,
        "ratio_wall": ratio_wall,
        "ratio_cpu": ratio_cpu,
        "full_realtime_factor": t_end / best,
        "sensing_share_of_plant": log_share,
        "per_system_us_per_tick": per_system,
        "control_us_per_robot_per_tick": control,
        "isolated_us": {k: round(v, 1) for k, v in costs.items()},
        "scaling_plant_step": scaling,
        "control_loop_us_per_robot_per_tick": per_robot,
        "extra": extra,
    }
    if out:
        from drake_coop.results.io import atomic_write_text

        atomic_write_text(out, json.dumps(numbers, indent=2))
    return numbers
