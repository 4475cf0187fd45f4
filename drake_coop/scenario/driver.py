"""A robot's ``driver:`` section of a scenario: its LCM driver, for ``drake-coop serve`` and
``drake-coop sim-driver`` (:mod:`drake_coop.robot`); re-exported by
:mod:`drake_coop.scenario.schema` with the other sections."""

from dataclasses import dataclass
from typing import Optional

__all__ = ["DRIVER_KINDS", "SAFE_COMMANDS", "Driver"]

#: The LCM drivers ``drake-coop serve`` and ``sim-driver`` speak (:class:`Driver`).
DRIVER_KINDS = ("panda",)
#: What a driver is sent when the watchdog trips or the controller stops (:class:`Driver`).
SAFE_COMMANDS = ("zero_torque", "hold")


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
        The (simulated) driver applies zero torque when the newest command is older (s).
    safe_command : str
        What the controller sends when its watchdog trips or it stops: ``zero_torque`` or
        ``hold`` (the controller model's gravity torque at the last good position).
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
    command_timeout: float = 0.05
    safe_command: str = "zero_torque"
    clock_phase: float = 0.0
    clock_drift: float = 0.0
