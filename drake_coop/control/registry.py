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
#: Inputs a source reads from outside the block, exported under the same name, and what each
#: is (a real arm's driver gives neither: :func:`missing_inputs`).
EXTERNAL_INPUTS = {
    "state": "the arm's measured joint velocities (its state)",
    "lambda_sensor": "a wrist F/T sensor's reading",
}

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
        options (``difference_cutoff_hz``, ``momentum_torque_limits``,
        ``anti_windup_limits``, ``anti_windup_gain``, and ``clock``: the
        :class:`~drake_coop.control.timing.Clock` a source with periodic updates ticks on,
        None for the run's grid).
    outputs : tuple of str
        Outputs of its own the block exports besides :data:`KIND_OUTPUTS`.
    options : tuple of str
        The fields of a robot's scenario entry the source reads (dotted paths inside the
        entry, e.g. ``gains.momentum_gain``); an option that is null by default applies to
        the sources that declare it only.
    checks : callable or None
        ``checks(robot, h)``: refuses the robot's options for this source at the control
        period ``h`` with a ``ValueError`` whose message starts with the field's path inside
        the entry; None when the source has no option to check (:meth:`check`).
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
    options: tuple[str, ...] = ()
    checks: Callable | None = None

    @property
    def external_inputs(self) -> tuple[str, ...]:
        """The inputs it reads from outside the block (:data:`EXTERNAL_INPUTS`)."""
        return tuple(i for i in self.inputs if i in EXTERNAL_INPUTS)

    def check(self, robot, h: float) -> None:
        """Refuse ``robot``'s options for this source at the control period ``h``.

        Parameters
        ----------
        robot : Robot
            The robot's scenario entry (any object with its fields).
        h : float
            The control period, s.

        Raises
        ------
        ValueError
            One line starting with the field's path inside the entry (the scenario's
            validation puts ``robots[i].`` before it) and what is allowed.
        """
        if self.checks is not None:
            self.checks(robot, h)

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


def _check_cutoff(robot, h: float) -> None:
    """``difference_cutoff_hz``: null or below the Nyquist frequency ``1/(2h)``."""
    value = robot.difference_cutoff_hz
    nyquist = 1.0 / (2.0 * h)
    if value is not None and not 0.0 < value < nyquist:
        raise ValueError(f"difference_cutoff_hz must be null or in (0, {nyquist:g}) Hz (below "
                         f"the Nyquist frequency 1/(2h) for h = {h:g} s), got {value!r}")


def _check_momentum_gain(robot, h: float) -> None:
    """``gains.momentum_gain``: at most ``1/h`` (the sampled observer's error shrinks by
    ``1 − h K_O`` per tick)."""
    gain = robot.gains.momentum_gain
    if gain * h > 1.0:
        raise ValueError(f"gains.momentum_gain must be at most 1/h = {1.0 / h:g} 1/s with "
                         f"force_source: {robot.force_source} (the sampled observer's error "
                         f"shrinks by 1 - h K_O per tick), got {gain:g}")


def _check_anti_windup(robot, h: float) -> None:
    """``anti_windup``: null (the paper's (6)) or a scheme of
    :data:`~drake_coop.control.anti_windup.ANTI_WINDUP_SCHEMES`, which needs the arm's
    ``actuators.torque_limits`` (the clipping it reacts to); ``anti_windup_gain``: the
    tracking rate ``K_aw`` in ``(0, 1/h]`` 1/s, with ``back_calculation`` only (required
    there)."""
    allowed = ("conditional", "back_calculation")   # anti_windup.ANTI_WINDUP_SCHEMES
    value = getattr(robot, "anti_windup", None)
    gain = getattr(robot, "anti_windup_gain", None)
    if gain is not None and value != "back_calculation":
        raise ValueError(f"anti_windup_gain: only with anti_windup: back_calculation (got "
                         f"anti_windup: {value}); set it to null")
    if value is None:
        return
    if value not in allowed:
        raise ValueError(f"anti_windup must be null or one of {', '.join(allowed)}, "
                         f"got {value!r}")
    if robot.actuators.torque_limits is None:
        raise ValueError(f"anti_windup: {value} needs actuators.torque_limits (the clipping "
                         "it reacts to); set them or set anti_windup to null")
    if value == "back_calculation" and (
            gain is None or isinstance(gain, bool) or not isinstance(gain, (int, float))
            or not (gain > 0.0 and gain * h <= 1.0 + 1e-12)):
        raise ValueError(f"anti_windup_gain: a tracking rate in (0, 1/h = {1.0 / h:g}] 1/s is "
                         f"required with anti_windup: back_calculation (got {gain!r})")


SOURCES: tuple[Source, ...] = (
    Source("observer", "velocity", "observers.VelocityObserver", "velocity_observer",
           "velocity observer", "(15)–(16)", ("q", "qddot_r_hat"),
           lambda cls, law, h, o: cls(law.n, law.Lambda, law.k_d, h, clock=o.get("clock"))),
    Source("measured", "velocity", "sources.MeasuredVelocity", "measured_velocity",
           "measured velocity", "baseline", ("state", "q"),
           lambda cls, law, h, o: cls(law.n)),
    Source("difference", "velocity", "sources.DifferenceVelocity", "difference_velocity",
           "backward difference", "of the encoders", ("q",),
           lambda cls, law, h, o: cls(law.n, h, o.get("difference_cutoff_hz"),
                                      clock=o.get("clock")),
           options=("difference_cutoff_hz",), checks=_check_cutoff),
    Source("observer", "force", "observers.ForceObserver", "force_observer",
           "force observer", "(22)", ("q", "q_hat", "qdot_o", "reference"),
           lambda cls, law, h, o: cls(law, h, clock=o.get("clock"))),
    Source("sensor", "force", "sources.SensedForce", "sensed_force",
           "force feedback", "F/T sensor in (13)", ("lambda_sensor", "reference"),
           lambda cls, law, h, o: cls(h, law.layout,
                                      anti_windup_limits=o.get("anti_windup_limits"),
                                      clock=o.get("clock"),
                                      anti_windup_gain=o.get("anti_windup_gain"),
                                      model=law.model, force_gain=law.k_F),
           options=("anti_windup", "anti_windup_gain"), checks=_check_anti_windup),
    Source("none", "force", "sources.NoForceEstimate", "no_force_estimate",
           "no force estimate", "λ̂ = λ_d", ("reference",),
           lambda cls, law, h, o: cls(law.layout)),
    Source("momentum", "force", "momentum.MomentumObserver", "momentum_observer",
           "momentum observer", "generalized momentum", ("q", "qdot_hat", "tau", "reference"),
           lambda cls, law, h, o: cls(law.model, law.layout, h, law.momentum_gain,
                                      torque_limits=o.get("momentum_torque_limits"),
                                      anti_windup_limits=o.get("anti_windup_limits"),
                                      clock=o.get("clock"),
                                      anti_windup_gain=o.get("anti_windup_gain"),
                                      force_gain=law.k_F),
           outputs=("tau_ext_hat", "O_F_ext_hat"),
           options=("gains.momentum_gain", "anti_windup", "anti_windup_gain"),
           checks=lambda robot, h: (_check_momentum_gain(robot, h),
                                    _check_anti_windup(robot, h))),
)

#: The scenario field that selects each kind's source in a robot's entry.
SELECTING_FIELD = {"velocity": "velocity_source", "force": "force_source"}


def selected(robot) -> tuple[Source, Source]:
    """The velocity and force sources a robot's entry selects.

    Parameters
    ----------
    robot : Robot
        The robot's scenario entry.

    Returns
    -------
    tuple of Source
        Its velocity source and its force source.

    Raises
    ------
    KeyError
        A name no source of its kind has.
    """
    return tuple(source(kind, getattr(robot, field)) for kind, field in SELECTING_FIELD.items())


def missing_inputs(robot, available=()) -> list[tuple[str, str, str]]:
    """The inputs from outside the block the robot's sources read that are not
    ``available`` (e.g. on a real arm, whose driver gives neither the velocities nor a wrist
    force: ``available=()``).

    Parameters
    ----------
    robot : Robot
        The robot's scenario entry.
    available : iterable of str
        The :data:`EXTERNAL_INPUTS` the path provides.

    Returns
    -------
    list of (str, str, str)
        ``(field, source, input)`` per missing input: the selecting field
        (``velocity_source``), the source's name and the input (``state``); empty when every
        input is there.
    """
    available = set(available)
    return [(SELECTING_FIELD[s.kind], s.name, i) for s in selected(robot)
            for i in s.external_inputs if i not in available]


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
