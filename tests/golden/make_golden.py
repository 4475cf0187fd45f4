"""Regenerate the golden record of the paper's run (deliberately, never to make a test pass).

``python tests/golden/make_golden.py`` simulates the paper's 90 s experiment (``scenarios/
paper.yaml``, every optional field at its default) and writes ``paper_run.json``: the
circle-phase metrics of both robots and every 30th logged sample of the raw signals.
``tests/test_golden.py`` compares a fresh run against it: circle-phase metrics to 1e-6
relative, the sampled logs to 1e-6 of each signal's scale (see that test's docstring).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
STRIDE = 30
SIGNALS = ("t", "q", "q_hat", "lambda_hat", "lambda_meas", "tau")


def golden_record() -> dict:
    from drake_coop.experiment.simulate import simulate
    from drake_coop.results.metrics import compute_metrics
    from drake_coop.scenario import load_scenario

    scenario = load_scenario(HERE.parents[1] / "scenarios" / "paper.yaml")
    result = simulate(scenario)
    assert result.ok, result.meta["message"]
    metrics = compute_metrics(result.logs, result.meta)
    record = {"circle_metrics": {}, "samples": {}, "stride": STRIDE}
    for robot, log in result.logs.items():
        record["circle_metrics"][robot] = metrics[robot]["circle"]
        record["samples"][robot] = {k: np.asarray(log[k])[::STRIDE].tolist() for k in SIGNALS}
    return record


if __name__ == "__main__":
    (HERE / "paper_run.json").write_text(json.dumps(golden_record(), indent=1))
