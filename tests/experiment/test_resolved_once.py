"""A run is resolved once (:mod:`drake_coop.experiment.plan`): counted while one two-arm
``contact`` Diagram with an estimated object model is built, each pad is read once per arm,
each arm's URDF path resolved at most twice, one ``Arm`` made per robot and each period
checked once (before the plan: 24 pad reads by a regular expression, 42 path resolutions, 4
to 6 ``Arm`` objects, 14 period checks)."""

from collections import Counter

import pytest

import drake_coop.control.params as params
import drake_coop.experiment.plan as plan_module
import drake_coop.scenario.resources as resources
from drake_coop.experiment.diagram import build_experiment
from drake_coop.experiment.plan import plan_run
from drake_coop.experiment.references import reference_trajectory
from drake_coop.plant.arms import Arm
from drake_coop.scenario import load_scenario
from drake_coop.scenario.resources import find_scenario


@pytest.fixture
def counted(monkeypatch):
    """Counters of the pad reads, path resolutions, ``Arm`` objects and period checks."""
    counts = {"pad": Counter(), "path": Counter(), "arm": Counter(), "period": Counter()}

    def wrap(module, name, key, label):
        inner = getattr(module, name)

        def counting(*args, **kwargs):
            counts[key][label(*args, **kwargs)] += 1
            return inner(*args, **kwargs)

        monkeypatch.setattr(module, name, counting)

    wrap(plan_module, "read_pad", "pad", lambda urdf, ee_frame: (str(urdf), ee_frame))
    wrap(resources, "_model_path", "path",
         lambda value, field, robot=None: getattr(robot, "name", None))
    wrap(params, "_validated_period", "period",
         lambda period, time_step=None: (float(period), time_step))
    init = Arm.__init__

    def arm_init(self, robot, task=None):
        counts["arm"][robot.name] += 1
        init(self, robot, task)

    monkeypatch.setattr(Arm, "__init__", arm_init)
    return counts


@pytest.fixture(scope="module")
def scenario():
    s = load_scenario(find_scenario("contact"))
    s.object_model.mode = "estimated"
    return s


def _check(counts, robots):
    names = [r.name for r in robots]
    assert len(counts["pad"]) == len(robots) and set(counts["pad"].values()) == {1}
    assert set(counts["path"]) == set(names)
    assert max(counts["path"].values()) <= 2
    assert counts["arm"] == Counter({name: 1 for name in names})
    assert counts["period"] and set(counts["period"].values()) == {1}


def test_building_a_diagram_from_the_scenario_resolves_each_thing_once(counted, scenario):
    exp = build_experiment(scenario)
    _check(counted, scenario.robots)
    # What was read is what the blocks got: each pad's radius in its stiffness law.
    for resolved in exp.plan.robots:
        assert resolved.stiffness.radius == pytest.approx(0.015, abs=1e-12)
        assert resolved.pad.modulus == pytest.approx(5e6, rel=1e-12)
    # h (against the plant's step) and the mass estimator's 5 h.
    assert sorted(p for p, _ in counted["period"]) == pytest.approx([exp.h, 5 * exp.h])


def test_the_runners_path_resolves_each_thing_once(counted, scenario):
    """:func:`~drake_coop.experiment.simulate.simulate`'s order: the plan, the references
    from it, the Diagram from it."""
    plan = plan_run(scenario, 2.0)
    references = [reference_trajectory(scenario, i, 2.0, plan)
                  for i in range(len(scenario.robots))]
    build_experiment(plan, references=references)
    _check(counted, scenario.robots)


def test_the_counters_see_a_second_resolution(counted, scenario):
    """The counts can fail: a second plan reads every pad and makes every arm again."""
    for _ in range(2):
        for resolved in plan_run(scenario).robots:
            resolved.stiffness
    assert set(counted["pad"].values()) == {2}
    assert set(counted["arm"].values()) == {2}


def _object_block_calls(path) -> list[str]:
    """The names of :mod:`drake_coop.experiment.object_blocks`'s functions called in a file
    (read from its syntax tree, not run)."""
    import ast

    import drake_coop.experiment.object_blocks as object_blocks

    tree = ast.parse(path.read_text())
    imported = {alias.asname or alias.name
                for node in ast.walk(tree)
                if isinstance(node, ast.ImportFrom)
                and node.module == "drake_coop.experiment.object_blocks"
                for alias in node.names}
    functions = {name for name in imported
                 if callable(getattr(object_blocks, name, None))
                 and not isinstance(getattr(object_blocks, name), type)}
    return [node.func.id for node in ast.walk(tree)
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
            and node.func.id in functions]


def test_the_diagram_enters_the_object_blocks_once():
    """``build_experiment`` calls one function of the object blocks, once
    (:func:`~drake_coop.experiment.object_blocks.add_object_layer`): the run's plan enters
    ``object_blocks.py`` once and never comes back (it used to enter three times: the shared
    estimator, each arm's blocks, the shared estimator's inputs)."""
    import drake_coop.experiment.diagram as diagram
    from pathlib import Path

    assert _object_block_calls(Path(diagram.__file__)) == ["add_object_layer"]


def test_the_object_block_call_counter_sees_more_calls(tmp_path):
    """The counter above sees every call of an imported object-blocks function."""
    source = tmp_path / "two_calls.py"
    source.write_text("from drake_coop.experiment.object_blocks import (add_object_blocks,\n"
                      "    couple_samples, ObjectBlocks)\n"
                      "couple_samples(1, 2, 3, 4)\nadd_object_blocks()\nObjectBlocks()\n")
    assert sorted(_object_block_calls(source)) == ["add_object_blocks", "couple_samples"]
