"""A cell of arms served by several ``drake-coop serve`` processes (one per arm, or one for
all): each process announces itself, every one watches the others, and the cell fails safe
as a whole.

Every ``serve`` publishes a heartbeat on :data:`CELL_CHANNEL` — its session id (random, one
per process), its pid, when it started, its state (``waiting`` for the first status,
``serving``, ``done``, ``stopped``) and the arms it serves — at every pump while it waits and
at every tick while it serves (:class:`CellWatch`). From the others' heartbeats it knows:

- **a partner's death.** An arm of the scenario this process does not serve is a partner's;
  ``serve`` begins only once a serve for every partner arm has announced itself; a partner
  serving, then not heard for ``cell.partner_silence_ticks`` of this process's own ticks in a
  row (killed, hung, its hub connection lost), stops this one: one line naming the silent
  arm, its safe command sent, exit 1; its stop then stops the others. A partner that has not
  announced ``serving`` within :data:`START_GRACE` of this one's start stops it too.
- **a duplicate.** A second ``serve`` for an arm already served (a heartbeat naming one of its
  arms from another session) refuses to begin in one line (exit 2); which one is second: the
  one still waiting when the other serves, else the later to start. When that cannot be told
  — both already serving, or both started at the same nanosecond — both stop.

Text from other processes (heartbeats, stop messages, reasons) is untrusted: it reaches a
terminal or ``run.json`` only through :func:`printable` (every byte 0–255, every control or
format character shown as an escape), and a malformed heartbeat is counted and ignored.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass

__all__ = ["CELL_CHANNEL", "CellStops", "CellWatch", "Heartbeat", "parse_heartbeat", "printable"]

#: The LCM channel of the serve processes' heartbeats.
CELL_CHANNEL = "DRAKE_COOP_CELL"
#: Largest heartbeat read (bytes); a longer one is ignored.
MAX_HEARTBEAT = 4096
#: Heartbeats a serve publishes while waiting before it may begin (a duplicate starting at
#: the same time hears it first).
MIN_ANNOUNCEMENTS = 3
STATES = ("waiting", "serving", "done", "stopped")
#: How long a partner may take to begin serving once this serve has begun (s): it announces
#: while waiting only every pump (50 ms) and waits a lead before its first tick.
START_GRACE = 1.0


def printable(data, limit: int = 300) -> str:
    """``data`` as one line of printable text: bytes decoded as UTF-8 (an invalid byte shown
    as its backslash escape), every character that is not printable (C0/C1 controls, ESC, DEL,
    bidirectional and other format characters, separators) shown as its Python escape,
    blanks collapsed, at most ``limit`` characters (``…`` ending a cut).

    Parameters
    ----------
    data : bytes or str
        Untrusted text.
    limit : int
        The most characters returned.

    Returns
    -------
    str
        One printable line (``str.isprintable()`` holds).
    """
    if isinstance(data, (bytes, bytearray, memoryview)):
        text = bytes(data).decode("utf-8", "backslashreplace")
    else:
        text = str(data)
    out = []
    for ch in text:
        if ch.isprintable():
            out.append(ch)
        elif ch in "\t\n\r\v\f":
            out.append(" ")
        else:
            out.append(ch.encode("unicode_escape", "backslashreplace").decode("ascii"))
    line = " ".join("".join(out).split())
    return line if len(line) <= limit else line[:max(limit - 1, 0)] + "…"


@dataclass
class Heartbeat:
    """One ``serve``'s announcement on :data:`CELL_CHANNEL`.

    Attributes
    ----------
    session : str
        The process's session id (hex).
    pid : int
        Its process id.
    start_ns : int
        When it started (``time.time_ns()``).
    state : str
        One of ``waiting``, ``serving``, ``done``, ``stopped``.
    robots : list of str
        The arms it serves.
    """

    session: str
    pid: int
    start_ns: int
    state: str
    robots: list

    def encode(self) -> bytes:
        """The heartbeat's bytes (JSON).

        Returns
        -------
        bytes
            The heartbeat as JSON text (session, pid, start, state, arms).
        """
        return json.dumps({"session": self.session, "pid": self.pid, "start_ns": self.start_ns,
                           "state": self.state, "robots": self.robots}).encode("utf-8")


def parse_heartbeat(data: bytes) -> Heartbeat | None:
    """A heartbeat read from untrusted bytes, or None when they are not one (too long, not
    JSON, a field missing or of the wrong type); never raises.

    Parameters
    ----------
    data : bytes
        The message.

    Returns
    -------
    Heartbeat or None
        The heartbeat, or None when the bytes are not one (foreign or malformed).
    """
    try:
        if len(data) > MAX_HEARTBEAT:
            return None
        raw = json.loads(bytes(data).decode("utf-8"))
        if not isinstance(raw, dict):
            return None
        session, pid, start, state, robots = (raw.get(k) for k in (
            "session", "pid", "start_ns", "state", "robots"))
        if not (isinstance(session, str) and 0 < len(session) <= 64
                and all(c in "0123456789abcdef" for c in session)):
            return None
        if isinstance(pid, bool) or not isinstance(pid, int) or \
                isinstance(start, bool) or not isinstance(start, int) or state not in STATES:
            return None
        if not (isinstance(robots, list) and 0 < len(robots) <= 64
                and all(isinstance(r, str) and 0 < len(r) <= 200 for r in robots)):
            return None
        return Heartbeat(session, pid, start, state, list(robots))
    except Exception:            # RecursionError of a deeply nested document included
        return None


class CellWatch:
    """This ``serve``'s heartbeat and its watch over the others (see the module's docstring).

    :attr:`reason` is set (one printable line naming the arm) when this process must stop or
    must not begin; :attr:`refused` then says it must not begin (a duplicate, exit 2), and
    :attr:`arm` names the arm the reason is about.

    Parameters
    ----------
    lcm : DrakeLcm
        The LCM connection.
    robots : list of str
        The arms this process serves.
    cell_robots : list of str
        Every arm of the scenario (the others are the partners').
    silence_ticks : int
        A partner not heard for this many of this process's ticks in a row, once it serves,
        stops it.
    grace_ticks : int
        A partner that has not announced ``serving`` this many ticks after this process began
        stops it (its start is slower than a tick: see :data:`START_GRACE`).
    channel : str
        The heartbeat channel.
    session : str or None
        This process's session id (hex; None: 16 random hex digits).
    clock_ns : Callable[[], int]
        The start stamp's clock (``time.time_ns``: comparable between processes of a
        machine).
    """

    def __init__(self, lcm, robots: list[str], cell_robots: list[str], silence_ticks: int = 3,
                 grace_ticks: int = 112, channel: str = CELL_CHANNEL,
                 session: str | None = None, clock_ns=time.time_ns):
        self._lcm, self.channel = lcm, channel
        self.robots = list(robots)
        self.partners = [r for r in cell_robots if r not in self.robots]
        self.silence_ticks = int(silence_ticks)
        self.grace_ticks = int(grace_ticks)
        self.serving: set[str] = set()             # partner arms heard serving
        self.session = session if session is not None else os.urandom(8).hex()
        self.pid = os.getpid()
        self.start_ns = int(clock_ns())
        self.state = "waiting"
        self.k = 0                                  # this process's ticks
        self.heard: dict[str, int | None] = {r: None for r in self.partners}
        self.done: set[str] = set()
        self.peers: dict[str, Heartbeat] = {}        # session -> newest heartbeat
        self.announced = 0
        self.ignored = 0
        self.reason: str | None = None
        self.arm: str | None = None
        self.refused = False
        lcm.Subscribe(channel, self._handle)

    def announce(self, state: str | None = None) -> None:
        """Publish this process's heartbeat (``state``: its new state, else the current one).

        Parameters
        ----------
        state : str or None
            ``waiting``, ``serving``, ``done`` or ``stopped``.
        """
        if state is not None:
            self.state = state
        self._lcm.Publish(self.channel, Heartbeat(self.session, self.pid, self.start_ns,
                                                  self.state, self.robots).encode())
        self.announced += 1

    def ready(self) -> bool:
        """Whether this process may begin: no reason to stop, a serve heard for every partner
        arm, and its own heartbeat published :data:`MIN_ANNOUNCEMENTS` times.

        Returns
        -------
        bool
            True when it may begin.
        """
        self.check()
        return (self.reason is None and self.announced >= MIN_ANNOUNCEMENTS
                and all(self.heard[r] is not None for r in self.partners))

    def missing(self) -> list[str]:
        """The partner arms no serve has announced yet.

        Returns
        -------
        list of str
            The partner arms no serve has announced yet.
        """
        return [r for r in self.partners if self.heard[r] is None]

    def begin(self) -> None:
        """This process begins serving: its state ``serving``, the partners' silence counted
        from now."""
        self.state = "serving"
        for r in self.partners:
            self.heard[r] = self.k

    def tick(self) -> str | None:
        """After each of this process's ticks: its heartbeat (:meth:`beat`), then each
        partner's silence (:meth:`watch`).

        Returns
        -------
        str or None
            Why this process must stop (:attr:`reason`), or None.
        """
        self.beat()
        return self.watch()

    def beat(self) -> None:
        """This process's tick is counted and its heartbeat published.

        In lockstep the heartbeat of a tick is published *before* the tick's command (see
        :func:`~drake_coop.robot.lockstep.run_lockstep`): the driver advances only on every
        arm's command, so a partner's tick ``m`` then always follows the heartbeat of this
        process's tick ``m - 1`` on the wire, and a partner counts at most 2 ticks of silence
        however the processes are scheduled. Sent after the command, a heartbeat can trail
        it (TCP's Nagle delay, a process descheduled between the two sends) while the lockstep
        runs on: 3 ticks, the stop's bound, were seen under load."""
        self.k += 1
        self.announce("serving")

    def watch(self) -> str | None:
        """Each partner's silence after this process's tick (:meth:`beat` counted it).

        Returns
        -------
        str or None
            Why this process must stop (:attr:`reason`), or None.
        """
        self.check()
        for r in self.partners:
            if self.reason is not None:
                break
            if r in self.done or self.heard[r] is None:
                continue
            silent = self.k - self.heard[r]
            if r not in self.serving:              # still starting: the grace
                if self.k >= self.grace_ticks:
                    self._stop(r, f"{r}: its serve did not begin within {self.k} ticks of "
                                  "this one")
            elif silent >= self.silence_ticks:
                self._stop(r, f"{r}: its serve silent for {silent} ticks (killed, hung or "
                              "cut from the LCM hub)")
        return self.reason

    def _stop(self, arm: str, reason: str, refused: bool = False) -> None:
        if self.reason is None:
            self.reason, self.arm, self.refused = printable(reason), printable(arm, 100), refused

    def _handle(self, data: bytes) -> None:
        beat = parse_heartbeat(data)
        if beat is None:
            self.ignored += 1
            return
        if beat.session == self.session:
            return
        self.peers[beat.session] = beat
        if len(self.peers) > 256:                  # a flood of made-up sessions
            self.peers.pop(next(iter(self.peers)))
        for r in beat.robots:
            if r in self.heard:
                self.heard[r] = self.k
                if beat.state == "done":
                    self.done.add(r)
                elif beat.state == "serving":
                    self.serving.add(r)

    def check(self) -> None:
        """Each other serve's newest heartbeat against this one's arms: a duplicate sets
        :attr:`reason` (see the module's docstring). Called by :meth:`ready` and
        :meth:`tick`, after the heartbeats that arrived in between were all handled (a serve
        that announced ``serving`` and then ``done`` is not a duplicate)."""
        for beat in list(self.peers.values()):
            if self.reason is None:
                self._against(beat)
        self.peers.clear()

    def _against(self, beat: Heartbeat) -> None:
        shared = [r for r in self.robots if r in beat.robots]
        if not shared or beat.state not in ("waiting", "serving"):
            return
        arm, other = shared[0], f"pid {beat.pid}, session {beat.session}"
        if self.state == "waiting" and beat.state == "serving":
            self._stop(arm, f"{arm} is already served by another serve ({other}); not "
                            "started", refused=True)
        elif self.state == "waiting" and beat.state == "waiting":
            if beat.start_ns < self.start_ns:
                self._stop(arm, f"{arm} is already served by another serve started earlier "
                                f"({other}); not started", refused=True)
            elif beat.start_ns == self.start_ns:
                self._stop(arm, f"{arm}: two serve processes started at the same time "
                                f"(this one and {other}); neither starts", refused=True)
        elif self.state == "serving" and beat.state == "serving":
            self._stop(arm, f"{arm}: two serve processes command it (this one, pid "
                            f"{self.pid}, and {other}); both stop")


class CellStops:
    """What stops this ``serve`` before its next tick: another serve's stop message (a
    :class:`~drake_coop.robot.serve_loop.StopListener`) or this process's
    :class:`CellWatch` (a duplicate serving the same arm); the ``stop`` argument of
    :func:`~drake_coop.robot.serve_loop.run_on_arrival`.

    Parameters
    ----------
    listener : StopListener
        The other serves' stop messages.
    watch : CellWatch
        This process's watch over the cell.
    """

    def __init__(self, listener, watch: CellWatch):
        self.listener, self.watch = listener, watch

    @property
    def reason(self) -> str | None:
        """The cell's reason first, else the stop message's, else None."""
        return self.watch.reason or self.listener.reason
