"""Each arm's driver as the controller side and the simulated driver see it, and its LCM
messages.

:class:`DriverSpec` is a robot's ``driver:`` section resolved (defaults filled in, checked
against the arm and its sources: :func:`driver_specs`); the messages are Drake's
``lcmt_panda_status`` and ``lcmt_panda_command`` (torque mode): :data:`SharedPandaCommand`, the
decoded command shared rather than deep-copied by the subscriber's state
(:func:`shared_message_type`), and :func:`safe_command_message`, the command a caller
publishes itself (the safe command of ``drake-coop serve``). The two sides built on them:
:mod:`drake_coop.robot.drivers`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drake import lcmt_panda_command, lcmt_panda_status
from drake_coop.control import registry
from drake_coop.control.registry import EXTERNAL_INPUTS
from drake_coop.experiment.ticks import time_grid
from drake_coop.scenario.driver import FRANKA_DAMPING, Driver
from drake_coop.scenario.schema import Scenario, ScenarioError
from drake_coop.scenario.validation import driver_channels


def shared_message_type(lcm_type):
    """``lcm_type`` whose decoded messages are shared, not deep-copied, when Drake copies the
    subscriber's state (pydrake deep-copies Python values; a status at 1 kHz costs a deep copy
    of its eight arrays several times per message, most of the split run's time).

    Safe because a decoded message is never modified: its arrays are tuples and nothing here
    writes its fields.

    Parameters
    ----------
    lcm_type : type
        A generated LCM message class.

    Returns
    -------
    type
        Its subclass whose ``__deepcopy__`` returns the message itself.
    """

    class Shared(lcm_type):
        __slots__ = []

        @staticmethod
        def decode(data):
            msg = lcm_type.decode(data)
            msg.__class__ = Shared
            return msg

        def __copy__(self):
            return self

        def __deepcopy__(self, memo):
            return self

    Shared.__name__ = Shared.__qualname__ = f"Shared_{lcm_type.__name__}"
    return Shared


#: The Python-typed command the driver's stamp is read from (shared, see
#: :func:`shared_message_type`).
SharedPandaCommand = shared_message_type(lcmt_panda_command)


@dataclass(frozen=True)
class DriverSpec:
    """One arm's driver, resolved from ``robots[i].driver`` (defaults filled in).

    Attributes
    ----------
    robot : str
        The robot's name.
    kind : str
        The driver's messages (``panda``).
    status_channel, command_channel : str
        The LCM channels.
    n : int
        The arm's joints.
    period : float
        The driver's cycle, s.
    torque_limits : numpy.ndarray or None
        The commanded torque's limits (n,), N·m; None: none given.
    max_status_age : float
        The watchdog's largest status age, s.
    command_timeout : float
        The driver's largest command age, s.
    safe_command : str
        ``zero_torque`` or ``hold``.
    time_base : str
        The driver's clock: ``epoch`` or ``run`` (:class:`~drake_coop.scenario.driver.Driver`).
    gravity : str
        Who adds ``g(q)``: ``robot_adds``, ``driver_subtracts`` or ``none``.
    damping : numpy.ndarray
        The driver's damping gains ``k_d`` (n,), N·m·s/rad.
    clock_phase : float
        The simulated driver's clock phase, s.
    clock_drift : float
        The simulated driver's relative clock-rate error.
    """

    robot: str
    kind: str
    status_channel: str
    command_channel: str
    n: int
    period: float
    torque_limits: np.ndarray | None
    max_status_age: float
    command_timeout: float
    safe_command: str
    time_base: str = "epoch"
    gravity: str = "robot_adds"
    damping: np.ndarray | None = None
    #: The simulated driver's clock: cycles at ``phase + j period (1 + drift)``.
    clock_phase: float = 0.0
    clock_drift: float = 0.0


def driver_specs(scenario: Scenario, joints: list[int]) -> list[DriverSpec]:
    """Each robot's :class:`DriverSpec` (``joints``: each arm's ``n``).

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    joints : list of int
        Each arm's ``n``.

    Raises
    ------
    ScenarioError
        A velocity or force source that reads an input from outside the block a driver
        does not give (:func:`~drake_coop.control.registry.missing_inputs`: the measured
        velocities, an F/T reading), or a ``max_status_age`` shorter than one control
        period, naming the field.
    """
    h = time_grid(scenario)[0]
    specs = []
    for i, (robot, n) in enumerate(zip(scenario.robots, joints)):
        for field, name, signal in registry.missing_inputs(robot):
            kind = "velocity" if field == "velocity_source" else "force"
            usable = [s.name for s in registry.SOURCES if s.kind == kind
                      and not s.external_inputs]
            raise ScenarioError(f"robots[{i}].{field}: {name!r} reads "
                                f"{EXTERNAL_INPUTS[signal]}, which the arm's driver does not "
                                f"give; use {', '.join(usable)}")
        d = robot.driver if robot.driver is not None else Driver()
        if d.max_status_age < h * (1 - 1e-9):
            raise ScenarioError(f"robots[{i}].driver.max_status_age: at least one control "
                                f"period ({h:g} s) is required, got {d.max_status_age:g}")
        if d.num_joints is not None and d.num_joints != n:     # also checked by validate()
            raise ScenarioError(f"robots[{i}].driver.num_joints is {d.num_joints} but the arm "
                                f"has {n} joints")
        limits = d.torque_limits if d.torque_limits is not None else \
            robot.actuators.torque_limits
        status, command = driver_channels(robot)
        specs.append(DriverSpec(
            robot=robot.name, kind=d.kind, status_channel=status, command_channel=command,
            n=n, period=1.0 / d.rate_hz,
            torque_limits=None if limits is None else np.asarray(limits, dtype=float),
            max_status_age=d.max_status_age, command_timeout=d.command_timeout,
            safe_command=d.safe_command, time_base=d.time_base, gravity=d.gravity,
            damping=default_damping(n, d.damping), clock_phase=d.clock_phase,
            clock_drift=d.clock_drift))
    return specs


def default_damping(n: int, damping=None) -> np.ndarray:
    """The driver's damping gains: ``damping`` as given, else drake-franka-driver's
    (:data:`~drake_coop.scenario.driver.FRANKA_DAMPING`) for ``n = 7``, else its smallest
    (2.5 N·m·s/rad) on every joint.

    Parameters
    ----------
    n : int
        The arm's joints.
    damping : list of float or None
        The scenario's ``driver.damping``.

    Returns
    -------
    numpy.ndarray
        ``k_d`` (n,), N·m·s/rad.
    """
    if damping is not None:
        return np.asarray(damping, dtype=float).reshape(n)
    if n == len(FRANKA_DAMPING):
        return np.array(FRANKA_DAMPING, dtype=float)
    return np.full(n, min(FRANKA_DAMPING))


def wire_torque(spec: DriverSpec, tau: np.ndarray, gravity: np.ndarray) -> np.ndarray:
    """What the wire carries for the torque ``tau`` the controller wants on the arm, by the
    driver's gravity convention: ``tau − gravity`` when the robot adds ``g(q)`` itself
    (``robot_adds``), else ``tau`` (the driver subtracts its own, or nobody adds any).

    Parameters
    ----------
    spec : DriverSpec
        The arm's driver.
    tau : numpy.ndarray
        The torque on the arm (n,), N·m, gravity included.
    gravity : numpy.ndarray
        ``g(q)`` from the controller's model at the reading (n,), N·m.

    Returns
    -------
    numpy.ndarray
        The command's torque (n,), N·m.
    """
    tau = np.asarray(tau, dtype=float)
    if spec.gravity == "robot_adds":
        return tau - np.asarray(gravity, dtype=float)
    return tau


def safe_command_message(spec: DriverSpec, tau: np.ndarray, utime: int) -> lcmt_panda_command:
    """A torque-mode ``lcmt_panda_command`` carrying ``tau`` (non-finite entries sent as 0).

    Parameters
    ----------
    spec : DriverSpec
        The arm's driver.
    tau : numpy.ndarray
        The torque (n,), N·m.
    utime : int
        The message's time stamp, µs.
    """
    tau = np.asarray(tau, dtype=float).reshape(spec.n)
    tau = np.where(np.isfinite(tau), tau, 0.0)
    if spec.torque_limits is not None:
        tau = np.clip(tau, -spec.torque_limits, spec.torque_limits)
    return torque_command_message(tau, utime)


def torque_command_message(tau, utime: int) -> lcmt_panda_command:
    """A torque-mode ``lcmt_panda_command`` carrying ``tau`` as it is, stamped ``utime``.

    Parameters
    ----------
    tau : array_like
        The wire's torque (n,), N·m.
    utime : int
        The stamp, µs in the driver's time base.

    Returns
    -------
    lcmt_panda_command
        The message.
    """
    msg = lcmt_panda_command()
    msg.utime = int(utime)
    msg.control_mode_expected = lcmt_panda_status.CONTROL_MODE_TORQUE
    msg.num_joint_position = 0
    msg.joint_position = []
    msg.num_joint_velocity = 0
    msg.joint_velocity = []
    msg.joint_torque = [float(v) for v in tau]
    msg.num_joint_torque = len(msg.joint_torque)
    return msg
