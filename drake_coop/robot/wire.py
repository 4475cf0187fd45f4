"""The controller's command as the arm's driver reads it: :class:`WireCommand` turns the
torque the controller wants on the arm into the driver's ``lcmt_panda_command``, once, by the
arm's declared conventions (:class:`~drake_coop.robot.driver_spec.DriverSpec`).

* Gravity: with ``robot_adds`` (a Franka through FCI: the robot adds its own ``g(q)``) the
  wire carries ``τ − g(q)``, ``g`` from the controller's model at the checked reading; with
  ``driver_subtracts`` or ``none``, ``τ`` itself
  (:func:`~drake_coop.robot.driver_spec.wire_torque`).
* Time: ``utime`` in the driver's time base: its wall clock (``epoch``) when ``serve`` runs
  against the wall clock, the driver's own simulated clock in the loopback run (both sides
  share one :class:`~drake_coop.robot.torque_driver.DriverClock`), the stamp of the status
  the tick read (:meth:`WireCommand.echo`) in lockstep, or the Diagram's time (``run``).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem

from drake import lcmt_panda_command
from drake_coop.robot.driver_spec import torque_command_message, wire_torque


class WireCommand(LeafSystem):
    """The command on the wire: ``τ`` (gravity included) and the reading ``q`` in,
    the driver's ``lcmt_panda_command`` out (see the module).

    ``tripped``: the watchdog's code; once it is not 0 the command is the safe one as the
    driver reads it: with ``robot_adds`` zero on the wire (the robot's own gravity
    compensation: the ``hold`` safe command, whatever the last reading was), else ``τ`` (the
    watchdog's safe torque) itself.

    .. pydrake_system::

        name: WireCommand
        input_ports:
        - tau
        - q
        - tripped
        output_ports:
        - lcmt_panda_command

    Parameters
    ----------
    spec : DriverSpec
        The arm's driver (``n``, ``gravity``, ``time_base``).
    gravity : Callable[[numpy.ndarray], numpy.ndarray]
        ``g(q)`` of the controller's model (N·m).
    stamp : Callable[[float], int] or None
        The command's ``utime`` at the Diagram's time ``t`` (µs, the driver's time base);
        None: ``round(t·1e6)`` (``time_base: run``).
    """

    def __init__(self, spec, gravity: Callable, stamp: Callable | None = None):
        super().__init__()
        self._spec, self._g = spec, gravity
        self._stamp = stamp if stamp is not None else (lambda t: int(round(t * 1e6)))
        self._echo: int | None = None
        self._tau = self.DeclareVectorInputPort("tau", spec.n)
        self._q = self.DeclareVectorInputPort("q", spec.n)
        self._tripped = self.DeclareVectorInputPort("tripped", 1)
        self.DeclareAbstractOutputPort(
            "lcmt_panda_command", lambda: AbstractValue.Make(lcmt_panda_command()), self._calc)

    def echo(self, utime: int | None) -> None:
        """Stamp the next commands with ``utime + 1`` (lockstep: the stamp of the status the
        tick read, in the driver's own clock); None: back to ``stamp``.

        Parameters
        ----------
        utime : int or None
            The status's ``utime`` (µs).
        """
        self._echo = None if utime is None else int(utime)

    def utime(self, t: float) -> int:
        """The stamp of a command sent at the Diagram's time ``t`` (s): the echoed status's
        ``utime`` + 1 in lockstep, else ``stamp(t)``.

        Parameters
        ----------
        t : float
            The Diagram's time, s.

        Returns
        -------
        int
            µs in the driver's time base.
        """
        return self._echo + 1 if self._echo is not None else self._stamp(t)

    def wire(self, context: Context) -> np.ndarray:
        """The torque the command carries now (n,), N·m.

        Parameters
        ----------
        context : Context
            This system's context.

        Returns
        -------
        numpy.ndarray
            The wire's torque.
        """
        tau = np.asarray(self._tau.Eval(context), dtype=float)
        if self._spec.gravity == "robot_adds" and self._tripped.Eval(context)[0] != 0.0:
            return np.zeros(self._spec.n)
        gravity = (self._g(np.asarray(self._q.Eval(context), dtype=float))
                   if self._spec.gravity == "robot_adds" else 0.0)
        return wire_torque(self._spec, tau, gravity)

    def _calc(self, context: Context, value: AbstractValue) -> None:
        value.set_value(torque_command_message(self.wire(context),
                                               self.utime(context.get_time())))
