"""Real-time pacing of the controller side: the wall-clock loop, its per-tick figures, and
their comparison with the loop's delay margin.

:class:`WallClockLoop` runs a Simulator tick by tick against the wall clock: it waits for
``t0 + k h`` while pumping LCM (so each status is received when it arrives, and its arrival
time is known), then advances the Diagram through the tick's updates and the command's
publication (``t_k + COMMAND_OFFSET``). Per tick it records:

* ``compute`` — wall time of the tick's work (the status latched, the control blocks, the
  watchdog, the command encoded and published);
* ``lateness`` — when the command left, against ``t0 + t_k``;
* ``status_age`` — age of the newest status the tick used (the oldest over the arms), from
  its arrival in this process;
* ``missed`` — the command left after :math:`t_{k+1}` (the next tick's deadline);
* ``wait`` — how long the tick waited past ``t0 + t_k`` for a fresh status of every arm
  (ticking on the status's arrival, :func:`~drake_coop.robot.serve_loop.run_on_arrival`;
  0 on the wall-clock grid).

The loop's delay at a tick (what the stability map calls a computation delay ``d``: from the
measurement to the torque acting) is ``status_age + lateness + one driver cycle`` (the
driver applies a command at its next cycle). Ticking on the status's arrival, a tick is due
when the status that releases it arrives: ``lateness`` is then counted from the tick's start
(its release), so that ``status_age + lateness`` is the time from the oldest status's arrival
to the command's departure. :func:`pacing_summary` compares its 99th
percentile with the delay margin of :func:`delay_margin`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drake_coop.control.deprecation import moved

#: Names this module no longer holds (found here until the removal date of
#: :mod:`drake_coop.control.deprecation`).
_MOVED = dict.fromkeys(("REALTIME_POLICIES", "missing_realtime", "realtime_settings",
                        "unlock_memory"), "drake_coop.robot.realtime")

#: Columns of ``pacing.csv``.
PACING_COLUMNS = ("k", "t", "compute_s", "lateness_s", "status_age_s", "missed", "wait_s")


@dataclass
class PacingRecord:
    """Per-tick figures of a paced run (see the module's docstring).

    Attributes
    ----------
    period : float
        The control period ``h``, s.
    driver_period : float
        The driver's cycle, s.
    k : list of int
        The ticks.
    compute : list of float
        Each tick's computation, s.
    lateness : list of float
        Each tick's start after its deadline, s.
    status_age : list of float
        The oldest status's age at the tick, s.
    wait : list of float
        The wait for a fresh status past the grid time, s.
    """

    period: float
    driver_period: float
    k: list[int] = field(default_factory=list)
    compute: list[float] = field(default_factory=list)
    lateness: list[float] = field(default_factory=list)
    status_age: list[float] = field(default_factory=list)
    wait: list[float] = field(default_factory=list)

    def add(self, k: int, compute: float, lateness: float, status_age: float,
            wait: float = 0.0) -> None:
        """Record one tick's figures.

        Parameters
        ----------
        k : int
            The tick.
        compute : float
            Its computation, s.
        lateness : float
            Its lateness, s.
        status_age : float
            The oldest status's age, s.
        wait : float
            The wait past the grid time, s.
        """
        self.k.append(k)
        self.compute.append(compute)
        self.lateness.append(lateness)
        self.status_age.append(status_age)
        self.wait.append(wait)

    def arrays(self) -> dict[str, np.ndarray]:
        """The figures as arrays (the columns of :data:`PACING_COLUMNS`).

        Returns
        -------
        dict of str to numpy.ndarray
            Column → values (times in s).
        """
        k = np.asarray(self.k, dtype=int)
        lateness = np.asarray(self.lateness, dtype=float)
        return {"k": k, "t": k * self.period, "compute_s": np.asarray(self.compute, dtype=float),
                "lateness_s": lateness,
                "status_age_s": np.asarray(self.status_age, dtype=float),
                "missed": (lateness > self.period).astype(int),
                "wait_s": np.asarray(self.wait, dtype=float)}


#: Messages of a channel kept unchecked at most (then checked as they arrive).
_MAX_PENDING = 1000


class StatusArrivals:
    """Wall time at which the newest message of each channel arrived in this process, and
    that message (a plain ``DrakeLcm`` subscription; pump it outside ``AdvanceTo`` only, see
    :func:`~drake_coop.robot.drivers.add_lcm_interface`).

    Each message's handler only stamps and keeps its bytes (the LCM dispatch of a message to
    Python is most of its cost at the driver's rate). The messages are checked when the
    caller looks (:attr:`faulty`, :meth:`take`): ``check``, optional, maps a channel to
    ``check(data) -> bool`` (False: a faulty message), ``check_many`` to
    ``check_many(messages) -> int`` (the index of the first faulty one, -1 if none: the same
    check on all the messages that arrived since the last look, at once). :meth:`take`
    gives the first faulty message since the last :meth:`take` in preference to the newest,
    so that a bad message followed by good ones between two ticks is still seen by the next
    tick.

    Parameters
    ----------
    lcm : DrakeLcm
        The LCM connection.
    channels : list of str
        The status channels.
    check : dict or None
        Channel → ``check(data) -> bool``.
    parse : dict or None
        Channel → ``parse(data)``.
    check_many : dict or None
        Channel → ``check_many(messages) -> int``.
    """

    def __init__(self, lcm, channels: list[str], check: dict | None = None,
                 parse: dict | None = None, check_many: dict | None = None):
        self.last = {c: math.nan for c in channels}
        self.count = {c: 0 for c in channels}
        self.message = {c: None for c in channels}
        self._faulty = {c: None for c in channels}
        self._pending = {c: [] for c in channels}
        self._check = dict(check or {})
        self._check_many = dict(check_many or {})
        self._parse = dict(parse or {})
        for c in channels:
            lcm.Subscribe(c, self._handler(c))

    def _handler(self, channel: str):
        last, count, message = self.last, self.count, self.message
        pending = self._pending[channel]
        keep = pending.append
        if channel not in self._check and channel not in self._check_many:
            keep = None
        clock = time.perf_counter

        def handle(data: bytes) -> None:
            last[channel] = clock()
            count[channel] += 1
            message[channel] = data
            if keep is not None:
                keep(data)
                if len(pending) >= _MAX_PENDING:      # nobody looked for a while
                    self._settle(channel)
        return handle

    def _settle(self, channel: str) -> None:
        """Check the messages that arrived since the last look (the first faulty one kept)."""
        pending = self._pending[channel]
        if not pending:
            return
        if self._faulty[channel] is None:
            many = self._check_many.get(channel)
            if many is not None:
                i = many(pending)
            else:
                check = self._check[channel]
                i = next((j for j, data in enumerate(pending) if not check(data)), -1)
            if i >= 0:
                self._faulty[channel] = pending[i]
        pending.clear()

    @property
    def faulty(self) -> dict:
        """Each channel's first faulty message since the last :meth:`take` (None: none)."""
        for c in self._pending:
            self._settle(c)
        return self._faulty

    def parsed(self, channel: str):
        """``parse`` (given for the channel) of the newest message.

        Parameters
        ----------
        channel : str
            The channel.
        """
        return self._parse[channel](self.message[channel])

    def take_parsed(self, channel: str):
        """``parse`` of what :meth:`take` gives (None before the first message).

        Parameters
        ----------
        channel : str
            The channel.
        """
        data = self.take(channel)
        return None if data is None else self._parse[channel](data)

    def take(self, channel: str) -> bytes | None:
        """The first faulty message since the last call if any (then forgotten), else the
        newest.

        Parameters
        ----------
        channel : str
            The channel.
        """
        self._settle(channel)
        data = self._faulty[channel]
        if data is None:
            return self.message[channel]
        self._faulty[channel] = None
        return data

    def all_arrived(self) -> bool:
        """Whether every channel has had a message.

        Returns
        -------
        bool
            True once each has.
        """
        return all(n > 0 for n in self.count.values())

    def age(self, now: float) -> float:
        """The oldest newest-status age over the channels (s).

        Parameters
        ----------
        now : float
            The wall time (``time.perf_counter``), s.
        """
        return max(now - t for t in self.last.values())


def pump_until(lcm, deadline: float) -> None:
    """Handle LCM messages as they arrive until the wall clock reaches ``deadline``
    (``time.perf_counter`` seconds); the last fraction of a millisecond is slept.

    Parameters
    ----------
    lcm : DrakeLcm
        The LCM connection.
    deadline : float
        The wall time, s.
    """
    while True:
        remaining = deadline - time.perf_counter()
        if remaining <= 0:
            return
        if remaining > 1e-3:
            lcm.HandleSubscriptions(int(remaining * 1e3))
        else:
            time.sleep(remaining)
            lcm.HandleSubscriptions(0)


def run_paced(simulator, lcm, arrivals: StatusArrivals, h: float, k_end: int, offset: float,
              record: PacingRecord, after_tick=None, lead: float = 0.05,
              before_tick=None) -> float:
    """Advance ``simulator`` tick by tick against the wall clock.

    For ``k = 0 … k_end``: pump LCM until ``t0 + k h``, call ``before_tick(k)`` (e.g. hand the
    newest statuses to the Diagram), then ``AdvanceTo(k h + offset)``; the tick's figures go
    to ``record`` (its computation includes ``before_tick``). ``after_tick(k)`` returning a
    string stops the loop (the watchdog's reason); it is returned. ``t0`` is ``lead`` seconds
    after the call.

    Parameters
    ----------
    simulator : Simulator
        The controller's simulator.
    lcm : DrakeLcm
        The LCM connection.
    arrivals : StatusArrivals
        The statuses.
    h : float
        The control period, s.
    k_end : int
        The last tick.
    offset : float
        How far past ``k h`` each ``AdvanceTo`` goes, s.
    record : PacingRecord
        Receives the figures.
    after_tick : Callable[[int], str or None] or None
        Called after each tick.
    lead : float
        The wait before tick 0, s.
    before_tick : Callable[[int], None] or None
        Called before each tick.

    Returns
    -------
    str
        ``after_tick``'s reason, or ``''`` after ``k_end``.
    """
    t0 = time.perf_counter() + lead
    for k in range(k_end + 1):
        pump_until(lcm, t0 + k * h)
        start = time.perf_counter()
        age = arrivals.age(start)
        if before_tick is not None:
            before_tick(k)
        simulator.AdvanceTo(k * h + offset)
        end = time.perf_counter()
        record.add(k, end - start, end - (t0 + k * h), age)
        if after_tick is not None:
            reason = after_tick(k)
            if reason:
                return reason
    return ""


def percentile(x: np.ndarray, q: float) -> float:
    """The ``q``-th percentile of ``x`` (NaN when empty).

    Parameters
    ----------
    x : numpy.ndarray
        The values.
    q : float
        The percentile, 0 to 100.
    """
    x = np.asarray(x, dtype=float)
    return float(np.percentile(x, q)) if x.size else math.nan


#: The percentiles reported of each figure (``p50``, ``p99``, ``p99.9``) and its maximum.
PERCENTILES = (50.0, 99.0, 99.9)


def _key(q: float) -> str:
    return f"p{q:g}".replace(".", "_")


def pacing_summary(record: PacingRecord, margin: float | None, *, margin_reason: str = "",
                   collector: dict | None = None) -> dict:
    """The paced run's figures against the delay margin ``margin`` (s; None: unknown).

    ``met`` is True when no deadline was missed and the 99th percentile of the loop's delay
    (``status_age + lateness + driver cycle``) is within the margin. Each figure (computation,
    lateness, status age, loop delay) is given at :data:`PERCENTILES` and its maximum
    (``<figure>_p50_s``, ``_p99_s``, ``_p99_9_s``, ``_max_s``).

    Parameters
    ----------
    record : PacingRecord
        The run's figures.
    margin : float or None
        The delay margin, s.
    margin_reason : str
        Why there is no margin (one line), when ``margin`` is None.
    collector : dict or None
        The garbage collector's figures
        (:meth:`~drake_coop.robot.collector.ManagedCollector.summary`).

    Returns
    -------
    dict
        The summary (times in s).
    """
    a = record.arrays()
    delay = a["status_age_s"] + a["lateness_s"] + record.driver_period
    summary = {"ticks": int(a["k"].size), "period_s": record.period,
               "driver_period_s": record.driver_period}
    figures = {"compute": a["compute_s"], "lateness": a["lateness_s"],
               "status_age": a["status_age_s"], "loop_delay": delay, "wait": a["wait_s"]}
    for name, x in figures.items():
        for q in PERCENTILES:
            summary[f"{name}_{_key(q)}_s"] = percentile(x, q)
        summary[f"{name}_max_s"] = float(x.max()) if x.size else math.nan
    summary["missed_deadlines"] = int(a["missed"].sum())
    summary["delay_margin_s"] = margin
    if margin is None and margin_reason:
        summary["delay_margin_reason"] = margin_reason
    summary["met_margin"] = (None if margin is None or not a["k"].size else bool(
        summary["missed_deadlines"] == 0 and summary["loop_delay_p99_s"] <= margin + 1e-12))
    if collector is not None:
        summary["collector"] = dict(collector)
    return summary


def summary_line(summary: dict) -> str:
    """One line for the terminal.

    Parameters
    ----------
    summary : dict
        :func:`pacing_summary`'s.

    Returns
    -------
    str
        The line (times in ms).
    """
    ms = 1e3
    margin = summary["delay_margin_s"]
    if summary["met_margin"] is None:
        reason = summary.get("delay_margin_reason", "")
        verdict = "margin unknown" + (f" ({reason})" if reason else "")
    else:
        verdict = (("met the" if summary["met_margin"] else "did NOT meet the")
                   + f" {margin * ms:.3g} ms delay margin")

    def spread(name: str) -> str:
        return "/".join(f"{summary[f'{name}_{_key(q)}_s'] * ms:.2f}" for q in PERCENTILES) + \
            f"/{summary[f'{name}_max_s'] * ms:.2f}"

    gc_part = ""
    c = summary.get("collector")
    if c:
        gc_part = (f", {c['pauses_over_1ms']} collector pauses over 1 ms "
                   f"({c['collections']} collections, {c['during_ticks']} during ticks)")
    return (f"{summary['ticks']} ticks: loop delay p50/p99/p99.9/max {spread('loop_delay')} ms, "
            f"computation {spread('compute')} ms, lateness p99 "
            f"{summary['lateness_p99_s'] * ms:.2f} ms, status age p99 "
            f"{summary['status_age_p99_s'] * ms:.2f} ms, {summary['missed_deadlines']} missed "
            f"deadlines{gc_part}: {verdict}")


def delay_margin(scenario, *, epsilon: float = 1e-5) -> float:
    """The delay margin of ``scenario`` as it runs (its own delay compensation): the largest
    computation delay ``d`` (whole plant steps, up to ``h``) for which the stability map
    (:mod:`drake_coop.stability`, free operating point) gives ``ρ < 1`` at every delay from 0
    to ``d``; NaN if not even the undelayed loop is stable
    (:func:`~drake_coop.stability.margin.delay_margins` says why, and gives the margin with
    and without compensation).

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    epsilon : float
        The central differences' step.
    """
    from drake_coop.stability.margin import delay_margins

    m = delay_margins(scenario, epsilon=epsilon).configured
    return math.nan if m.margin_s is None else m.margin_s


def write_pacing_csv(path: Path, record: PacingRecord) -> None:
    """``pacing.csv``: one row per tick (:data:`PACING_COLUMNS`), written whole.

    Parameters
    ----------
    path : Path
        The file.
    record : PacingRecord
        The figures.
    """
    from drake_coop.results.io import atomic_write_text

    a = record.arrays()
    lines = [",".join(PACING_COLUMNS)]
    for i in range(a["k"].size):
        lines.append(f"{a['k'][i]},{a['t'][i]:.6f},{a['compute_s'][i]:.9f},"
                     f"{a['lateness_s'][i]:.9f},{a['status_age_s'][i]:.9f},{a['missed'][i]},"
                     f"{a['wait_s'][i]:.9f}")
    atomic_write_text(path, "\n".join(lines) + "\n")


def __getattr__(name):
    """A name that moved to its defining module (:data:`_MOVED`), with a warning."""
    return moved(__name__, name, _MOVED)
