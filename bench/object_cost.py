"""What the object-aware blocks add to a run, apart from the plant's own changed work
(:func:`_object_blocks_cost`)."""

from __future__ import annotations

from collections import defaultdict

from bench.callbacks import _timed_callbacks
from bench.runs import _experiment, _plant_replay, _spread


def _object_blocks_cost(scenario, t_end: float, repeats: int,
                        modes: tuple[str, ...] = ("none", "known", "estimated")) -> dict:
    """What the object-aware blocks (``object_model``: ``LoadFeedforward`` and, when
    ``estimated``, ``MassEstimator``) add to a run, apart from the plant's own changed work.

    CPU seconds of the scenario with each ``object_model.mode`` of ``modes`` (``none`` first;
    by default ``none``, ``known`` and ``estimated``), alternated ``repeats`` times in this process, each run followed by the
    plant alone replaying that run's applied torques (:func:`_plant_replay`, its deviation
    from the run's joint angles and box pose reported). The runs differ physically (other
    torques, other contact states), so the plain ratio ``run_X / run_none`` mixes the blocks'
    cost with the plant's. Per repeat:

    * ``ratio_to_none`` = ``run_X / run_none`` (the plain ratio);
    * ``blocks_own`` = ``(run_X / replay_X) / (run_none / replay_none) − 1``: what the blocks
      add to the loop's cost over its own plant;
    * ``plant_difference`` = ``replay_X / replay_none − 1``: the plant's own extra work on
      the object-aware run's trajectory.

    And, from one instrumented run of the last mode, the blocks' own Python time per tick. The
    load average (1 min) is recorded at the start and the end."""
    import copy
    import os

    from drake_coop.experiment.ticks import num_ticks_until, time_grid

    if not modes or modes[0] != "none" or len(modes) < 2:
        raise ValueError(f"modes: 'none' first and at least one object model, got {modes!r}")
    load_start = os.getloadavg()[0]
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
        _experiment(variants[modes[-1]], t_end)
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
            "python_us_per_tick": blocks, "instrumented_mode": modes[-1],
            "simulated_s": t_end, "repeats": repeats,
            "load_average_1min": [load_start, os.getloadavg()[0]]}
