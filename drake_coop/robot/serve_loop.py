"""``drake-coop serve``'s controller side, ticked by its caller (:class:`ServeLoop`), and the
loops that tick it: on the wall-clock grid, or on each status's arrival
(:func:`run_on_arrival`).

One tick of :class:`ServeLoop` is: each arm's newest status (every status of the tick checked
on its bytes first, :func:`status_arrivals`), read once
(:func:`~drake_coop.robot.status.check_panda_status`) and, as the checked reading (the
reading itself when the status is valid, else the last valid one: never a NaN), set on the
C++ ``PassThrough`` that feeds the control blocks (``add_controller_side(...,
status_input="loop")``); ``λ̂(k)`` read, then **one** Simulator step (``AdvanceTo`` to
:math:`t_{k+1}` from ``t_k`` runs the updates at ``t_k``: the controller's latch, the
observers); each arm's watchdog, which has no event in this Diagram, run on floats
(:meth:`~drake_coop.control.watchdog.Watchdog.tick`: the status's stamp and fault, the
reading, ``λ̂(k)``, the latched ``τ(k)``); then each arm's command published at once
(``ForcedPublish`` of its C++ publisher, reading the watchdog's latched ``tau_latched``). The
Python callbacks of a step are the paper's blocks' only.

A stop shared by several ``serve`` processes (``serve --robot NAME``, one per arm): every
``serve`` subscribes to :data:`STOP_CHANNEL`; the one whose watchdog trips publishes
``"<robot>: <reason>"`` there right after sending its safe command, and every other one,
pumping LCM between its ticks, stops before its next tick as if its own watchdog had tripped
(safe command, exit 1, its run folder kept).
"""

from __future__ import annotations

import math
import time

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from drake_coop.control.watchdog import STATUS_NONE, STATUS_OK
from drake_coop.robot.driver_spec import safe_command_message, wire_torque
from drake_coop.robot.drivers import add_controller_side
from drake_coop.robot.status import check_panda_status

#: The LCM channel on which a tripped ``serve`` tells the others to stop.
STOP_CHANNEL = "DRAKE_COOP_STOP"


def status_arrivals(lcm, specs):
    """The arms' status channels subscribed (:class:`~drake_coop.robot.pacing.StatusArrivals`):
    every message's bytes kept as it arrives and checked, all those of a tick at once, when
    the loop looks (:func:`~drake_coop.robot.status.first_bad_panda_status`: the checks of
    :func:`~drake_coop.robot.status.panda_status_ok`), the one a tick takes read
    (:func:`check_panda_status`).

    Parameters
    ----------
    lcm : DrakeLcm
        The LCM connection.
    specs : list of DriverSpec
        The arms' drivers.
    """
    from drake_coop.robot.pacing import StatusArrivals
    from drake_coop.robot.status import first_bad_panda_status

    return StatusArrivals(
        lcm, [s.status_channel for s in specs],
        check_many={s.status_channel: (lambda messages, n=s.n:
                                       first_bad_panda_status(messages, n)) for s in specs},
        parse={s.status_channel: (lambda data, n=s.n: check_panda_status(data, n))
               for s in specs})


class StopListener:
    """The stop messages of the other ``serve`` processes (:data:`STOP_CHANNEL`), ignoring
    this process's own: those carrying its ``session`` (a message without one: those naming
    one of its ``robots``). Another process serving the same arm (a duplicate) has another
    session: its stop is heard. The reason kept is printable text only
    (:func:`~drake_coop.robot.cell.printable`: no control bytes reach a terminal or
    ``run.json``).

    Parameters
    ----------
    lcm : DrakeLcm
        The LCM connection.
    robots : list of str
        This process's arms.
    channel : str
        The stop channel.
    session : str or None
        This process's session id (:class:`~drake_coop.robot.cell.CellWatch`).
    """

    def __init__(self, lcm, robots: list[str], channel: str = STOP_CHANNEL,
                 session: str | None = None):
        self.channel = channel
        self._own = set(robots)
        self._session = session
        self.reason: str | None = None
        lcm.Subscribe(channel, self._handle)

    def _handle(self, data: bytes) -> None:
        from drake_coop.robot.cell import printable

        if self.reason is not None:
            return
        text, session = bytes(data), None
        head, sep, tail = text.rpartition(b"\nsession ")
        if sep and 0 < len(tail) <= 64 and all(c in b"0123456789abcdef" for c in tail):
            text, session = head, tail.decode("ascii")
        if session is not None:
            if session == self._session:
                return
        elif text.split(b":", 1)[0].decode("utf-8", "replace") in self._own:
            return
        self.reason = printable(text)

    @staticmethod
    def publish(lcm, robot: str, reason: str, channel: str = STOP_CHANNEL,
                session: str | None = None) -> None:
        """Publish ``"<robot>: <reason>"`` (and a line ``session <id>``) on the stop channel
        (the other processes stop).

        Parameters
        ----------
        lcm : DrakeLcm
            The LCM connection.
        robot : str
            The robot whose watchdog tripped (or this process's arms, for another stop).
        reason : str
            Its reason.
        channel : str
            The stop channel.
        session : str or None
            This process's session id.
        """
        from drake_coop.robot.cell import printable

        text = f"{printable(robot, 100)}: {printable(reason)}"
        if session is not None:
            text += f"\nsession {session}"
        lcm.Publish(channel, text.encode("utf-8"))


def step_end(k: int, h: float, periods: tuple[float, ...] = ()) -> float:
    """Where :meth:`ServeLoop.step` stops before tick ``k``: ``k h``, unless an event of one of
    ``periods`` (Drake schedules it at ``m P``, offset 0) falls a rounding *before* ``k h``
    (within :func:`~drake_coop.control.timing.tick_of`'s tolerance): then ``k h`` less a tenth
    of that tolerance, so that the event runs in the next step, on tick ``k``'s reading — as
    the simulated diagram's encoders give it there. The context's time still reads as tick
    ``k`` either way.

    Parameters
    ----------
    k : int
        The next tick.
    h : float
        The control period, s.
    periods : tuple of float
        The periods of the Diagram's events off the tick grid's own ``h`` (the mass
        estimator's ``ESTIMATOR_TICKS h``), s.

    Returns
    -------
    float
        The time, s.
    """
    t = k * h
    tolerance = 1e-9 * max(1.0, t)
    for period in periods:
        event = round(t / period) * period      # as Drake computes it: 0 + m P
        if event < t and t - event <= tolerance:
            return t - 0.1 * tolerance
    return t


class ServeLoop:
    """The controller side of ``serve`` for the given arms, ticked by the caller.

    Parameters
    ----------
    plan : RunPlan
        The run's :class:`~drake_coop.experiment.plan.RunPlan` (its scenario, arms and
        references).
    lcm : DrakeLcmInterface
        Where the commands are published.
    specs : list of DriverSpec
        Every arm's :class:`~drake_coop.robot.driver_spec.DriverSpec`.
    robots : list of str, optional
        The arms served (default all; one for ``serve --robot``).
    """

    def __init__(self, plan, lcm, specs, robots: list[str] | None = None):
        builder = DiagramBuilder()
        self.side = add_controller_side(builder, plan, lcm, specs,
                                        status_input="loop", robots=robots)
        self.specs = [arm.spec for arm in self.side.arms]
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()
        self.h = plan.h
        # the events off the grid of h (the mass estimator's period), for step_end
        self._periods: tuple[float, ...] = ()
        if plan.object is not None and plan.object.estimated:
            from drake_coop.control.params import checked_period
            from drake_coop.experiment.object_blocks import ESTIMATOR_TICKS

            self._periods = (checked_period(ESTIMATOR_TICKS * plan.h),)
        self._plan, self._lcm = plan, lcm
        self._fixed_q: list = []
        self._status: list[tuple[float, float, float]] = []   # each arm's [s, f, v]
        self._q: list[list[float]] = []                       # and its last valid reading
        self._wd: list = []
        self._lam: list = []
        self._good: list[np.ndarray] = []
        self._pub: list = []
        self.k = 0
        #: The first commands' blend (:class:`~drake_coop.robot.safe_start.StartRamp`);
        #: None: the controller's command from the first tick.
        self.ramp = None

    def start(self, q0: list[np.ndarray]) -> None:
        """Observers at ``q̂ = q0``, watchdogs untripped with ``q0`` as their last good
        reading, no status yet; ``Initialize``.

        Parameters
        ----------
        q0 : list of numpy.ndarray
            Each arm's first reading (n,), rad.
        """
        from drake_coop.robot.loopback import initialize_sides

        initialize_sides(self._plan, self.context, None, self.side, q0)
        for arm, q in zip(self.side.arms, q0):
            q = np.asarray(q, dtype=float)
            self._good.append(q)
            self._fixed_q.append(arm.position_input.get_input_port().FixValue(
                arm.position_input.GetMyMutableContextFromRoot(self.context), q))
            self._status.append((math.nan, float(STATUS_NONE), 0.0))
            self._q.append(q.tolist())
            block = arm.block
            # The torque the watchdog latches: the control block's, plus the load
            # feedforward's with an object model (what the simulated diagram applies).
            tau = arm.tau if arm.tau is not None else block.tau_output
            self._wd.append((arm.watchdog, arm.watchdog.GetMyMutableContextFromRoot(
                self.context), block.system.GetMyContextFromRoot(self.context),
                block.lambda_hat_output, (tau, tau.get_system().GetMyContextFromRoot(
                    self.context))))
            self._pub.append(arm.command_publisher.GetMyContextFromRoot(self.context))
        self.simulator.Initialize()

    def feed(self, i: int, parsed) -> None:
        """Arm ``i``'s newest status, as :func:`check_panda_status` read it
        (``(q, stamp, fault, value)``); None: no new status (nothing changes, it ages).

        Parameters
        ----------
        i : int
            The arm's index.
        parsed : tuple or None
            ``(q, stamp, fault, value)``, or None.
        """
        if parsed is None:
            return
        q, stamp, fault, value = parsed
        self._status[i] = (stamp, float(fault), value)
        if fault == STATUS_OK:
            self._good[i] = q
            self._q[i] = q.tolist()
            self._fixed_q[i].GetMutableData().set_value(q)

    def feed_bytes(self, i: int, data: bytes) -> None:
        """:meth:`feed` of a status's bytes.

        Parameters
        ----------
        i : int
            The arm's index.
        data : bytes
            The status's bytes.
        """
        self.feed(i, check_panda_status(data, self.specs[i].n))

    def tick(self) -> None:
        """Tick ``k``: :meth:`step`, :meth:`check`, :meth:`send`."""
        self.step()
        self.check()
        self.send()

    def step(self) -> None:
        """The updates at ``t_k`` (one Simulator step), ``λ̂(k)`` read first: the value the
        step's updates then use (computed once, cached by Drake) and the watchdog checks.

        The step ends at :math:`t_{k+1}`, or just short of it when an event falls a rounding
        before it (:func:`step_end`: the mass estimator's, every ``ESTIMATOR_TICKS h``,
        ``m (5h)`` and ``(5m) h`` differ by an ulp now and then), so that such an event runs in
        the next step, on the reading of tick ``k + 1``: what the simulated diagram's blocks
        read there (its encoders treat a time within ``1e-9`` of a tick as the tick,
        :func:`~drake_coop.control.timing.tick_of`)."""
        self._lam = [port.Eval(block).tolist() for _, _, block, port, _ in self._wd]
        self.k += 1
        self.simulator.AdvanceTo(step_end(self.k, self.h, self._periods))

    def check(self) -> None:
        """Each arm's watchdog for tick ``k``
        (:meth:`~drake_coop.control.watchdog.Watchdog.tick`, at ``t_k``, on the fed status,
        ``λ̂(k)`` and the latched ``τ(k)``)."""
        t = (self.k - 1) * self.h
        for (wd, wd_context, _, _, (tau, tau_context)), status, q, lam in zip(
                self._wd, self._status, self._q, self._lam):
            wd.tick(wd_context, t, status, q, lam, tau.Eval(tau_context).tolist())

    def send(self) -> None:
        """Each arm's command (the watchdog's ``tau_latched``) encoded and published; during
        :attr:`ramp`, an untripped arm's command blended from its hold torque
        (:meth:`send_ramped`)."""
        for i, (arm, pub_context) in enumerate(zip(self.side.arms, self._pub)):
            if self.ramp is not None and self.ramp.active(self.k - 1) and self.send_ramped(i):
                continue
            arm.command_publisher.ForcedPublish(pub_context)

    def send_ramped(self, i: int) -> bool:
        """Whether arm ``i``'s blended command of tick ``k`` (:class:`~drake_coop.robot.
        safe_start.StartRamp`) was sent, stamped with the wall clock: False (nothing sent) when
        its watchdog has tripped.

        Parameters
        ----------
        i : int
            The arm's index.
        """
        wd, wd_context = self._wd[i][0], self._wd[i][1]
        if wd.is_tripped(wd_context):
            return False
        tau = wd.get_tau_latched_output_port().Eval(wd_context)
        spec, arm = self.specs[i], self.side.arms[i]
        q = wd.last_good_position(wd_context)
        tau = wire_torque(spec, self.ramp.blend(i, self.k - 1, tau), arm.hold_torque(q))
        msg = safe_command_message(spec, tau, arm.command_sender.utime(self.k * self.h))
        self._lcm.Publish(spec.command_channel, msg.encode())
        return True

    def time(self) -> float:
        """``t_k`` of the last tick (s; 0 before the first).
        """
        return max(self.k - 1, 0) * self.h

    def tripped(self) -> dict | None:
        """The first tripped arm's robot, status channel and reason, else None.

        Returns
        -------
        dict or None
            ``robot``, ``channel``, ``reason``, or None.
        """
        for arm in self.side.arms:
            wd = arm.watchdog
            wd_context = wd.GetMyContextFromRoot(self.context)
            if wd.is_tripped(wd_context):
                return {"robot": arm.spec.robot, "channel": arm.spec.status_channel,
                        "reason": wd.reason(wd_context)}
        return None

    def send_safe(self) -> None:
        """Each driver's safe command (zero torque, or the hold torque at the last good
        reading)."""
        for arm, spec in zip(self.side.arms, self.specs):
            wd = arm.watchdog
            q = wd.last_good_position(wd.GetMyContextFromRoot(self.context))
            tau = np.zeros(spec.n) if spec.safe_command == "zero_torque" else arm.hold_torque(q)
            tau = wire_torque(spec, tau, arm.hold_torque(q))     # as the driver reads it
            msg = safe_command_message(spec, tau, arm.command_sender.utime(self.k * self.h))
            self._lcm.Publish(spec.command_channel, msg.encode())


def run_on_arrival(loop: ServeLoop, lcm, arrivals, k_end: int, record, after_tick=None,
                   lead: float = 0.05, timeout: float | None = None,
                   stop: StopListener | None = None, on_arrival: bool = True,
                   collector=None) -> str:
    """Tick ``loop`` from ``k = 0`` to ``k_end``, each tick on a fresh status of every arm.

    With ``on_arrival``, tick ``k`` is released by the first status of every arm that
    arrives after its grid time ``g_k`` (or a faulty one, at once), at the latest at
    ``g_k + timeout`` (default: one driver cycle and a half; the watchdog's age check covers
    a driver that stopped): the status's age at the tick is the transport time, and the
    command leaves as soon as ``τ`` is computed. The grid follows the driver's clock:
    :math:`g_{k+1} = a_k + h - c/2` (``a_k`` the newest arrival that released tick ``k``, ``c`` the
    driver's cycle), so the wait ends on the status of the driver's cycle ``h`` later.
    Without ``on_arrival``, ``g_k = t0 + k h`` and nothing is waited for (the wall-clock
    grid). Before each tick, LCM is pumped until ``g_k`` (:func:`~drake_coop.robot.pacing.
    pump_until`).

    ``after_tick(k)`` returning a string stops the loop (returned); a stop message of another
    ``serve`` (``stop``) stops it before the next tick (``"stop: <its reason>"`` returned).
    Per tick, ``record`` gets the computation, the lateness (from ``g_k`` on the grid; from the
    tick's release on arrival), the oldest status's age at the start and the wait past ``g_k``.
    With a ``collector`` (:class:`~drake_coop.robot.collector.ManagedCollector`, started by
    the caller), Python's garbage collector runs only in the slack after a tick's command
    (:meth:`~drake_coop.robot.collector.ManagedCollector.slack`, before the next ``g_k``),
    and a collection that starts during a tick's work is counted.

    Parameters
    ----------
    loop : ServeLoop
        The controller.
    lcm : DrakeLcm
        The LCM connection.
    arrivals : StatusArrivals
        The statuses.
    k_end : int
        The last tick.
    record : PacingRecord
        Receives the figures.
    after_tick : Callable[[int], str or None] or None
        Called after each tick.
    lead : float
        The wait before tick 0, s.
    timeout : float or None
        The longest wait past ``g_k``, s; None for a driver cycle and a half.
    stop : StopListener or None
        The other processes' stops.
    on_arrival : bool
        Tick on each fresh status (else on the wall-clock grid).
    collector : ManagedCollector or None
        Collects in the slack; None leaves Python's collector as it is.

    Returns
    -------
    str
        Why the loop stopped, or ``''`` at ``k_end``.
    """
    from drake_coop.robot import pacing

    h = loop.h
    cycle = max(s.period for s in loop.specs)
    timeout = 1.5 * cycle if timeout is None else timeout
    channels = [s.status_channel for s in loop.specs]
    grid = time.perf_counter() + lead
    for k in range(k_end + 1):
        pacing.pump_until(lcm, grid)
        if stop is not None and stop.reason is not None:
            return f"stop: {stop.reason}"
        if on_arrival:
            limit = grid + timeout
            while not all(arrivals.last[c] >= grid or arrivals.faulty[c] is not None
                          for c in channels):
                remaining = limit - time.perf_counter()
                if remaining <= 0:          # what is already there is still taken
                    lcm.HandleSubscriptions(0)
                    break
                lcm.HandleSubscriptions(max(1, int(math.ceil(remaining * 1e3))))
            if stop is not None and stop.reason is not None:
                return f"stop: {stop.reason}"
        start = time.perf_counter()
        if collector is not None:
            collector.pauses.ticking = True
        age = arrivals.age(start)
        for i, c in enumerate(channels):
            loop.feed(i, arrivals.take_parsed(c))
        loop.tick()
        end = time.perf_counter()
        if collector is not None:
            collector.pauses.ticking = False
        if on_arrival:
            newest = max(arrivals.last[c] for c in channels)
            released = newest if newest > grid else None
            record.add(k, end - start, end - start, age, start - grid)
            grid = (released if released is not None else grid + cycle / 2) + h - cycle / 2
        else:
            record.add(k, end - start, end - grid, age, 0.0)
            grid += h
        if after_tick is not None:
            reason = after_tick(k)
            if reason:
                return reason
        if collector is not None:
            collector.slack(grid)
    return ""
