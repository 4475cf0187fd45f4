"""Scenario: every number of an experiment, as typed dataclasses loaded from YAML.

``schema`` holds the dataclasses (:class:`Scenario`), ``loading`` reads and writes YAML
(:func:`load_scenario`, :func:`dump_scenario`, :func:`default_scenario`: ``paper.yaml``),
``validation`` the ranges and rules (:func:`validate`, :data:`BOUNDS`; the arms' rules in
``arm_check``, the model files in ``model_check``, reachability in ``reach``), ``task_path`` the
task's Cartesian paths (28) and force (29), ``timing`` the aligned periods and the run size;
``bounds``, ``safe_yaml`` and ``resources`` are their helpers. The public
names are re-exported here: ``from drake_coop.scenario import Scenario, load_scenario``.
"""

from drake_coop.scenario.loading import (
    default_scenario,
    dump_scenario,
    load_scenario,
    paper_robots,
)
from drake_coop.scenario.schema import (
    ARM_MODELS,
    OBJECT_MODES,
    Actuators,
    Encoders,
    ForceSensorModel,
    Guards,
    ModelError,
    ObjectModelSettings,
    PlantSettings,
    Robot,
    Scenario,
    ScenarioError,
    Task,
    Tool,
)
from drake_coop.control.params import FORCE_SOURCES, VELOCITY_SOURCES, Gains
from drake_coop.control.timing import aligned_periods
from drake_coop.scenario.validation import BOUNDS, LENGTHS, validate

__all__ = [
    "ARM_MODELS", "FORCE_SOURCES", "OBJECT_MODES", "VELOCITY_SOURCES", "Actuators", "Encoders",
    "ForceSensorModel", "Gains", "Guards", "ModelError", "ObjectModelSettings", "PlantSettings",
    "Robot", "Scenario", "ScenarioError", "Task", "Tool", "default_scenario", "paper_robots",
    "aligned_periods", "BOUNDS", "LENGTHS", "validate",
    "dump_scenario", "load_scenario",
]
