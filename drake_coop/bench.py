"""Benchmark: realtime factor of the paper's experiment and cost per controller tick.

``drake-coop bench`` (or ``python bench/benchmark.py``) measures, on this machine:

1. the full experiment (both arms, three Python systems each, ``planes`` mode) — wall time
   and realtime factor;
2. the plant alone (same plant and constraints, constant gravity-compensating torques, no
   Python systems) — the floor set by Drake's solver;
3. the cost of one tick of each system of one robot (controller (13), velocity observer
   (15)–(16), force observer (22)), timed on a held-object sample with ``timeit``;
4. the framework overhead per tick: (full − plant alone − systems) / ticks.
"""

from __future__ import annotations

import json
import platform
import time
import timeit

import numpy as np


def _plant_alone(scenario, t_end: float) -> float:
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    from drake_coop.arm_model import ArmModel
    from drake_coop.plant import build_plant, initialize_plant_context
    from drake_coop.references import reference_samples

    b = DiagramBuilder()
    coop = build_plant(b, scenario)
    q0 = [reference_samples(scenario, i)[1][0, 0:3] for i in range(2)]
    for i, h in enumerate(coop.arms):
        src = b.AddSystem(ConstantVectorSource(ArmModel(h.arm).g(q0[i])))
        b.Connect(src.get_output_port(), coop.plant.get_actuation_input_port(h.instance))
    diagram = b.Build()
    sim = Simulator(diagram)
    ctx = sim.get_mutable_context()
    pc = coop.plant.GetMyMutableContextFromRoot(ctx)
    initialize_plant_context(coop, pc, q0, 0.535)
    coop.set_held(pc, True)
    sim.Initialize()
    start = time.perf_counter()
    sim.AdvanceTo(t_end)
    return time.perf_counter() - start


def _tick_costs(scenario) -> dict[str, float]:
    """Microseconds per call of each system's work on one held sample of robot 1."""
    from drake_coop.arm_model import ArmModel
    from drake_coop.arms import Arm
    from drake_coop.finger import FingerLaw, Reference
    from drake_coop.references import reference_samples

    robot = scenario.robots[0]
    law = FingerLaw(ArmModel(Arm(robot)), robot.gains)
    _, r = reference_samples(scenario, 0)
    k = int(np.argmax(r[:, 10] > 0.5)) + 1000
    ref = Reference.unpack(r[k])
    q = ref.q_d + 1e-4
    q_hat, qdot_hat_o = ref.q_d.copy(), ref.qdot_d.copy()
    qdot_hat, qdot_o = law.observer_derivative(q, q_hat, qdot_hat_o)
    n = 2000
    costs = {
        "controller (13)": lambda: law.control(q, q_hat, qdot_hat, qdot_o, ref.lambda_d, 0.1,
                                               ref),
        "force observer (22)": lambda: law.force_estimate(q, q_hat, qdot_o, ref, 0.1),
        "velocity observer (15)-(16)": lambda: (law.observer_derivative(q, q_hat, qdot_hat_o),
                                                law.observer_acceleration(q, q_hat, ref.qddot_d)),
    }
    return {name: 1e6 * min(timeit.repeat(f, number=n, repeat=3)) / n for name, f in costs.items()}


def run_benchmark(t_end: float = 90.0, repeats: int = 1, out: str | None = None) -> dict:
    """Run the benchmark, print a table and return the numbers.

    Parameters
    ----------
    t_end : float
        Simulated seconds of the experiment (90 s = the paper's).
    repeats : int
        Repetitions of the full run; the best is reported.
    out : str, optional
        Also write the numbers as JSON to this file.
    """
    from drake_coop.references import num_ticks_until
    from drake_coop.scenario import aligned_periods, default_scenario
    from drake_coop.simulate import simulate

    scenario = default_scenario()
    h, _ = aligned_periods(scenario.control_period, scenario.plant.time_step)
    walls = []
    for _ in range(max(1, repeats)):
        result = simulate(scenario, t_end=t_end)
        walls.append(result.wall_time)
    full = min(walls)
    plant = _plant_alone(scenario, t_end)
    ticks = num_ticks_until(t_end, h)
    costs = _tick_costs(scenario)
    systems = 2 * sum(costs.values()) * 1e-6 * ticks
    numbers = {
        "machine": f"{platform.processor() or platform.machine()}, Python "
                   f"{platform.python_version()}",
        "simulated_s": t_end,
        "plant_time_step_s": scenario.plant.time_step,
        "control_period_s": scenario.control_period,
        "full_wall_s": full,
        "full_realtime_factor": t_end / full,
        "plant_alone_wall_s": plant,
        "plant_alone_realtime_factor": t_end / plant,
        "per_tick_us": {k: round(v, 1) for k, v in costs.items()},
        "full_per_tick_us": 1e6 * full / ticks,
        "overhead_per_tick_us": 1e6 * max(0.0, full - plant - systems) / ticks,
    }
    print(f"experiment: {t_end:g} s simulated in {full:.2f} s  (realtime x{t_end / full:.2f})")
    print(f"plant alone: {plant:.2f} s  (realtime x{t_end / plant:.2f})")
    for k, v in costs.items():
        print(f"  {k:30s} {v:8.1f} us per tick (one robot)")
    print(f"whole diagram per control tick: {numbers['full_per_tick_us']:.0f} us; "
          f"framework overhead {numbers['overhead_per_tick_us']:.0f} us")
    if out:
        from drake_coop.results.io import atomic_write_text

        atomic_write_text(out, json.dumps(numbers, indent=2))
    return numbers
