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
7. optionally (``--object-arms two_pandas``) the object-aware blocks on lab arms with
   ``contact.yaml``'s plant and ``object_model: {mode: estimated}``: each run against its
   plant alone replaying its torques, and the blocks' own cost (:mod:`bench.object_cost`).

What each part measures lives in its own module: the single runs and the ratio
(:mod:`bench.runs`), the ground truth's and sensors' attribution (:mod:`bench.attribution`),
the Python callbacks (:mod:`bench.callbacks`), the object-aware blocks (:mod:`bench.object_cost`),
the isolated tick (:mod:`bench.tick_costs`); this module runs them all (:func:`run_benchmark`)
and imports their names (for ``bench/robots_scaling.py`` and the tests).
"""

from __future__ import annotations

import json
import os
import platform
import sys
import statistics
from collections import defaultdict

from bench.attribution import (  # noqa: F401  (imported from here by the tests and scripts)
    _ATTRIBUTION,
    _CONTACT_ATTRIBUTION,
    _contact_pad_force_log,
    _contact_reaction_ground_truth,
    _ground_truth,
    _hold,
    _offline_ground_truth,
    _sensing_attribution,
)
from bench.callbacks import (  # noqa: F401
    _TIMED,
    _builtin,
    _calls_from_builtins,
    _count_callbacks,
    _timed_callbacks,
)
from bench.object_cost import _object_blocks_cost
from bench.runs import _experiment, _plant_alone, _plant_replay, _spread  # noqa: F401
from bench.tick_costs import _tick_costs


def _cpu_name() -> str:
    from bench.lab_arms_object import _cpu_name as name

    return name()


def _print_object_blocks(blocks: dict, indent: str, target: float) -> None:
    """Print :func:`_object_blocks_cost`'s rows (``target``: the bar on the blocks' own cost)."""
    load = blocks["load_average_1min"]
    modes = list(blocks["run_over_replay"])
    print(f"{indent}the object-aware blocks: object_model {' / '.join(modes)}, "
          f"{blocks['repeats']} alternated repeats of {blocks['simulated_s']:g} s, each run "
          f"followed by its plant alone replaying its torques (joint angles and box pose within "
          f"{blocks['replay_max_deviation']:.1e} of the run's), CPU, median [min, max], "
          f"load {load[0]:.1f} -> {load[1]:.1f}:")

    def fmt(r, scale=1.0, digits=3):
        return (f"{scale * r['median']:.{digits}f} [{scale * r['min']:.{digits}f}, "
                f"{scale * r['max']:.{digits}f}]")
    for mode, r in blocks["run_over_replay"].items():
        print(f"{indent}  {mode:9s} run / its replay {fmt(r)}  (run "
              f"{blocks['cpu_s'][mode]['median']:.2f} s, replay "
              f"{blocks['replay_cpu_s'][mode]['median']:.2f} s)")
    for mode in blocks["ratio_to_none"]:
        print(f"{indent}  {mode:9s} run / run none {fmt(blocks['ratio_to_none'][mode])}; "
              f"blocks' own cost (run/replay over none's) "
              f"{fmt(blocks['blocks_own'][mode], 100, 1)} % (target <= {100 * target:.0f} %); "
              f"plant's own difference (replay / replay none) "
              f"{fmt(blocks['plant_difference'][mode], 100, 1)} %")
    print(f"{indent}  their own Python per tick (instrumented {blocks['instrumented_mode']} run, "
          f"all arms): " + ", ".join(f"{k} {v:.1f} us"
                                     for k, v in blocks["python_us_per_tick"].items()))


# ------------------------------------------------------------------------------ the bench
def run_benchmark(t_end: float = 90.0, repeats: int = 1, out: str | None = None,
                  t_scaling: float = 20.0, extra_scenario: str | None = None,
                  t_extra: float | None = None, t_attribution: float = 10.0,
                  attribution_repeats: int = 5, t_callbacks: float = 16.2,
                  object_repeats: int = 0, lab_object: list[str] | None = None,
                  t_lab: float = 30.0, lab_repeats: int = 3) -> dict:
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
    lab_object : list of str, optional
        Shipped scenarios (e.g. ``two_pandas``; ``contact`` = the paper's arms) run with
        ``contact.yaml``'s plant and ``object_model: {mode: estimated}``
        (:func:`bench.lab_arms_object.contact_scenario`): the whole run against its plant
        replay and the object-aware blocks' own cost (:func:`_object_blocks_cost`, modes
        ``none`` and ``estimated``), ``lab_repeats`` alternated pairs of ``t_lab`` seconds.
    t_lab, lab_repeats : float, int
        Simulated seconds of those runs (30 s: the grasp at 15 s, the lift, 5 s of the
        circle) and their alternated repeats.
    """
    from drake_coop.experiment.ticks import num_ticks_until
    from drake_coop.scenario.loading import default_scenario, load_scenario
    from drake_coop.experiment.ticks import time_grid

    scenario = default_scenario()
    h, _ = time_grid(scenario)
    ticks = num_ticks_until(t_end, h)
    line = "-" * 78
    load_start = os.getloadavg()[0]
    print(f"CPU: {_cpu_name()} ({os.cpu_count()} logical); load average (1 min) {load_start:.2f}")

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
            _print_object_blocks(blocks, "    ", target=0.10)

    # 7. the object-aware blocks on lab arms (bar: <= 20 % over their plant replay)
    lab = {}
    for name in lab_object or ():
        from bench.lab_arms_object import contact_scenario

        s = contact_scenario(name)
        blocks = _object_blocks_cost(s, t_lab, max(1, lab_repeats), modes=("none", "estimated"))
        blocks["scenario"] = name
        blocks["setup"] = ("contact.yaml's plant, object_model: {mode: estimated}, "
                           "control_point: auto (bench.lab_arms_object.contact_scenario)")
        lab[name] = blocks
        print(line)
        print(f"{name} with contact.yaml's plant and object_model estimated (grasp at "
              f"{s.task.t_grasp:g} s, circle from {s.task.t_circle_start:g} s), {t_lab:g} s "
              f"runs:")
        _print_object_blocks(blocks, "  ", target=0.20)
        if out:     # kept as each scenario ends (the whole file is written again at the end)
            from drake_coop.results.io import atomic_write_text

            atomic_write_text(out, json.dumps({"partial": True, "lab_object_blocks": lab},
                                              indent=2))

    from importlib.metadata import version

    numbers = {
        "command": "python " + " ".join(sys.argv),
        "drake": version("drake"),
        "machine_cpu": _cpu_name(),
        "load_average_1min_start": load_start,
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
        "lab_object_blocks": lab or None,
        "load_average_1min_end": os.getloadavg()[0],
    }
    if out:
        from drake_coop.results.io import atomic_write_text

        atomic_write_text(out, json.dumps(numbers, indent=2))
    return numbers
