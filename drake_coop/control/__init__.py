"""The paper's per-robot law as Drake systems, for any Drake plant.

The public API: :func:`AddCooperativeController` wires one arm's control block into a user's
diagram (see ``docs/api_usage.md``); the systems it holds — :class:`VelocityObserver` (15)-(16),
:class:`ForceObserver` (22), :class:`Controller` (13) and the alternative sources
(:class:`MeasuredVelocity`, :class:`DifferenceVelocity`, :class:`SensedForce`,
:class:`NoForceEstimate`, :class:`MomentumObserver`) — the law at one sample (:class:`FingerLaw`), the controller's arm model
(:class:`ArmModel`), the reference layout (:class:`ReferenceLayout`, :class:`Reference`) and the
gains (:class:`Gains`).

Modules: the model (arm_model), Property 1 (orthogonal), the law at one sample (finger), its Drake
systems (observers, controller, sources) and the wiring (block).
"""

from drake_coop.control.arm_model import ArmModel
from drake_coop.control.block import (
    AddCooperativeController,
    ControllerHandles,
    MakeArmControllerPlant,
    build_control_block,
)
from drake_coop.control.controller import Controller
from drake_coop.control.finger import FingerLaw, Reference, ReferenceLayout
from drake_coop.control.momentum import MomentumObserver
from drake_coop.control.observers import ForceObserver, VelocityObserver
from drake_coop.control.sources import (
    DifferenceVelocity,
    MeasuredVelocity,
    NoForceEstimate,
    SensedForce,
)
from drake_coop.scenario.schema import Gains

__all__ = [
    "AddCooperativeController",
    "ArmModel",
    "Controller",
    "ControllerHandles",
    "DifferenceVelocity",
    "FingerLaw",
    "ForceObserver",
    "Gains",
    "MakeArmControllerPlant",
    "MeasuredVelocity",
    "MomentumObserver",
    "NoForceEstimate",
    "Reference",
    "ReferenceLayout",
    "SensedForce",
    "VelocityObserver",
    "build_control_block",
]
