"""The delay margin of any arm, without and with delay compensation
(:mod:`drake_coop.stability.margin`): its rule on a scripted map, and the map itself on a
shipped arm (the paper's CRS arms) and on a lab arm (the UR5 of ``two_ur5``, and a UR10 given
the UR5's gains, which has no margin and says why)."""

import math

import pytest

from drake_coop.control.arm_plant import description_packages
from drake_coop.scenario.loading import load_scenario
from drake_coop.scenario.resources import find_scenario
from drake_coop.stability.margin import delay_margins, margin_line

needs_robots = pytest.mark.skipif(
    "example-robot-data" not in description_packages(),
    reason='example-robot-data is not installed (pip install -e ".[robots]")')


def scripted(rho_without, rho_with, seen):
    """A map whose ρ depends on the delay and on whether the horizon is set."""

    def rows(text):
        s = load_scenario(data=text)
        t = s.robots[0].timing
        d = round(t.computation_delay, 6)
        p = t.prediction_horizon
        seen.append((d, None if p is None else round(p, 6)))
        table = rho_without if p is None else rho_with
        return {"rho": table.get(d, 0.5), "status": "stable" if table.get(d, 0.5) < 1
                else "unstable", "slowest_states": "plant:robot1::joint1_w"}
    return rows


def test_the_margin_is_the_last_delay_stable_from_zero_and_compensation_matches_the_delay():
    seen = []
    rho_without = {0.0: 0.9, 0.001: 0.95, 0.002: 0.99, 0.003: 1.01, 0.004: 0.98}
    m = delay_margins(load_scenario(), rows=scripted(rho_without, {}, seen))
    assert m.without.margin_s == pytest.approx(0.002) and not m.without.at_least
    # stable up to h = 9 ms with the horizon matched: at least h
    assert m.with_compensation.margin_s == pytest.approx(0.009)
    assert m.with_compensation.at_least and m.with_compensation.horizon == "matched"
    # p = d at each d > 0 (unset at 0: the same loop as without, computed once)
    compensated = [x for x in seen if x[1] is not None]
    assert compensated == [(round(k * 0.001, 6), round(k * 0.001, 6)) for k in range(1, 10)]
    assert seen.count((0.0, None)) == 1
    assert m.as_configured == "without" and m.configured is m.without
    line = margin_line(m)
    assert "2 ms (rho 0.99 there, 1.01 one plant step more) without compensation" in line
    assert ">= 9 ms" in line and "\n" not in line


def test_a_loop_unstable_without_delay_has_no_margin_and_one_line_saying_why():
    seen = []
    m = delay_margins(load_scenario(), rows=scripted({0.0: 2.17}, {0.0: 2.17}, seen))
    assert m.without.margin_s is None and m.with_compensation.margin_s is None
    assert "unstable with no delay" in m.without.reason and "drake-coop gains" in m.without.reason
    line = margin_line(m)
    assert line.count("unstable") == 1 and "\n" not in line
    assert m.as_dict()["without"]["margin_s"] is None


def test_the_scenarios_own_horizon_is_the_compensated_margins_and_the_configured_one():
    s = load_scenario()
    for r in s.robots:
        r.timing.prediction_horizon = 0.003
    seen = []
    m = delay_margins(s, rows=scripted({0.0: 1.2}, {0.0: 0.9, 0.005: 1.1}, seen))
    assert m.as_configured == "with" and m.configured is m.with_compensation
    assert m.with_compensation.horizon == "0.003 s"
    assert m.with_compensation.margin_s == pytest.approx(0.004)
    assert {p for _, p in seen if p is not None} == {0.003}
    assert m.without.margin_s is None


def test_the_delay_goes_on_the_arms_named_and_an_unknown_arm_is_refused():
    seen_delays = []

    def rows(text):
        s = load_scenario(data=text)
        seen_delays.append(tuple(r.timing.computation_delay for r in s.robots))
        return {"rho": 0.9, "status": "stable"}

    delay_margins(load_scenario(), robots=["robot2"], rows=rows)
    assert all(d1 == 0.0 for d1, _ in seen_delays) and max(d2 for _, d2 in seen_delays) > 0
    with pytest.raises(ValueError, match=r"^robots: robot9 not in the scenario"):
        delay_margins(load_scenario(), robots=["robot9"], rows=rows)


@pytest.mark.slow
def test_the_paper_arms_margin_from_the_map():
    """The paper's loop: 2 ms and not 3 ms without compensation (ρ 0.985, then 1.022: the
    values of the delay study), past the period with the horizon matched."""
    m = delay_margins(load_scenario())
    assert m.without.margin_s == pytest.approx(0.002)
    assert m.without.rho[2] == pytest.approx(0.985, abs=2e-3)
    assert m.without.rho[3] == pytest.approx(1.022, abs=2e-3)
    assert m.with_compensation.margin_s == pytest.approx(0.009)
    assert m.with_compensation.at_least


@needs_robots
def test_a_lab_arm_given_another_arms_gains_has_no_margin_and_says_why():
    """A UR10 with the gains derived for the UR5 (``two_ur5``): unstable with no delay, so no
    margin — the line names the map's slowest states on the UR10's wrist."""
    text = find_scenario("two_ur5").read_text().replace("ur5_robot.urdf", "ur10_robot.urdf")
    s = load_scenario(data=text)
    m = delay_margins(s)
    assert m.without.margin_s is None and math.isnan(m.without.rho[0]) is False
    assert m.without.rho[0] > 1.0
    assert "ur10_wrist" in m.without.reason and "drake-coop gains" in m.without.reason


@pytest.mark.slow
@needs_robots
def test_a_lab_arm_with_its_derived_gains_has_a_margin():
    """The UR5 of ``two_ur5`` (gains derived by ``drake-coop gains``): 2 ms without
    compensation, at least the period with it."""
    m = delay_margins(load_scenario(find_scenario("two_ur5")), robots=["robot1"])
    assert m.without.margin_s == pytest.approx(0.002)
    assert m.with_compensation.margin_s is not None
    assert m.with_compensation.margin_s >= m.without.margin_s


def test_a_contact_scenario_is_mapped_on_its_planes_copy_as_gains_checks_it():
    """The map takes no floating box: the margin of a ``contact`` scenario (every lab-arm
    scenario of the guides) is computed on the copy ``drake-coop gains`` checks its gains on
    (``planes``, no object model), not refused."""
    texts = []
    seen = []
    rows = scripted({}, {}, seen)

    def spy(text):
        texts.append(load_scenario(data=text))
        return rows(text)

    s = load_scenario(find_scenario("contact"))
    assert s.plant.object_mode == "contact"
    m = delay_margins(s, rows=spy)
    assert texts and all(t.plant.object_mode == "planes" for t in texts)
    assert all(t.object_model.mode == "none" for t in texts)
    assert m.without.margin_s is not None and m.with_compensation.at_least
    assert s.plant.object_mode == "contact"                # the caller's scenario untouched
