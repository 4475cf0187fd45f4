r"""``serve``'s start: it begins only on arms at rest at their start posture, and brings its
first commands in without a kick.

Before its first tick ``serve`` checks each arm's first reading against the scenario's start
posture (the posture the simulated run starts from,
:func:`~drake_coop.experiment.simulate.rest_posture`) and its motion (the status's measured
joint velocity, and the positions' change over the wait for the first status): a joint
farther than ``cell.start_max_offset`` or faster than ``cell.start_max_speed`` refuses the
start in one line naming the robot, the joint and how far or how fast
(:func:`start_refusal`).

Its first commands are ramped (:class:`StartRamp`): at tick ``k`` of the first ``N =
ceil(cell.start_ramp / h)`` the command is

.. math:: \tau_{cmd}(k) = (1 - k/N)\, \tau_{hold}(q_0) + (k/N)\, \tau(k),

``τ_hold(q_0)`` the controller model's hold (gravity) torque at the first reading and
``τ(k)`` the controller's command (the watchdog's latched torque, already within the
torque limits). A convex blend: every joint's command stays within ``max(|τ_hold|, |τ(k)|)
<= |τ_hold| + τ_lim`` (``τ_lim`` the joint's torque limit), and its change per tick within
``|τ_hold − τ(k)| / N`` plus the controller's own change, scaled by ``k/N``. A tripped
watchdog's safe command is sent as it is, never blended. The observers are fed the
controller's own torque, not the blend: during the ramp they assume the torque the
controller asked for (a residual of this design, over ``start_ramp`` only).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["StartRamp", "arms_refusal", "first_readings", "start_ramp", "start_refusal"]


def start_refusal(robot: str, q, q_start, velocity=None, drift_speed=None,
                  max_offset: float = 0.05, max_speed: float = 0.05) -> str | None:
    """Why ``robot`` must not start from its first reading, in one line, or None.

    Parameters
    ----------
    robot : str
        The robot's name.
    q : array_like
        Its first reading (n,), rad.
    q_start : array_like
        Its start posture (n,), rad.
    velocity : array_like or None
        The status's measured joint velocity (n,), rad/s (None: not known).
    drift_speed : array_like or None
        Each joint's position change over the wait divided by its duration (n,), rad/s
        (None: not known).
    max_offset : float
        The largest distance from the start posture, rad (``cell.start_max_offset``).
    max_speed : float
        The largest joint speed, rad/s (``cell.start_max_speed``).

    Returns
    -------
    str or None
        The refusal (naming the robot and the worst joint, 1-based), or None to start.
    """
    q, q_start = np.asarray(q, dtype=float), np.asarray(q_start, dtype=float)
    for what, speed in (("measured velocity", velocity), ("position change over the wait",
                                                          drift_speed)):
        if speed is None:
            continue
        speed = np.abs(np.asarray(speed, dtype=float))
        speed = np.where(np.isfinite(speed), speed, math.inf)
        j = int(np.argmax(speed))
        if speed[j] > max_speed:
            return (f"{robot} is moving: joint {j + 1} at {speed[j]:.3g} rad/s by its "
                    f"{what} (cell.start_max_speed = {max_speed:g} rad/s); not started")
    offset = np.abs(q - q_start)
    offset = np.where(np.isfinite(offset), offset, math.inf)
    j = int(np.argmax(offset))
    if offset[j] > max_offset:
        return (f"{robot} is {offset[j]:.3g} rad from its start posture at joint {j + 1} "
                f"({q[j]:.4g} rad, start {q_start[j]:.4g} rad; cell.start_max_offset = "
                f"{max_offset:g} rad); not started")
    return None


class StartRamp:
    """The blend of the first commands (see the module's docstring).

    Parameters
    ----------
    hold : list of numpy.ndarray
        Each arm's hold torque at its first reading (n,), N·m.
    ticks : int
        ``N``: the ramp's length in ticks (0: no ramp).
    """

    def __init__(self, hold: list, ticks: int):
        if isinstance(ticks, bool) or not isinstance(ticks, int) or ticks < 0:
            raise ValueError(f"ticks: an integer >= 0 is required, got {ticks!r}")
        self.hold = [np.asarray(h, dtype=float) for h in hold]
        self.ticks = ticks

    def weight(self, k: int) -> float:
        """The controller's share ``min(1, k/N)`` at tick ``k`` (1 without a ramp).

        Parameters
        ----------
        k : int
            The tick (0 first).

        Returns
        -------
        float
            The weight in [0, 1].
        """
        return 1.0 if self.ticks == 0 else min(1.0, max(k, 0) / self.ticks)

    def active(self, k: int) -> bool:
        """Whether tick ``k``'s command is a blend.

        Parameters
        ----------
        k : int
            The tick.

        Returns
        -------
        bool
            True while ``k < N``.
        """
        return k < self.ticks

    def blend(self, i: int, k: int, tau) -> np.ndarray:
        """Arm ``i``'s command at tick ``k`` from the controller's ``tau``.

        Parameters
        ----------
        i : int
            The arm's index.
        k : int
            The tick.
        tau : array_like
            The controller's torque (n,), N·m.

        Returns
        -------
        numpy.ndarray
            The blended command (n,), N·m.
        """
        w = self.weight(k)
        return (1.0 - w) * self.hold[i] + w * np.asarray(tau, dtype=float)


def first_readings(arrivals, specs, first: dict) -> None:
    """Keep each arm's first valid reading and its arrival time, and its newest, while
    ``serve`` waits for the first status (the positions' change over the wait).

    Parameters
    ----------
    arrivals : StatusArrivals
        The statuses (:func:`~drake_coop.robot.serve_loop.status_arrivals`).
    specs : list of DriverSpec
        The arms served.
    first : dict
        Updated: status channel → ``(q, t)`` of the first valid reading, and
        ``channel + "/last"`` → that of the newest (``t``: ``time.perf_counter``, s).
    """
    from drake_coop.control.watchdog import STATUS_OK

    for spec in specs:
        c = spec.status_channel
        if arrivals.count[c] == 0:
            continue
        q, _, fault, _ = arrivals.parsed(c)
        if fault == STATUS_OK:
            first.setdefault(c, (q, arrivals.last[c]))
            first[c + "/last"] = (q, arrivals.last[c])


def arms_refusal(arrivals, specs, index, q0, rest, first: dict, settings) -> str | None:
    """The first served arm that must not start (:func:`start_refusal` on its first reading,
    the status's measured velocity and the change kept by :func:`first_readings` over at
    least 20 ms), else None. An arm whose first status was faulty is left to the watchdog
    (it trips at the first tick).

    Parameters
    ----------
    arrivals : StatusArrivals
        The statuses.
    specs : list of DriverSpec
        The arms served.
    index : list of int
        Their indices among the scenario's robots.
    q0 : list of numpy.ndarray
        Their first readings (n,), rad.
    rest : list of array_like
        Every robot's start posture (n,), rad.
    first : dict
        What :func:`first_readings` kept.
    settings : CellSettings
        The limits (``cell.start_max_offset``, ``cell.start_max_speed``).

    Returns
    -------
    str or None
        The refusal, or None to start.
    """
    from drake import lcmt_panda_status

    faulty = arrivals.faulty
    for i, spec, q in zip(index, specs, q0):
        c = spec.status_channel
        if faulty[c] is not None:
            continue
        try:
            velocity = list(lcmt_panda_status.decode(arrivals.message[c]).joint_velocity)
            velocity = velocity if len(velocity) == spec.n else None
        except Exception:            # not a status: the watchdog trips at the first tick
            velocity = None
        drift = None
        if c in first and c + "/last" in first:
            (qa, ta), (qb, tb) = first[c], first[c + "/last"]
            if tb - ta >= 0.02:
                drift = (np.asarray(qb) - np.asarray(qa)) / (tb - ta)
        refusal = start_refusal(spec.robot, q, rest[i], velocity, drift,
                                settings.start_max_offset, settings.start_max_speed)
        if refusal is not None:
            return refusal
    return None


def start_ramp(loop, q0, ramp_time: float, h: float) -> StartRamp:
    """The first commands' blend over ``ceil(ramp_time / h)`` ticks from each arm's hold
    torque at its first reading.

    Parameters
    ----------
    loop : ServeLoop
        The controller (its arms' ``hold_torque``).
    q0 : list of numpy.ndarray
        Each served arm's first reading (n,), rad.
    ramp_time : float
        ``cell.start_ramp``, s (0: no ramp).
    h : float
        The control period, s.

    Returns
    -------
    StartRamp
        Each arm's blend from its hold torque at ``q0`` over the ramp's ticks.
    """
    ticks = int(math.ceil(ramp_time / h - 1e-9)) if ramp_time > 0 else 0
    return StartRamp([np.asarray(arm.hold_torque(np.asarray(q, dtype=float)), dtype=float)
                      for arm, q in zip(loop.side.arms, q0)], ticks)
