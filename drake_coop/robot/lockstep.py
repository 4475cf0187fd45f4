"""Lockstep over the wire: ``drake-coop sim-driver --lockstep`` and ``drake-coop serve
--lockstep`` exchange the same messages as the paced run, but the driver advances its plant
only once every arm's command of the tick has arrived, and ``serve`` ticks only once every
arm's status of the tick has arrived: simulated time on both sides, no wall clock, so the
two-process run over ``tcpq://127.0.0.1`` is the same on any machine, however loaded, as the
one-process loopback run (:func:`~drake_coop.robot.loopback.run_loopback`).

The schedule is the loopback run's, tick ``k`` at ``t_k = k h``:

* the driver (:func:`drive_lockstep`) advances to ``t_k + COMMAND_OFFSET`` (its cycles up to
  ``t_k``: statuses published, the command of tick ``k − 1`` applied), then waits for tick
  ``k``'s command of every arm (each ``serve`` sends one per tick), so that it is applied
  from the driver's first cycle after ``t_k + COMMAND_OFFSET``; before tick 0 it repeats
  its first status (a ``serve`` may start after it);
* ``serve`` (:func:`run_lockstep`) feeds tick ``k`` each arm's status of the driver's newest
  cycle at or before ``t_k`` (:func:`status_time`), found by its ``utime`` in the driver's clock (the first status gives the
  clock's origin), and stamps each command with that status's ``utime`` + 1 µs (the driver's
  own clock: within its expiry whatever the wall clocks say); the cell's heartbeat of the
  tick goes out just before its command (``before_send``: a partner never ticks past a
  command whose heartbeat it has not had).

A side that hears nothing for ``timeout`` wall seconds stops (one line): the other process
has died or stopped. A stop on the serves' stop channel (a serve tripped, or was stopped)
ends the commands: the driver then runs :data:`HOLD_AFTER_STOP` s more without them, as a
real driver does (the last command expires, gravity compensation and damping hold the
arms), and stops (one line), its ground truth showing where the arms came to rest.
"""

from __future__ import annotations

import math
import time

from drake_coop.robot.status import check_panda_status

#: µs of slack when matching a status's ``utime`` to the cycle it should come from.
UTIME_SLACK = 2
#: Simulated seconds the lockstep driver holds the arms without commands after a stop.
HOLD_AFTER_STOP = 2.0


def status_time(spec, t: float) -> float | None:
    """The time of the driver's newest cycle at or before ``t``, a cycle within ``1e-9``
    of the cycle count counting as at ``t`` (its status is what the loopback run's tick at
    ``t`` reads: published :data:`~drake_coop.robot.torque_driver.STATUS_LEAD` ahead of the
    cycle, so latched before the tick's updates however ``t`` and the cycle's time round),
    or None before the first.

    Parameters
    ----------
    spec : DriverSpec
        The arm's driver (its cycle, phase and drift).
    t : float
        The tick's time, s.

    Returns
    -------
    float or None
        ``phase + j c (1 + drift)`` for the largest such ``j``, s.
    """
    cycle = spec.period * (1.0 + spec.clock_drift)
    j = math.floor((t - spec.clock_phase) / cycle + 1e-9)
    return None if j < 0 else spec.clock_phase + j * cycle


class LockstepStatuses:
    """Every status of each arm by its ``utime`` (subscribed at construction: before the
    driver's first status can be missed).

    Parameters
    ----------
    lcm : DrakeLcm
        The LCM connection.
    specs : list of DriverSpec
        The arms' drivers.
    """

    def __init__(self, lcm, specs):
        self._specs = list(specs)
        self.origin: list[int | None] = [None] * len(self._specs)
        self._by_utime: list[dict[int, bytes]] = [{} for _ in self._specs]
        for i, spec in enumerate(self._specs):
            lcm.Subscribe(spec.status_channel, lambda data, i=i: self._handle(i, data))

    def _handle(self, i: int, data: bytes) -> None:
        if len(data) < 16:
            return
        utime = int.from_bytes(bytes(data[8:16]), "big", signed=True)
        if self.origin[i] is None:     # the driver's first status: its cycle at clock_phase
            self.origin[i] = utime - int(round(self._specs[i].clock_phase * 1e6))
        self._by_utime[i][utime] = bytes(data)

    def expected_utime(self, i: int, t: float) -> int:
        """Arm ``i``'s status ``utime`` of its cycle at ``t`` (s).

        Parameters
        ----------
        i : int
            The arm.
        t : float
            The cycle's time, s.

        Returns
        -------
        int
            µs in the driver's clock.
        """
        return self.origin[i] + int(round(t * 1e6))

    def take(self, i: int, t: float):
        """The bytes and ``utime`` of arm ``i``'s status of its cycle at ``t``, or None if not
        arrived yet (older ones are forgotten).

        Parameters
        ----------
        i : int
            The arm.
        t : float
            The cycle's time, s.

        Returns
        -------
        tuple of (bytes, int) or None
            The status and its ``utime``.
        """
        if self.origin[i] is None:
            return None
        want = self.expected_utime(i, t)
        found = next((u for u in self._by_utime[i] if abs(u - want) <= UTIME_SLACK), None)
        if found is None:
            return None
        data = self._by_utime[i][found]
        for u in [u for u in self._by_utime[i] if u < found - UTIME_SLACK]:
            del self._by_utime[i][u]
        return data, found


def wait_for(lcm, ready, timeout: float, late, poll=None) -> str:
    """Pump ``lcm`` until ``ready()`` holds: the one wait of both lockstep sides.

    Parameters
    ----------
    lcm : DrakeLcm
        The LCM connection (handled in slices of 10 ms).
    ready : Callable[[], bool]
        What is awaited; asked first, and again after every slice.
    timeout : float
        The longest wall-clock wait, s.
    late : Callable[[], str]
        The one line returned when ``timeout`` passes first.
    poll : Callable[[], str] or None
        Called before every slice: a non-empty string stops the wait (returned).

    Returns
    -------
    str
        ``''`` once ready, else why not.
    """
    deadline = time.perf_counter() + timeout
    while not ready():
        reason = poll() if poll is not None else ""
        if reason:
            return reason
        if time.perf_counter() > deadline:
            return late()
        lcm.HandleSubscriptions(10)
    return ""


def run_lockstep(loop, lcm, statuses: LockstepStatuses, k_end: int, record, after_tick=None,
                 stop=None, timeout: float = 10.0, before_send=None) -> str:
    """Tick ``loop`` (a started :class:`~drake_coop.robot.serve_loop.ServeLoop`) from
    ``k = 0`` to ``k_end`` in lockstep with the driver (see the module).

    Parameters
    ----------
    loop : ServeLoop
        The controller (started: its first readings from the driver's first statuses).
    lcm : DrakeLcm
        The LCM connection.
    statuses : LockstepStatuses
        The statuses.
    k_end : int
        The last tick.
    record : PacingRecord
        Receives each tick's computation time.
    after_tick : Callable[[int], str or None] or None
        Called after each tick; a string stops the loop (returned).
    stop : StopListener or None
        Another ``serve``'s stop.
    timeout : float
        The longest wall-clock wait for a status, s.
    before_send : Callable[[], None] or None
        Called in each tick after its updates and watchdog check, before its commands are
        sent (the cell's heartbeat, :meth:`~drake_coop.robot.cell.CellWatch.beat`: on the
        wire ahead of the command the driver waits for).

    Returns
    -------
    str
        Why the loop stopped, or ``''`` at ``k_end``.
    """
    specs = loop.specs
    senders = [arm.command_sender for arm in loop.side.arms]
    for i, sender in enumerate(senders):          # tick 0: the first status's clock
        sender.echo(statuses.origin[i] + int(round(specs[i].clock_phase * 1e6)))

    def stopped() -> str:
        return "" if stop is None or stop.reason is None else f"stop: {stop.reason}"

    for k in range(k_end + 1):
        t_k = k * loop.h
        taken = []
        for i, spec in enumerate(specs):
            t_s = status_time(spec, t_k)
            if t_s is None:
                taken.append(None)
                continue
            got: list = [None]

            def arrived(i=i, t_s=t_s, got=got) -> bool:
                got[0] = statuses.take(i, t_s)
                return got[0] is not None

            reason = wait_for(lcm, arrived, timeout, lambda spec=spec, t_s=t_s: (
                f"no status on {spec.status_channel} for t = {t_s:.4f} s within "
                f"{timeout:g} s (lockstep: is the driver running with --lockstep?)"),
                poll=stopped)
            if reason:
                return reason
            taken.append(got[0])
        lcm.HandleSubscriptions(0)
        if stop is not None and stop.reason is not None:
            return f"stop: {stop.reason}"
        start = time.perf_counter()
        for i, got in enumerate(taken):
            if got is not None:
                loop.feed(i, check_panda_status(got[0], specs[i].n))
                senders[i].echo(got[1])
        loop.step()                    # loop.tick(), with the heartbeat before the command
        loop.check()
        if before_send is not None:
            before_send()
        loop.send()
        end = time.perf_counter()
        record.add(k, end - start, end - start, 0.0, 0.0)
        if after_tick is not None:
            reason = after_tick(k)
            if reason:
                return reason
    return ""


def drive_lockstep(simulator, side, lcm, plan, timeout: float, before_tick=None,
                   offset: float = 1e-4) -> str:
    """Advance the simulated driver in lockstep with the ``serve`` processes (see the
    module): to ``t_k + offset``, then wait for tick ``k``'s command of every arm.

    Parameters
    ----------
    simulator : Simulator
        The driver's Simulator (initialized; no ``LcmInterfaceSystem`` in its Diagram).
    side : DriverSide
        Its arms.
    lcm : DrakeLcm
        The LCM connection (pumped here, between the steps).
    plan : RunPlan
        The run's plan (``h``, ``k_end``).
    timeout : float
        The longest wall-clock wait for a command, s.
    before_tick : Callable[[int], str or None] or None
        Called at ``t_k`` before the tick's updates (the plan's switches; a fault check);
        a string stops the run (returned).
    offset : float
        The commands' offset after the tick (s, :data:`~drake_coop.robot.drivers.
        COMMAND_OFFSET`).

    Returns
    -------
    str
        Why it stopped early, or ``''``.

    Raises
    ------
    ValueError
        A driver whose first cycle comes after ``offset`` (``clock_phase``).
    """
    late = [arm.spec.robot for arm in side.arms if arm.spec.clock_phase >= offset]
    if late:
        raise ValueError(f"--lockstep: the driver's clock_phase of {', '.join(late)} must be "
                         f"< {offset:g} s (its first status before the first command)")
    from drake_coop.robot.serve_loop import STOP_CHANNEL, StopListener

    counts = {arm.spec.command_channel: 0 for arm in side.arms}
    for channel in counts:
        lcm.Subscribe(channel, lambda data, c=channel: counts.__setitem__(c, counts[c] + 1))
    stop = StopListener(lcm, [])            # every serve's stop: the commands end
    repeat = [0.0]

    def repeat_first_status() -> str:
        if time.perf_counter() >= repeat[0]:
            for arm in side.arms:
                if arm.driver.first_status is not None:
                    lcm.Publish(arm.spec.status_channel, arm.driver.first_status)
            repeat[0] = time.perf_counter() + 0.05
        return ""

    def stopped() -> str:
        if stop.reason is None:
            return ""
        # no more commands: the drivers hold the arms
        simulator.AdvanceTo(simulator.get_context().get_time() + HOLD_AFTER_STOP)
        return (f"stop on {STOP_CHANNEL}: {stop.reason} (the arms held by their "
                f"drivers for {HOLD_AFTER_STOP:g} s)")

    for k in range(plan.k_end + 1):
        simulator.AdvanceTo(k * plan.h)
        if before_tick is not None:
            reason = before_tick(k)
            if reason:
                return reason
        simulator.AdvanceTo(k * plan.h + offset)
        # a serve may start late: tick 0 repeats the first status
        reason = wait_for(
            lcm, lambda k=k: all(n > k for n in counts.values()), timeout,
            lambda k=k: (f"no command of tick {k} on "
                         f"{', '.join(c for c, n in counts.items() if n <= k)} within "
                         f"{timeout:g} s (lockstep: is serve running with --lockstep?)"),
            poll=lambda k=k: stopped() or (repeat_first_status() if k == 0 else ""))
        if reason:
            return reason
    simulator.AdvanceTo(max(plan.t_end, simulator.get_context().get_time()))
    return ""
