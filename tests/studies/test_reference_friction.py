"""The reference table's friction-held part: its default columns, slips and drops per cell,
the same numbers on a rerun with the same seeds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.studies.reference_engine import run_table
from drake_coop.studies.reference_table import (
    COLUMNS,
    FRICTION_COLUMNS,
    cell_statistics,
    default_columns,
    per_draw,
)


def _record(status: str, slips: tuple[int, int], drops: int, slides: tuple[float, float],
            squeeze: float = 0.2) -> dict:
    """A stored case of a contact run, its numbers given (two robots)."""
    metrics = {}
    for robot, k, slide in zip(("robot1", "robot2"), slips, slides):
        held = {"force_error": {"rms": squeeze, "max": 1.0},
                "estimate_error": {"rms": squeeze / 2, "max": 1.0}}
        metrics[robot] = {
            "circle": held, "lift": held,
            "all": {**held, "slips": {"count": k, "unit": "events"},
                    "drops": {"count": drops, "unit": "events"},
                    "slip": {"rms": slide / 2, "max": slide, "unit": "m"}}}
    return {"status": status, "metrics": metrics}


def test_a_cell_counts_the_slips_and_drops_of_its_draws():
    """Slips summed over both robots and the draws, a draw with a slip or a drop counted
    once, the worst pad's slide per draw; a run stopped by its grasp guard keeps its drop."""
    records = [_record("ok", (0, 0), 0, (1e-4, 2e-4)),
               _record("ok", (2, 1), 0, (5e-3, 3e-4)),
               _record("ok", (0, 1), 0, (1e-4, 2.5e-3)),
               _record("diverged", (1, 0), 1, (3e-2, 1e-3))]
    d = per_draw(records[1])
    assert (d["slips"], d["drops"], d["slide"]) == (3.0, 0.0, 5e-3)
    assert per_draw(records[3])["drops"] == 1.0 and math.isnan(per_draw(records[3])["squeeze"])
    cell = cell_statistics(records)
    assert (cell["slips"], cell["slipped"], cell["dropped"], cell["diverged"]) == (5, 3, 1, 1)
    slides = [2e-4, 5e-3, 2.5e-3, 3e-2]                 # the worst pad of each draw
    assert cell["slide"]["median"][0] == pytest.approx(float(np.median(slides)))
    assert cell["slide"]["p90"][0] == pytest.approx(float(np.quantile(slides, 0.9)))


def test_a_run_without_a_box_held_by_friction_has_no_slip_keys():
    """The ideal constraint's cells keep their keys (its table unchanged)."""
    record = {"status": "ok", "metrics": {"robot1": {
        "circle": {"force_error": {"rms": 0.1, "max": 0.2},
                   "estimate_error": {"rms": 0.05, "max": 0.1}}}}}
    assert set(per_draw(record)) == {"squeeze", "estimate", "squeeze_lift", "diverged"}
    assert set(cell_statistics([record])) == {"n", "diverged", "squeeze", "estimate",
                                              "squeeze_lift"}


def test_a_base_holding_the_box_by_friction_takes_the_friction_columns():
    assert default_columns(load_scenario()) == COLUMNS
    contact = load_scenario("scenarios/contact.yaml")
    assert contact.plant.object_mode == "contact"
    assert default_columns(contact) == FRICTION_COLUMNS
    assert FRICTION_COLUMNS == ("exact", "model_30", "coulomb", "saturation", "id_map_sdp_5s")


@pytest.mark.slow
def test_the_friction_table_gives_the_same_numbers_on_a_rerun_with_the_same_seeds(tmp_path):
    """Two runs of a tiny friction-held table (the paper's arms on contact.yaml with an
    estimated object model, 0.5 s of the circle) into two folders: equal cells, slips and
    drops included."""
    base = load_scenario("scenarios/contact.yaml")
    base.object_model.mode = "estimated"
    path = tmp_path / "base.yaml"
    path.write_text(dump_scenario(base))
    tables = [run_table(tmp_path / name, rows=["momentum"], cols=["coulomb"], draws=1,
                        t_end=5.5, workers=1, base=str(path), quiet=True)
              for name in ("a", "b")]
    a, b = (t["cells"]["momentum"]["coulomb"] for t in tables)
    assert a == b
    assert a["n"] == 1 and a["diverged"] == 0
    assert a["slips"] == 0 and a["dropped"] == 0 and 0 <= a["slide"]["median"][0] < 2e-3
    assert math.isfinite(a["squeeze"]["median"][0])


def _contact_base():
    from drake_coop.scenario.resources import find_scenario

    return load_scenario(find_scenario("contact"))


def test_the_grasp_checks_need_is_the_limit_it_accepts_and_no_less():
    """``required_torques`` against the check it floors: limits at 1.001 × the need pass the
    grasp check; 0.5 % below it on the most loaded joint of either arm, it refuses."""
    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.squeeze_check import check_squeeze_limits, required_torques
    from drake_coop.scenario.schema import ScenarioError
    from drake_coop.studies.reference_table import compress

    base = compress(_contact_base())
    need = required_torques(plan_run(base, 8.0))
    assert set(need) == {r.name for r in base.robots}
    assert all(max(v) > 1.0 for v in need.values())      # the box's weight: a need that can fail
    for robot in base.robots:
        robot.actuators.torque_limits = [1.001 * v for v in need[robot.name]]
    check_squeeze_limits(plan_run(base, 8.0))              # accepted
    for i, robot in enumerate(base.robots):
        tight = load_scenario(data=dump_scenario(base))
        j = int(np.argmax(need[robot.name]))
        limits = list(tight.robots[i].actuators.torque_limits)
        limits[j] = 0.995 * need[robot.name][j]
        tight.robots[i].actuators.torque_limits = limits
        with pytest.raises(ScenarioError, match=robot.name):
            check_squeeze_limits(plan_run(tight, 8.0))
    ideal = compress(load_scenario())
    assert required_torques(plan_run(ideal, 8.0)) == {}   # no grasp check on the constraint


def test_the_saturation_column_on_a_box_held_by_friction_is_the_tightest_the_check_accepts():
    """On a friction base every saturation draw's limits are at least ``NEED_MARGIN`` × the
    grasp check's need (its runs are not refused), and on the joint whose lift peak exceeds
    that floor the limit stays below the peak (the lift still clips); on the ideal constraint
    the need plays no part (the column's limits are the fraction of the peaks alone)."""
    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.squeeze_check import check_squeeze_limits, required_torques
    from drake_coop.studies.reference_table import (
        NEED_MARGIN,
        SATURATION_FRACTION,
        compress,
        expand_table,
    )

    base = _contact_base()
    need = required_torques(plan_run(compress(base), 8.0))
    # peaks as a calibration run gives them: the lift's above the need on one joint
    peaks = {r: {"lift": [1.05 * v for v in need[r]], "other": [0.5 * v for v in need[r]],
                 "need": need[r]} for r in need}
    cases = expand_table(base, ["observer"], ["saturation"], 3, peaks=peaks)
    assert len(cases) == 3
    for case in cases:
        scenario = load_scenario(data=case.scenario_yaml)
        check_squeeze_limits(plan_run(scenario, 8.0))
        for robot in scenario.robots:
            limits = np.asarray(robot.actuators.torque_limits)
            floor = NEED_MARGIN * np.asarray(need[robot.name])
            assert np.all(limits >= floor - 1e-12)
            assert np.all(limits < np.asarray(peaks[robot.name]["lift"]))
    ideal = load_scenario()
    ideal_peaks = {r.name: {"lift": [10.0] * 3, "other": [1.0] * 3} for r in ideal.robots}
    for case in expand_table(ideal, ["observer"], ["saturation"], 2, peaks=ideal_peaks):
        for robot in load_scenario(data=case.scenario_yaml).robots:
            limits = np.asarray(robot.actuators.torque_limits)
            assert np.all((limits >= SATURATION_FRACTION * 10 * 0.95 - 1e-12)
                          & (limits <= SATURATION_FRACTION * 10 * 1.05 + 1e-12))
