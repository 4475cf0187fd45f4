"""Scenario: every number of an experiment, as typed dataclasses loaded from YAML.

``schema`` holds the dataclasses (:class:`Scenario`, :func:`default_scenario`), ``loading``
reads and writes YAML (:func:`load_scenario`, :func:`dump_scenario`), ``validation`` the
ranges and rules (:func:`validate`, :data:`BOUNDS`), ``timing`` the aligned periods and the run
size; ``bounds``, ``safe_yaml``, ``model_check`` and ``resources`` are their helpers. The public
names are re-exported here: ``from drake_coop.scenario import Scenario, load_scenario``.
"""

from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.scenario.schema import (
    ARM_MODELS,
    FORCE_SOURCES,
    OBJECT_MODES,
    VELOCITY_SOURCES,
    Actuators,
    Encoders,
    ForceSensorModel,
    Gains,
    Guards,
    ModelError,
    PlantSettings,
    Robot,
    Scenario,
    ScenarioError,
    Task,
    default_scenario,
    paper_robots,
)
from drake_coop.scenario.timing import (
    MAX_PLANT_STEPS,
    MAX_TICKS,
    aligned_periods,
    check_run_size,
    run_size,
)
from drake_coop.scenario.validation import BOUNDS, LENGTHS, validate

__all__ = [
    "ARM_MODELS", "FORCE_SOURCES", "OBJECT_MODES", "VELOCITY_SOURCES", "Actuators", "Encoders",
    "ForceSensorModel", "Gains", "Guards", "ModelError", "PlantSettings", "Robot", "Scenario",
    "ScenarioError", "Task", "default_scenario", "paper_robots", "MAX_PLANT_STEPS", "MAX_TICKS",
    "aligned_periods", "check_run_size", "run_size", "BOUNDS", "LENGTHS", "validate",
    "dump_scenario", "load_scenario",
]
