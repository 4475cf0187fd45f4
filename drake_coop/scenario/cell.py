"""A scenario's ``cell:`` section: how the ``drake-coop serve`` processes of a cell of arms
start and watch each other (:mod:`drake_coop.robot.cell`); re-exported by
:mod:`drake_coop.scenario.schema` with the other sections. Unused by simulated runs."""

from dataclasses import dataclass

__all__ = ["CellSettings"]


@dataclass
class CellSettings:
    """The cell's start and liveness settings for ``drake-coop serve``. Null (the default):
    these defaults.

    Attributes
    ----------
    start_max_offset : float
        ``serve`` refuses to begin when a joint of an arm is farther than this from the
        scenario's start posture (rad; the posture the simulated run starts from).
    start_max_speed : float
        ``serve`` refuses to begin when a joint moves faster than this (rad/s; the status's
        measured velocity, and the positions' change over the wait for the first status).
    start_ramp : float
        The first commands are brought in over this time (s): the command is the hold torque
        at the first reading blended into the controller's torque, linearly over
        ``ceil(start_ramp / control_period)`` ticks (0: none).
    partner_silence_ticks : int
        A ``serve`` that has not heard another arm's ``serve`` for this many of its own ticks
        in a row stops, naming that arm (3 to 1000: in lockstep a partner's heartbeat can
        trail this serve's ticks by 2 however the processes are scheduled).
    """

    start_max_offset: float = 0.05
    start_max_speed: float = 0.05
    start_ramp: float = 0.1
    partner_silence_ticks: int = 3
