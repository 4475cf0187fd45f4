"""The study store's summary columns for the held object's metrics (contact mode)."""

from __future__ import annotations

from drake_coop.studies.store import check_metric_names, summary_columns


def test_object_counts_and_times_become_columns():
    phase = {"force_error": {"rms": 1.0, "max": 2.0, "unit": "N"},
             "object_position_error": {"rms": 0.002, "max": 0.003, "unit": "m"},
             "slips": {"count": 2, "unit": "events"}, "drops": {"count": 0, "unit": "events"},
             "mass_convergence_time": {"time": 4.5, "unit": "s"}}
    other = {**phase, "slips": {"count": 3, "unit": "events"},
             "mass_convergence_time": {"time": None, "unit": "s"}}     # never converged
    columns = summary_columns({"robot1": {"circle": phase}, "robot2": {"circle": other}},
                              "circle")
    assert columns["robot1.slips.count"] == 2 and columns["robot2.slips.count"] == 3
    assert columns["worst.slips.count"] == 3 and columns["worst.drops.count"] == 0
    assert columns["robot1.mass_convergence_time.time"] == 4.5
    assert "robot2.mass_convergence_time.time" not in columns
    assert columns["worst.object_position_error.rms"] == 0.002
    robots = ["robot1", "robot2"]
    assert check_metric_names(["worst.drops.count", "robot2.slip.max"], robots) is None
    assert "unknown column" in check_metric_names(["worst.drops.rms"], robots)
