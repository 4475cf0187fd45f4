"""Pacing figures: the summary against the delay margin, the files, the wall-clock loop."""

import time

import numpy as np
import pytest
from pydrake.lcm import DrakeLcm
from pydrake.systems.analysis import Simulator
from pydrake.systems.primitives import ZeroOrderHold

from drake_coop.robot import pacing
from drake_coop.robot.pacing_plot import clip_limit, plot_pacing
from drake_coop.robot.pacing import (
    PacingRecord,
    StatusArrivals,
    pacing_summary,
    pump_until,
    run_paced,
    write_pacing_csv,
)


def record(lateness_ms, age_ms=0.5, compute_ms=0.4):
    r = PacingRecord(period=0.009, driver_period=0.001)
    for k, late in enumerate(lateness_ms):
        r.add(k, compute_ms * 1e-3, late * 1e-3, age_ms * 1e-3)
    return r


def test_the_margin_is_met_when_age_lateness_and_a_driver_cycle_fit_in_it():
    s = pacing_summary(record([0.3] * 100), margin=0.002)
    assert s["loop_delay_p99_s"] == pytest.approx(0.5e-3 + 0.3e-3 + 1e-3)
    assert s["met_margin"] is True and s["missed_deadlines"] == 0
    assert pacing_summary(record([0.3] * 100), margin=0.0015)["met_margin"] is False
    assert pacing_summary(record([0.3] * 100), margin=None)["met_margin"] is None


def test_a_missed_deadline_fails_the_margin_and_percentiles_are_of_the_ticks():
    late = [0.2] * 98 + [5.0, 12.0]                   # one tick past h = 9 ms
    s = pacing_summary(record(late), margin=0.1)
    assert s["missed_deadlines"] == 1 and s["met_margin"] is False
    assert s["lateness_max_s"] == pytest.approx(0.012)
    # 99th percentile of 100 values, linear interpolation: between the 99th and 100th sorted
    assert s["lateness_p99_s"] == pytest.approx((5.0 + 0.01 * (12.0 - 5.0)) * 1e-3)


def test_csv_and_figure_are_written_whole(tmp_path):
    r = record([0.3, 0.4, 10.0])
    s = pacing_summary(r, 0.002)
    write_pacing_csv(tmp_path / "pacing.csv", r)
    plot_pacing(tmp_path / "pacing.png", r, s)
    rows = np.loadtxt(tmp_path / "pacing.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(rows[:, 3], [0.3e-3, 0.4e-3, 10e-3])
    np.testing.assert_array_equal(rows[:, 5], [0, 0, 1])
    assert (tmp_path / "pacing.png").stat().st_size > 1000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pacing.csv", "pacing.png"]


def test_delay_margin_is_the_last_stable_delay_of_the_map(monkeypatch):
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.stability import grid

    rho = {0.0: 0.9, 0.001: 0.94, 0.002: 0.985, 0.003: 1.02, 0.004: 0.99}
    seen = []

    def fake_rows(yaml_text, points, epsilon):
        d = round(load_scenario(data=yaml_text).robots[0].timing.computation_delay, 6)
        seen.append(d)
        return [{"rho": rho[d]}]

    monkeypatch.setattr(grid, "point_rows", fake_rows)
    assert pacing.delay_margin(load_scenario()) == pytest.approx(0.002)
    # without compensation: stops at the first unstable delay; then the compensated pass
    # (the same fake map: it does not see the horizon), d = 0 taken from the first
    assert seen == [0.0, 0.001, 0.002, 0.003, 0.001, 0.002, 0.003]


def test_pump_until_delivers_messages_and_returns_at_the_deadline():
    lcm = DrakeLcm("memq://")
    arrivals = StatusArrivals(lcm, ["S"])
    lcm.Publish("S", b"x")
    start = time.perf_counter()
    pump_until(lcm, start + 0.02)
    assert time.perf_counter() >= start + 0.02
    assert arrivals.count["S"] == 1 and arrivals.last["S"] >= start
    assert arrivals.age(arrivals.last["S"] + 0.004) == pytest.approx(0.004)


def test_run_paced_ticks_against_the_wall_clock():
    system = ZeroOrderHold(0.009, 1)                    # any Diagram with ticks
    sim = Simulator(system)
    system.get_input_port().FixValue(sim.get_mutable_context(), [1.0])
    sim.Initialize()
    lcm = DrakeLcm("memq://")
    arrivals = StatusArrivals(lcm, ["S"])
    lcm.Publish("S", b"x")
    r = PacingRecord(period=0.009, driver_period=0.001)
    start = time.perf_counter()
    assert run_paced(sim, lcm, arrivals, 0.009, 10, 1e-4, r, lead=0.0) == ""
    assert time.perf_counter() - start >= 10 * 0.009
    a = r.arrays()
    assert list(a["k"]) == list(range(11))
    assert np.all(a["compute_s"] >= 0) and np.all(a["lateness_s"] >= a["compute_s"] - 1e-9)
    assert sim.get_context().get_time() == pytest.approx(10 * 0.009 + 1e-4)
    sim = Simulator(system)
    system.get_input_port().FixValue(sim.get_mutable_context(), [1.0])
    sim.Initialize()
    stop = run_paced(sim, lcm, arrivals, 0.009, 12, 1e-4, PacingRecord(0.009, 0.001),
                     after_tick=lambda k: "tripped" if k == 11 else "", lead=0.0)
    assert stop == "tripped"


def test_the_summary_gives_p50_p99_p99_9_and_max_of_each_figure():
    # 1000 ticks: lateness 0.001..1.000 ms (known percentiles), one of them 181 ms late
    late = list(np.arange(1, 1001) * 1e-3)
    late[500] = 181.0
    s = pacing_summary(record(late), margin=0.002)
    x = np.sort(np.array(late)) * 1e-3
    for q, key in ((50, "p50"), (99, "p99"), (99.9, "p99_9")):
        rank = q / 100 * (x.size - 1)                  # linear interpolation between ranks
        lo = int(np.floor(rank))
        expected = x[lo] + (rank - lo) * (x[lo + 1] - x[lo])
        assert s[f"lateness_{key}_s"] == pytest.approx(expected)
        assert s[f"loop_delay_{key}_s"] == pytest.approx(expected + 0.5e-3 + 1e-3)
    assert s["lateness_max_s"] == pytest.approx(0.181)
    assert s["loop_delay_max_s"] == pytest.approx(0.181 + 1.5e-3)


def test_the_summary_line_gives_the_spread_the_collector_and_why_no_margin():
    c = {"collections": 12, "pauses_over_1ms": 1, "during_ticks": 0, "longest_s": 0.002}
    s = pacing_summary(record([0.3] * 100), margin=None,
                       margin_reason="the loop is unstable with no delay", collector=c)
    line = pacing.summary_line(s)
    assert "loop delay p50/p99/p99.9/max 1.80/1.80/1.80/1.80 ms" in line
    assert "1 collector pauses over 1 ms (12 collections, 0 during ticks)" in line
    assert line.endswith("margin unknown (the loop is unstable with no delay)")
    assert s["collector"] == c and "\n" not in line


def test_one_late_tick_does_not_set_the_figures_axes(tmp_path):
    """A 181 ms tick among 1 ms ones: every axis ends near the millisecond behaviour (or the
    margin), and the late tick is counted as beyond it."""
    late = [1.0 + 0.01 * (k % 7) for k in range(2000)]
    late[1200] = 181.0
    r = record(late, compute_ms=0.4)
    s = pacing_summary(r, 0.002)
    limits = plot_pacing(tmp_path / "pacing.png", r, s)
    assert limits["lateness"]["limit_ms"] < 5.0 and limits["lateness"]["beyond"] == 1
    assert limits["series"]["limit_ms"] < 5.0 and limits["series"]["beyond"] == 1
    assert limits["compute"]["beyond"] == 0
    # the margin's line stays on the axes
    assert limits["compute"]["limit_ms"] >= 2.0
    assert (tmp_path / "pacing.png").stat().st_size > 1000
    assert clip_limit(np.array([1e-3] * 999 + [0.181])) == pytest.approx(
        1.5 * np.percentile([1e-3] * 999 + [0.181], 99.9))


def test_serve_gives_the_margin_or_the_line_why_not(monkeypatch, capsys):
    """What ``serve`` checks its delay against and writes to ``run.json``: the map's margin
    of the served arms, or None and the one line saying why (a loop unstable with no delay:
    once "margin unknown" with no reason)."""
    from drake_coop.robot.cli import serve_margin
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.stability import grid

    monkeypatch.setattr(grid, "point_rows", lambda text, points, eps: [
        {"rho": 2.17, "status": "unstable", "slowest_states": "plant:robot1::joint1_w"}])
    margin, entry, reason = serve_margin(load_scenario(), ["robot1"], None)
    assert margin is None and reason.startswith("the loop is unstable with no delay")
    assert entry["robots"] == ["robot1"] and "\n" not in entry["line"]
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"drake-coop: {entry['line']}"
    s = pacing_summary(record([0.3] * 10), margin, margin_reason=reason)
    assert s["delay_margin_reason"] == reason and pacing.summary_line(s).endswith(f"({reason})")
    assert serve_margin(load_scenario(), ["robot1"], 0.004)[0] == 0.004
