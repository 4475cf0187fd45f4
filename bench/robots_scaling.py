"""Benchmark: cost per control tick against the number of robots ``l``.

``python bench/robots.py [--robots 2 3 4 6] [--t-end 10]`` builds ``l`` identical CRS A255 arms
around one object (:func:`ring_scenario`, the geometry of ``scenarios/three_arms.yaml`` with
the arms ``360°/l`` apart, planes mode) and measures, in one process, the CPU time of the
experiment and of the plant alone (the same plant and constraints, constant torques, no Python
system) for each ``l``. Reported per control tick: the plant alone, the control loop (the
difference: the ``l`` control blocks, sensors, references and loggers, plus whatever the
plant costs more under control than with constant torques) and, from one more run with every
Python callback timed (:func:`bench.harness._timed_callbacks`), the Python systems' own time
per robot. A per-robot cost that stays flat as ``l`` grows is the linear growth the paper's
decentralized scheme promises.
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from drake_coop.scenario.ring import ring_scenario

def robots_scaling(counts: tuple[int, ...] = (2, 3, 4, 6), t_end: float = 10.0,
                   repeats: int = 1) -> list[dict]:
    """CPU microseconds per control tick of the experiment and of the plant alone per ``l``
    (the median of ``repeats`` alternated pairs).

    Returns
    -------
    list of dict
        Per ``l``: ``robots``, ``experiment_us``, ``plant_alone_us``, ``control_loop_us`` and
        ``control_loop_us_per_robot`` (per control tick).
    """
    from collections import defaultdict

    from bench.harness import _experiment, _plant_alone, _timed_callbacks
    from drake_coop.experiment.plan import plan_run

    rows = []
    for l in counts:
        s = ring_scenario(l)
        ticks = plan_run(s, t_end).k_end
        pairs = [(_experiment(s, t_end)[1], _plant_alone(s, t_end)[1])
                 for _ in range(max(1, repeats))]
        full = statistics.median(p[0] for p in pairs)
        plant = statistics.median(p[1] for p in pairs)
        totals: dict = defaultdict(float)
        with _timed_callbacks(totals):
            _experiment(s, t_end)
        python = 1e6 * sum(totals.values()) / ticks
        loop = 1e6 * (full - plant) / ticks
        rows.append({"robots": l, "experiment_us": 1e6 * full / ticks,
                     "plant_alone_us": 1e6 * plant / ticks, "control_loop_us": loop,
                     "control_loop_us_per_robot": loop / l,
                     "python_systems_us_per_robot": python / l})
        r = rows[-1]
        print(f"  l = {l}: experiment {r['experiment_us']:7.0f}, plant alone "
              f"{r['plant_alone_us']:6.0f}, control loop {loop:7.0f} us per tick = "
              f"{loop / l:5.0f} us per robot; Python systems {python / l:5.0f} us per robot",
              flush=True)
    slope, intercept = np.polyfit([r["robots"] for r in rows],
                                  [r["control_loop_us"] for r in rows], 1)
    print(f"  control loop ~ {intercept:.0f} + {slope:.0f} l us per tick (least squares over "
          f"l = {', '.join(str(r['robots']) for r in rows)}; {time.strftime('%Y-%m-%d')})")
    return rows
