"""Python's garbage collector around ``serve``'s ticks (:mod:`drake_coop.robot.collector`):
the pauses counted from ``gc.callbacks`` on a scripted clock (no timing in the test), the
collector frozen and disabled during the loop and given back as it was."""

import gc

import pytest

from drake_coop.robot.collector import (
    OLDER_EVERY,
    SLACK_NEEDED,
    CollectorPauses,
    ManagedCollector,
)


class Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_pauses_over_the_threshold_are_counted_and_the_longest_kept():
    clock = Clock()
    p = CollectorPauses(clock=clock)
    for duration, ticking in ((0.0002, False), (0.005, True), (0.0011, False)):
        p.ticking = ticking
        p("start", {"generation": 0})
        clock.now += duration
        p("stop", {"generation": 0})
    s = p.summary()
    assert s["collections"] == 3 and s["pauses_over_1ms"] == 2
    assert s["longest_s"] == pytest.approx(0.005) and s["during_ticks"] == 1
    assert s["total_s"] == pytest.approx(0.0063)


def test_the_collector_is_disabled_during_the_loop_and_runs_only_in_the_slack():
    was = gc.isenabled()
    clock = Clock()
    c = ManagedCollector(clock=clock)
    with c:
        assert not gc.isenabled() and c.pauses in gc.callbacks
        assert gc.get_freeze_count() > 0
        assert c.slack(clock.now + SLACK_NEEDED / 2) is None          # too little time
        seen = c.pauses.count
        generations = [c.slack(clock.now + 2 * SLACK_NEEDED) for _ in range(OLDER_EVERY)]
        assert generations.count(1) == 1 and generations[-1] == 1
        assert c.pauses.count == seen + OLDER_EVERY                     # each one timed
    assert gc.isenabled() == was and c.pauses not in gc.callbacks
    assert gc.get_freeze_count() == 0
    s = c.summary()
    assert s["slack_collections"] == OLDER_EVERY and s["slack_generation1"] == 1
