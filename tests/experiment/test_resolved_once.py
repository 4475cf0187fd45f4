"""A run is resolved once (:mod:`drake_coop.experiment.plan`): counted while one two-arm
``contact`` Diagram with an estimated object model is built, each pad is read once per arm,
each arm's URDF path resolved at most twice, one ``Arm`` made per robot and each period
checked once (before the plan: 24 pad reads by a regular expression, 42 path resolutions, 4
to 6 ``Arm`` objects, 14 period checks)."""

from collections import Counter

import numpy as np
import pytest

import drake_coop.control.params as params
import drake_coop.experiment.plan as plan_module
import drake_coop.scenario.resources as resources
from drake_coop.experiment.diagram import build_experiment
from drake_coop.experiment.plan import plan_run
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


def test_building_a_diagram_from_a_plan_alone_resolves_each_thing_once(counted, scenario):
    exp = build_experiment(plan_run(scenario))
    _check(counted, scenario.robots)
    # What was read is what the blocks got: each pad's radius in its stiffness law.
    for resolved in exp.plan.robots:
        assert resolved.stiffness.radius == pytest.approx(0.015, abs=1e-12)
        assert resolved.pad.modulus == pytest.approx(5e6, rel=1e-12)
    # h (against the plant's step) and the mass estimator's 5 h.
    assert sorted(p for p, _ in counted["period"]) == pytest.approx([exp.h, 5 * exp.h])


def test_the_runners_path_resolves_each_thing_once(counted, scenario):
    """:func:`~drake_coop.experiment.simulate.simulate`'s order: the plan, the squeeze check
    on its references, the Diagram from it."""
    from drake_coop.experiment.squeeze_check import check_squeeze_limits

    plan = plan_run(scenario, 2.0)
    check_squeeze_limits(plan)
    build_experiment(plan)
    _check(counted, scenario.robots)


@pytest.fixture
def reference_computations(monkeypatch):
    """Counts :func:`~drake_coop.experiment.references.reference_samples` calls per robot."""
    import drake_coop.experiment.references as references

    counts = Counter()
    inner = references.reference_samples

    def counting(robot):
        counts[robot.name] += 1
        return inner(robot)

    monkeypatch.setattr(references, "reference_samples", counting)
    return counts


def test_the_diagrams_walk_computes_no_reference(reference_computations, scenario):
    """``build_experiment`` only wires: with the plan's references read once before, its
    walk computes none; and the plan computes each robot's once, however often it is read
    (the squeeze check, the Diagram, the couple's samples)."""
    from drake_coop.experiment.squeeze_check import check_squeeze_limits

    plan = plan_run(scenario, 2.0)
    for robot in plan.robots:
        robot.reference
    names = [r.name for r in scenario.robots]
    assert reference_computations == Counter(names)
    check_squeeze_limits(plan)
    exp = build_experiment(plan)
    assert reference_computations == Counter(names)          # nothing more
    for robot, rs in zip(plan.robots, exp.robots):
        source = exp.diagram.GetSubsystemByName(f"{rs.name}_reference")
        assert source.get_output_port().size() == robot.layout.size
    # A second plan computes again (the counter can fail).
    build_experiment(plan_run(scenario, 2.0))
    assert reference_computations == Counter({name: 2 for name in names})


def test_a_plans_given_references_are_wired_and_none_computed(reference_computations,
                                                              scenario):
    """:meth:`~drake_coop.experiment.plan.RunPlan.with_references`: the Diagram follows the
    given trajectories (a constant posture), the scenario's are never computed."""
    from pydrake.trajectories import PiecewisePolynomial

    plan = plan_run(scenario, 2.0)
    given = [PiecewisePolynomial(np.arange(r.layout.size, dtype=float).reshape(-1, 1))
             for r in plan.robots]
    exp = build_experiment(plan.with_references(given))
    assert not reference_computations
    context = exp.diagram.CreateDefaultContext()
    for rs, traj in zip(exp.robots, given):
        port = exp.diagram.GetSubsystemByName(f"{rs.name}_reference").get_output_port()
        np.testing.assert_array_equal(port.Eval(port.get_system().GetMyContextFromRoot(
            context)), traj.value(0.0).ravel())
    with pytest.raises(ValueError, match=r"references\[0\] \(robot1\): 11 rows"):
        plan.with_references([PiecewisePolynomial(np.zeros((3, 1)))] * 2)


def test_a_scenario_is_no_plan():
    """``build_experiment`` takes the plan alone: a scenario is refused in one line."""
    from drake_coop.scenario import default_scenario

    with pytest.raises(TypeError, match="plan: a RunPlan .plan_run.scenario.. is needed, got "
                                        "Scenario"):
        build_experiment(default_scenario())


def test_below_the_plan_no_builder_takes_a_scenario_beside_it():
    """Every function below the planning floor takes its section of the plan, never a
    scenario with it (a mismatch of the two cannot be written)."""
    import inspect

    from drake_coop.experiment import references, simulate, squeeze_check
    from drake_coop.plant import cooperative
    from drake_coop.stability import gains

    for function in (build_experiment, cooperative.build_plant, cooperative.add_arms,
                     references.reference_samples, squeeze_check.torque_limits,
                     squeeze_check.check_squeeze_limits, gains.task_postures,
                     simulate.rest_posture):
        assert "scenario" not in inspect.signature(function).parameters, function.__name__


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
