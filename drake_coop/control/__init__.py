"""The paper's per-robot law as Drake systems, for any Drake plant.

The public API: :func:`AddCooperativeController` wires one arm's control block into a user's
diagram (see ``docs/api_usage.md``); the systems it holds — :class:`VelocityObserver` (15)-(16),
:class:`ForceObserver` (22), :class:`Controller` (13) and the alternative sources
(:class:`MeasuredVelocity`, :class:`DifferenceVelocity`, :class:`SensedForce`,
:class:`NoForceEstimate`, :class:`MomentumObserver`) — the law at one sample (:class:`FingerLaw`), the controller's arm model
(:class:`ArmModel`), the object-aware blocks (:class:`ObjectModel`, :class:`LoadFeedforward`,
:class:`MassEstimator`, the shared :class:`ObjectStateEstimator`, :class:`ContactStiffness`, :func:`squeeze_for_grasp`,
:func:`load_distribution`, :func:`mass_shares`, the squeeze's couple in the load split:
:func:`squeeze_couple`, :func:`face_distance`), the reference layout (:class:`ReferenceLayout`, :class:`Reference`) and the
gains (:class:`Gains`).

Modules: the parameters (params), the time grid (timing), the model (arm_model; its plant,
arm_plant; its closed forms, arm_closed_form), Property 1 (orthogonal), the reference signal's
layout (reference_layout), the law at one sample (finger), its Drake systems (observers,
controller, sources, momentum), the sources' registry (registry: each velocity and force source declared once,
:data:`SOURCES`; the block, the accepted names and these exports read it) and the wiring
(block).

The library imports only Drake, NumPy and itself. Its names load on first use (PEP 562), so
that ``import drake_coop.control.params`` (the scenario's parameter types) does not load pydrake.
"""

import importlib

from drake_coop.control.registry import SOURCES as _SOURCES

#: Each public name and the module that defines it (the velocity and force sources' systems
#: from their registry, :data:`drake_coop.control.registry.SOURCES`).
_EXPORTS = {
    "AddCooperativeController": "block",
    "ControllerHandles": "block",
    "MakeArmControllerPlant": "block",
    "build_control_block": "block",
    "ArmModel": "arm_model",
    "Controller": "controller",
    "DelayPredictor": "delay",
    "FingerLaw": "finger",
    "Reference": "reference_layout",
    "ReferenceLayout": "reference_layout",
    "FORCE_SOURCES": "params",
    "VELOCITY_SOURCES": "params",
    "Gains": "params",
    "ContactStiffness": "object",
    "LoadFeedforward": "object",
    "MassEstimator": "object",
    "ObjectModel": "object",
    "ObjectStateEstimator": "object",
    "CompressedReference": "object",
    "load_distribution": "object",
    "mass_shares": "object",
    "squeeze_for_grasp": "object",
    "squeeze_couple": "couple",
    "face_distance": "couple",
    "Watchdog": "watchdog",
    "SOURCES": "registry",
    **{source.class_name: source.module for source in _SOURCES},
}

__all__ = [
    "AddCooperativeController",
    "ArmModel",
    "DelayPredictor",
    "ContactStiffness",
    "LoadFeedforward",
    "MassEstimator",
    "ObjectModel",
    "ObjectStateEstimator",
    "CompressedReference",
    "load_distribution",
    "mass_shares",
    "squeeze_for_grasp",
    "squeeze_couple",
    "face_distance",
    "Controller",
    "ControllerHandles",
    "FORCE_SOURCES",
    "FingerLaw",
    "Gains",
    "MakeArmControllerPlant",
    "Reference",
    "ReferenceLayout",
    "VELOCITY_SOURCES",
    "Watchdog",
    "build_control_block",
    "SOURCES",
    *(source.class_name for source in _SOURCES),
]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'drake_coop.control' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"drake_coop.control.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
