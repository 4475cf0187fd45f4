"""The reference table's worker made cheaper without changing a number: a case's scenario
loaded once, the friction squeeze computed once per plan, a stored friction-held case
reproduced."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import drake_coop.scenario.loading as loading
import drake_coop.studies.sweep as sweep
from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.squeeze import friction_squeeze
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.task_path import force_reference
from drake_coop.studies.engines import run_case
from drake_coop.studies.reference_table import compress
from drake_coop.studies.reference_variants import REACH_CACHE, run_variant_case

ROOT = Path(__file__).resolve().parents[2]


def _friction_held():
    """``scenarios/contact.yaml`` with an estimated object model (the friction-held base),
    compressed to the table's short segment."""
    scenario = load_scenario(ROOT / "scenarios" / "contact.yaml")
    scenario.object_model.mode = "estimated"
    return compress(scenario)


def test_a_plans_squeeze_is_the_friction_squeeze_computed_directly_and_a_fresh_array():
    scenario = _friction_held()
    plan = plan_run(scenario, 8.0)
    t = np.arange(plan.k_end + 1) * plan.h
    direct = np.maximum(force_reference(scenario.task, t), friction_squeeze(
        scenario, plan.object, t, exponent=plan.compression_exponent))
    first = plan.squeeze(t)
    assert np.array_equal(first, direct)
    assert direct[t > scenario.task.t_grasp + 1.0].min() > 0.0     # the squeeze is held
    first[:] = -1.0                       # a caller's change does not reach the next one
    assert np.array_equal(plan.squeeze(t), direct)
    assert np.array_equal(plan.squeeze(t[::7]), direct[::7])      # other times: their own


def test_the_worker_loads_a_case_once_and_gives_the_numbers_of_a_fresh_load(monkeypatch):
    text = dump_scenario(_friction_held())
    expected = run_case(text, 0.2)          # loads the text itself
    loads = []
    original = loading.load_scenario

    def counted(*args, **kwargs):
        loads.append(kwargs.get("cache") is REACH_CACHE)
        return original(*args, **kwargs)
    monkeypatch.setattr(loading, "load_scenario", counted)
    monkeypatch.setattr(sweep, "load_scenario", counted)
    record = run_variant_case(text, 0.2, None)
    assert loads == [True]                  # one load, its reach check through the cache
    assert record["status"] == expected["status"] == "ok"
    assert record["metrics"] == expected["metrics"]


@pytest.mark.slow
def test_a_stored_friction_held_case_is_reproduced():
    """The observer row's model-error draw 3 on the paper's arms (8 s), as the table stored
    it before the worker loaded a case once: the same numbers, to the golden runs' 1e-6
    relative (the stored file was written by drake 1.51; another Drake version rounds the
    contact solve differently, so not to the bit)."""
    from bench.reference_table_friction import paper_contact_text
    from drake_coop.studies.reference_engine import run_batch
    from drake_coop.studies.reference_table import expand_table, per_draw

    stored = json.loads((ROOT / "docs" / "results" / "reference_table_friction.json")
                        .read_text())["rerun"]["cases"]
    case = next(c for c in stored if (c["row"], c["column"]) == ("observer", "model_30"))
    cases = expand_table(load_scenario(data=paper_contact_text()), [case["row"]],
                         [case["column"]], case["draw"] + 1)
    mine = next(c for c in cases if c.params["draw"] == case["draw"])
    assert mine.hash == case["hash"]
    (_, record), = run_batch([(mine.hash, mine.scenario_yaml, mine.values["variant"])], 8.0)
    got = per_draw(record)
    assert set(got) == set(case["stored"])
    for key, value in case["stored"].items():
        assert got[key] == pytest.approx(value, rel=1e-6, abs=0.0), key
