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
from drake_coop.robot.driver_spec import safe_command_message
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
    this process's own (``robots``: the arms this process serves).

    Parameters
    ----------
    lcm : DrakeLcm
        The LCM connection.
    robots : list of str
        This process's arms.
    channel : str
        The stop channel.
    """

    def __init__(self, lcm, robots: list[str], channel: str = STOP_CHANNEL):
        self.channel = channel
        self._own = set(robots)
        self.reason: str | None = None
        lcm.Subscribe(channel, self._handle)

    def _handle(self, data: bytes) -> None:
        text = bytes(data).decode("utf-8", "replace")
        if text.split(":", 1)[0] in self._own or self.reason is not None:
            return
        self.reason = " ".join(text.split())[:300]

    @staticmethod
    def publish(lcm, robot: str, reason: str, channel: str = STOP_CHANNEL) -> None:
        """Publish ``"<robot>: <reason>"`` on the stop channel (the other processes stop).

        Parameters
        ----------
        lcm : DrakeLcm
            The LCM connection.
        robot : str
            The robot whose watchdog tripped.
        reason : str
            Its reason.
        channel : str
            The stop channel.
        """
        lcm.Publish(channel, f"{robot}: {reason}".encode("utf-8"))


class ServeLoop:
    """The controller side of ``serve`` for the given arms, ticked by the caller.

    Parameters
    ----------
    scenario, plan
        The scenario and its :class:`~drake_coop.experiment.plan.RunPlan`.
    lcm : DrakeLcmInterface
        Where the commands are published.
    specs : list of DriverSpec
        Every arm's :class:`~drake_coop.robot.driver_spec.DriverSpec`.
    robots : list of str, optional
        The arms served (default all; one for ``serve --robot``).
    """

    def __init__(self, scenario, plan, lcm, specs, robots: list[str] | None = None):
        builder = DiagramBuilder()
        self.side = add_controller_side(builder, scenario, lcm, plan, specs,
                                        status_input="loop", robots=robots)
        self.specs = [arm.spec for arm in self.side.arms]
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        self.context = self.simulator.get_mutable_context()
        self.h = plan.h
        self._scenario, self._plan, self._lcm = scenario, plan, lcm
        self._fixed_q: list = []
        self._status: list[tuple[float, float, float]] = []   # each arm's [s, f, v]
        self._q: list[list[float]] = []                       # and its last valid reading
        self._wd: list = []
        self._lam: list = []
        self._good: list[np.ndarray] = []
        self._pub: list = []
        self.k = 0

    def start(self, q0: list[np.ndarray]) -> None:
        """Observers at ``q̂ = q0``, watchdogs untripped with ``q0`` as their last good
        reading, no status yet; ``Initialize``.

        Parameters
        ----------
        q0 : list of numpy.ndarray
            Each arm's first reading (n,), rad.
        """
        from drake_coop.robot.loopback import initialize_sides

        initialize_sides(self._scenario, self._plan, self.context, None, self.side, q0)
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
        step's updates then use (computed once, cached by Drake) and the watchdog checks."""
        self._lam = [port.Eval(block).tolist() for _, _, block, port, _ in self._wd]
        self.k += 1
        self.simulator.AdvanceTo(self.k * self.h)

    def check(self) -> None:
        """Each arm's watchdog for tick ``k``
        (:meth:`~drake_coop.control.watchdog.Watchdog.tick`, at ``t_k``, on the fed status,
        ``λ̂(k)`` and the latched ``τ(k)``)."""
        t = (self.k - 1) * self.h
        for (wd, wd_context, _, _, (tau, tau_context)), status, q, lam in zip(
                self._wd, self._status, self._q, self._lam):
            wd.tick(wd_context, t, status, q, lam, tau.Eval(tau_context).tolist())

    def send(self) -> None:
        """Each arm's command (the watchdog's ``tau_latched``) encoded and published."""
        for arm, pub_context in zip(self.side.arms, self._pub):
            arm.command_publisher.ForcedPublish(pub_context)

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
            msg = safe_command_message(spec, tau, int(time.time() * 1e6))
            self._lcm.Publish(spec.command_channel, msg.encode())


def run_on_arrival(loop: ServeLoop, lcm, arrivals, k_end: int, record, after_tick=None,
                   lead: float = 0.05, timeout: float | None = None,
                   stop: StopListener | None = None, on_arrival: bool = True) -> str:
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
        age = arrivals.age(start)
        for i, c in enumerate(channels):
            loop.feed(i, arrivals.take_parsed(c))
        loop.tick()
        end = time.perf_counter()
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
    return ""
