"""Parameter studies run each scenario in its own process and return its metrics."""

import pytest

from drake_coop.scenario import ScenarioError
from drake_coop.studies.sweep import sweep
from tests.conftest import short_scenario


def test_sweep_over_the_sampling_time_returns_metrics_in_order():
    studies = []
    for h in (0.003, 0.009):
        s = short_scenario("planes", 0.003)
        s.control_period = h
        studies.append(s)
    results = sweep(studies, t_end=2.0, workers=2)
    assert [r["meta"]["control_period"] for r in results] == pytest.approx([0.003, 0.009])
    for r in results:
        assert r["meta"]["status"] == "ok"
        assert r["metrics"]["robot1"]["lift"]["force_error"]["rms"] >= 0.0
    # Faster sampling observes better (observation errors shrink with h).
    z = [r["metrics"]["robot1"]["all"]["z2"]["max"] for r in results]
    assert z[0] < z[1]


def test_sweep_rejects_a_bad_scenario_before_running():
    s = short_scenario()
    s.control_period = 0.0025         # not a multiple of the 1 ms plant step
    with pytest.raises(ScenarioError, match="integer multiple"):
        sweep([s])
