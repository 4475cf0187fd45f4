"""Parameter studies: run many scenarios, each in a fresh worker process, and collect metrics.

Building many Drake diagrams with Python LeafSystems in one process keeps memory alive
(reference cycles between Python systems and their C++ owners), so each run gets its own
process (``max_tasks_per_child=1``); runs go in parallel on ``workers`` cores.

Example
-------
>>> from drake_coop.scenario import default_scenario
>>> from drake_coop.studies.sweep import sweep
>>> studies = []
>>> for h in (0.003, 0.009):
...     s = default_scenario(); s.control_period = h; studies.append(s)
>>> results = sweep(studies, t_end=30.0)          # doctest: +SKIP
>>> results[0]["metrics"]["robot1"]["circle"]["force_error"]["rms"]   # doctest: +SKIP
"""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor

from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.schema import Scenario


def run_one(scenario_yaml: str, t_end: float | None = None, clocks=None,
            scenario: Scenario | None = None) -> dict:
    """Simulate one scenario (given as YAML) and return its metadata and metrics.

    Parameters
    ----------
    scenario_yaml : str
        The scenario, YAML text.
    t_end : float or None
        The run's end, s; None for the task's.
    clocks : sequence of (Clock or None), optional
        Each robot's controller-side clock (passed to
        :func:`~drake_coop.experiment.simulate.simulate`); None: the run's grid.
    scenario : Scenario, optional
        The scenario already loaded and validated from ``scenario_yaml`` (a caller that
        needed it first, e.g. the reference table's worker): used as it is, not loaded
        again; None: loaded from the text.

    Returns
    -------
    dict
        ``scenario_yaml``, ``meta`` and ``metrics``.
    """
    from drake_coop.experiment.simulate import simulate
    from drake_coop.results.metrics import compute_metrics

    if scenario is None:
        scenario = load_scenario(data=scenario_yaml)
    result = simulate(scenario, t_end=t_end, clocks=clocks)
    meta = {k: v for k, v in result.meta.items() if k != "scenario_yaml"}
    return {"scenario_yaml": scenario_yaml, "meta": meta,
            "metrics": compute_metrics(result.logs, result.meta)}


def sweep(scenarios: list[Scenario], *, t_end: float | None = None, workers: int = 2
          ) -> list[dict]:
    """Run ``scenarios`` in worker processes; results in the same order.

    Parameters
    ----------
    scenarios : list of Scenario
        Each is validated before any run starts.
    t_end : float, optional
        Stop every run at this time.
    workers : int
        Parallel processes (the machine has 2 cores).

    Returns
    -------
    list of dict
        Per scenario: ``scenario_yaml``, ``meta`` (status, message, timing) and ``metrics``
        (as in ``metrics.json``).
    """
    texts = [dump_scenario(s) for s in scenarios]
    for text in texts:
        load_scenario(data=text)     # fail fast, with the field named, before any run
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=max(1, workers), mp_context=context,
                             max_tasks_per_child=1) as pool:
        return list(pool.map(run_one, texts, [t_end] * len(texts)))
