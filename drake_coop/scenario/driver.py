"""A robot's ``driver:`` section of a scenario: its LCM driver, for ``drake-coop serve`` and
``drake-coop sim-driver`` (:mod:`drake_coop.robot`); re-exported by
:mod:`drake_coop.scenario.schema` with the other sections."""

from dataclasses import dataclass
from typing import Optional

__all__ = ["DRIVER_KINDS", "FRANKA_DAMPING", "GRAVITY_CONVENTIONS", "SAFE_COMMANDS", "TIME_BASES",
           "Driver"]

#: The LCM drivers ``drake-coop serve`` and ``sim-driver`` speak (:class:`Driver`).
DRIVER_KINDS = ("panda",)
#: What a driver is sent when the watchdog trips or the controller stops (:class:`Driver`).
SAFE_COMMANDS = ("zero_torque", "hold")
#: The clock a driver stamps its status with and checks a command's ``utime`` against
#: (:class:`Driver`): ``epoch`` (its wall clock, µs since the Unix epoch) or ``run`` (µs since
#: the run's start, the Diagram's time: what Drake's ``PandaCommandSender`` stamps).
TIME_BASES = ("epoch", "run")
#: Who adds the arm's gravity torque ``g(q)`` to the command on the wire (:class:`Driver`).
GRAVITY_CONVENTIONS = ("robot_adds", "driver_subtracts", "none")
#: drake-franka-driver's damping gains (N·m·s/rad, joints 1–7) of its "gravity compensation
#: and damping" controller, run before the first command and when one expires.
FRANKA_DAMPING = (37.5, 50.0, 37.5, 25.0, 5.0, 3.75, 2.5)


@dataclass
class Driver:
    """The arm's LCM driver, for ``drake-coop serve`` and ``drake-coop sim-driver``
    (:mod:`drake_coop.robot`); unused by simulated runs. Null (the default): a Panda driver
    with the defaults below.

    Attributes
    ----------
    kind : str
        The driver's messages: ``panda`` (``lcmt_panda_status`` / ``lcmt_panda_command``,
        torque mode, as drake-franka-driver speaks them).
    status_channel, command_channel : str
        LCM channels; empty: ``PANDA_STATUS_<name>`` and ``PANDA_COMMAND_<name>``. Every
        channel of a scenario is distinct.
    num_joints : int or None
        The driver's joint count; it must equal the arm's ``n_i``. Null: the arm's.
    rate_hz : float
        The driver's cycle (status published and command applied every ``1/rate_hz`` s; the
        Panda's is 1 kHz); ``control_period`` must be a whole number of cycles.
    torque_limits : list[float] or None
        Per-joint limits of the commanded torque (N·m, > 0), applied by the controller before
        sending (and by the simulated driver); null: ``actuators.torque_limits``, else the
        controller clips to the URDF's effort limits (the simulated driver to none).
    max_status_age : float
        The controller's watchdog trips when the newest status is older than this (s, at
        least one control period).
    command_timeout : float
        The driver's expiry (drake-franka-driver's ``--expire_sec``, default 0.1 s): a
        command whose ``utime`` is more than this from the driver's clock (either way) is
        dropped, and the driver runs its gravity compensation and damping, as before the
        first command.
    safe_command : str
        What the controller sends when its watchdog trips or it stops: ``hold`` (the
        controller model's gravity torque at the last good position; on a robot that adds
        gravity itself, zero on the wire) or ``zero_torque`` (no torque on the arm: it falls;
        refused with ``gravity: robot_adds``, where it would be ``−g(q)`` on the wire).
    time_base : str
        The driver's clock (:data:`TIME_BASES`): ``epoch`` (drake-franka-driver: its wall
        clock, µs since the Unix epoch; ``serve`` stamps each command with it, and the
        simulated driver stamps its status with it and drops a command by it) or ``run``
        (µs since the run's start; only for a driver that says so).
    gravity : str
        Who adds ``g(q)`` (:data:`GRAVITY_CONVENTIONS`): ``robot_adds`` (a Franka through FCI
        with drake-franka-driver's defaults: the robot adds its own ``g(q)``, so the wire
        carries ``τ − g(q)``, ``g`` from the controller's model at the reading),
        ``driver_subtracts`` (drake-franka-driver with ``--remove_gravity_compensation``: the
        wire carries ``τ``, the driver subtracts its own ``g(q)`` and the robot adds its own)
        or ``none`` (the wire carries ``τ``, applied as it is).
    damping : list[float] or None
        The gains ``k_d`` (N·m·s/rad, > 0) of the driver's gravity compensation and damping
        (``τ = g(q) − k_d v`` on the arm) before the arm's first command and after one
        expires; null: drake-franka-driver's (:data:`FRANKA_DAMPING`) for a 7-joint arm, else
        2.5 on every joint (its smallest).
    clock_phase : float
        The simulated driver's clock (``drake-coop sim-driver``, the loopback run): its
        cycles fall at ``clock_phase + j T (1 + clock_drift)``, ``T = 1/rate_hz``; s,
        ``0 <= clock_phase < T``. Two real arms' clocks are not synchronised (up to a cycle
        apart); default 0, the controller's grid.
    clock_drift : float
        The simulated driver's clock-rate error (relative, ``|clock_drift| <= 1e-3``); default 0.
    """

    kind: str = "panda"
    status_channel: str = ""
    command_channel: str = ""
    num_joints: Optional[int] = None
    rate_hz: float = 1000.0
    torque_limits: Optional[list[float]] = None
    max_status_age: float = 0.05
    command_timeout: float = 0.1
    safe_command: str = "hold"
    clock_phase: float = 0.0
    clock_drift: float = 0.0
    time_base: str = "epoch"
    gravity: str = "robot_adds"
    damping: Optional[list[float]] = None
