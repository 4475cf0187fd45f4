"""The velocity and force sources a control block can hold, each declared once.

A control block (:func:`~drake_coop.control.block.build_control_block`) holds one velocity
source, one force source and the controller (13). Each source is one entry of
:data:`SOURCES` (in the manner of dm_control's tagged task suites and Drake's typed driver
configs): its name (the value of ``velocity_source`` / ``force_source``), its system (a
:class:`~drake_coop.control.interfaces.VelocitySource` or
:class:`~drake_coop.control.interfaces.ForceSource` of this package), the name of that system
inside the block, its label in the paper's block diagram, the signals it reads and how it is
built from the robot's law. The block's wiring, the names the scenario accepts
(:data:`~drake_coop.control.params.VELOCITY_SOURCES`, :data:`~drake_coop.control.params.FORCE_SOURCES`),
the package's exports and the block diagram's labels are all read from here.

Adding a force source: its system in a module of its own, and one :class:`Source` entry here.

This module imports nothing (the systems load on first use), so that the parameter checks of
:mod:`drake_coop.control.params` read the names without loading pydrake.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Callable

#: The signals inside a control block a source may read, and who provides them: the block's
#: exported inputs ``q`` and ``reference``, the velocity source's outputs, the controller's.
BLOCK_SIGNALS = {
    "q": "block input",
    "reference": "block input",
    "q_hat": "velocity source",
    "qdot_hat": "velocity source",
    "qdot_o": "velocity source",
    "qddot_r_hat": "controller",
    "tau": "controller",
}
#: Inputs a source reads from outside the block: exported under the same name (the plant's
#: ``state`` of the arm, an F/T sensor's ``lambda_sensor``).
EXTERNAL_INPUTS = ("state", "lambda_sensor")

#: The outputs every velocity source / force source has (the interchangeable ports).
KIND_OUTPUTS = {"velocity": ("q_hat", "qdot_hat", "qdot_o"),
                "force": ("lambda_hat", "Delta_F_tilde")}


@dataclass(frozen=True)
class Source:
    """One velocity or force source of a control block.

    Attributes
    ----------
    name : str
        The value of ``velocity_source`` / ``force_source`` that selects it.
    kind : {"velocity", "force"}
        What the source estimates: the joint velocity or the contact force.
    system : str
        ``"<module>.<Class>"`` of its LeafSystem in :mod:`drake_coop.control`.
    suffix : str
        Its name in the block: ``<robot>_<suffix>``.
    label, role : str
        Its box in the paper's block diagram (:mod:`drake_coop.results.block_diagram`): what
        it is, and its equation numbers or role.
    inputs : tuple of str
        Its input ports: signals of the block (:data:`BLOCK_SIGNALS`) or inputs from outside
        (:data:`EXTERNAL_INPUTS`, exported by the block).
    build : callable
        ``build(cls, law, period, options)``: the system from its class, the robot's
        :class:`~drake_coop.control.finger.FingerLaw`, the period ``h`` and the block's
        options (``difference_cutoff_hz``, ``momentum_torque_limits``).
    outputs : tuple of str
        Outputs of its own the block exports besides :data:`KIND_OUTPUTS`.
    """

    name: str
    kind: str
    system: str
    suffix: str
    label: str
    role: str
    inputs: tuple[str, ...]
    build: Callable
    outputs: tuple[str, ...] = ()

    @property
    def class_name(self) -> str:
        """The system's class name."""
        return self.system.rsplit(".", 1)[1]

    @property
    def module(self) -> str:
        """The module of :mod:`drake_coop.control` that defines the system."""
        return self.system.rsplit(".", 1)[0]

    def system_class(self) -> type:
        """The system's class (imports its module).
        """
        return getattr(importlib.import_module(f"drake_coop.control.{self.module}"),
                       self.class_name)

    def make(self, law, period: float, options: dict):
        """The system for one robot's ``law`` at the period ``h``.

        Parameters
        ----------
        law : FingerLaw
            The robot's law (gains and model).
        period : float
            The sampling time ``h`` (s).
        options : dict
            The source's own options (its gains, filters).
        """
        return self.build(self.system_class(), law, period, options)


SOURCES: tuple[Source, ...] = (
    Source("observer", "velocity", "observers.VelocityObserver", "velocity_observer",
           "velocity observer", "(15)–(16)", ("q", "qddot_r_hat"),
           lambda cls, law, h, o: cls(law.n, law.Lambda, law.k_d, h)),
    Source("measured", "velocity", "sources.MeasuredVelocity", "measured_velocity",
           "measured velocity", "baseline", ("state", "q"),
           lambda cls, law, h, o: cls(law.n)),
    Source("difference", "velocity", "sources.DifferenceVelocity", "difference_velocity",
           "backward difference", "of the encoders", ("q",),
           lambda cls, law, h, o: cls(law.n, h, o.get("difference_cutoff_hz"))),
    Source("observer", "force", "observers.ForceObserver", "force_observer",
           "force observer", "(22)", ("q", "q_hat", "qdot_o", "reference"),
           lambda cls, law, h, o: cls(law, h)),
    Source("sensor", "force", "sources.SensedForce", "sensed_force",
           "force feedback", "F/T sensor in (13)", ("lambda_sensor", "reference"),
           lambda cls, law, h, o: cls(h, law.layout)),
    Source("none", "force", "sources.NoForceEstimate", "no_force_estimate",
           "no force estimate", "λ̂ = λ_d", ("reference",),
           lambda cls, law, h, o: cls(law.layout)),
    Source("momentum", "force", "momentum.MomentumObserver", "momentum_observer",
           "momentum observer", "generalized momentum", ("q", "qdot_hat", "tau", "reference"),
           lambda cls, law, h, o: cls(law.model, law.layout, h, law.momentum_gain,
                                      torque_limits=o.get("momentum_torque_limits")),
           outputs=("tau_ext_hat", "O_F_ext_hat")),
)


def names(kind: str) -> tuple[str, ...]:
    """The names of the sources of ``kind``, in their registry order.

    Parameters
    ----------
    kind : str
        ``"velocity"`` or ``"force"``.
    """
    return tuple(s.name for s in SOURCES if s.kind == kind)


def source(kind: str, name: str) -> Source:
    """The source of ``kind`` named ``name``.

    Parameters
    ----------
    kind : str
        ``"velocity"`` or ``"force"``.
    name : str
        The source's name, as a scenario spells it.

    Raises
    ------
    KeyError
        If no source of ``kind`` has that name.
    """
    for s in SOURCES:
        if s.kind == kind and s.name == name:
            return s
    raise KeyError(f"no {kind} source named {name!r}")
