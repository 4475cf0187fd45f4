"""Python's garbage collector kept out of ``serve``'s ticks, and its pauses counted.

CPython's cyclic collector runs when allocations pass a threshold, wherever the program then
is: inside a tick it stops the tick for as long as it takes (pauses of 20–100 ms are reported
by other Python robot stacks with large heaps). :class:`ManagedCollector` takes it out of the
ticks:

* on :meth:`~ManagedCollector.start`, one full collection, then ``gc.freeze()`` (everything
  alive — Drake's systems, the scenario, the imported modules — moves to the permanent
  generation, which later collections do not traverse) and ``gc.disable()`` (no automatic
  collection at all);
* after each tick's command has left, :meth:`~ManagedCollector.slack` collects the youngest
  generation when the time to the next tick is at least :data:`SLACK_NEEDED` (the young
  generation holds only what the last ticks allocated: a fraction of a millisecond), and an
  older one every :data:`OLDER_EVERY` young collections;
* on :meth:`~ManagedCollector.stop`, ``gc.unfreeze()`` and the collector's previous state back.

Every collection, automatic or not, is timed by a ``gc.callbacks`` hook
(:class:`CollectorPauses`): the count, the longest, and those over :data:`PAUSE_THRESHOLD`
(1 ms) go to ``run.json`` (``pacing.collector``).
"""

from __future__ import annotations

import gc
import time
from dataclasses import dataclass, field
from typing import Callable

__all__ = ["PAUSE_THRESHOLD", "SLACK_NEEDED", "OLDER_EVERY", "CollectorPauses",
           "ManagedCollector"]

#: A collection longer than this is a pause worth counting, s.
PAUSE_THRESHOLD = 1e-3
#: The least time before the next tick for a collection in the slack, s.
SLACK_NEEDED = 2e-3
#: One collection of generation 1 every this many of generation 0 (generation 2 never runs
#: inside the loop: the frozen heap is not traversed, and what is left is collected at stop).
OLDER_EVERY = 50


@dataclass
class CollectorPauses:
    """Each collection's duration, from ``gc.callbacks`` (see the module's docstring).

    Parameters
    ----------
    clock : Callable[[], float]
        The clock, s (``time.perf_counter``; given for tests).
    threshold : float
        A pause counted as long above this, s.

    Attributes
    ----------
    count : int
        Collections seen.
    long : int
        Those longer than ``threshold``.
    longest_s : float
        The longest, s.
    total_s : float
        Their sum, s.
    in_tick : int
        Collections that started while :attr:`ticking` was True.
    ticking : bool
        Set by the loop around each tick's work.
    """

    clock: Callable[[], float] = time.perf_counter
    threshold: float = PAUSE_THRESHOLD
    count: int = 0
    long: int = 0
    longest_s: float = 0.0
    total_s: float = 0.0
    in_tick: int = 0
    ticking: bool = False
    _start: float | None = field(default=None, init=False, repr=False)

    def __call__(self, phase: str, info: dict) -> None:
        """The ``gc.callbacks`` hook.

        Parameters
        ----------
        phase : str
            ``start`` or ``stop``.
        info : dict
            CPython's information (``generation``, ...).
        """
        if phase == "start":
            self._start = self.clock()
            if self.ticking:
                self.in_tick += 1
            return
        if self._start is None:
            return
        d = self.clock() - self._start
        self._start = None
        self.count += 1
        self.total_s += d
        self.longest_s = max(self.longest_s, d)
        if d > self.threshold:
            self.long += 1

    def summary(self) -> dict:
        """The figures for ``run.json``.

        Returns
        -------
        dict
            ``collections``, ``pauses_over_1ms``, ``longest_s``, ``total_s``,
            ``during_ticks``.
        """
        return {"collections": self.count, "pauses_over_1ms": self.long,
                "threshold_s": self.threshold, "longest_s": self.longest_s,
                "total_s": self.total_s, "during_ticks": self.in_tick}


class ManagedCollector:
    """The collector frozen and disabled during the loop, run in the slack (module docstring).

    Parameters
    ----------
    pauses : CollectorPauses or None
        The hook timing each collection (a new one by default).
    clock : Callable[[], float]
        The clock of :meth:`slack`'s deadlines, s.
    """

    def __init__(self, pauses: CollectorPauses | None = None,
                 clock: Callable[[], float] = time.perf_counter):
        self.pauses = pauses if pauses is not None else CollectorPauses()
        self._clock = clock
        self._was_enabled: bool | None = None
        self.young = 0
        self.older = 0

    def start(self) -> None:
        """Collect once, freeze the heap, disable automatic collection, hook the timing."""
        if self._was_enabled is not None:
            return
        self._was_enabled = gc.isenabled()
        gc.collect()
        gc.freeze()
        gc.disable()
        gc.callbacks.append(self.pauses)

    def slack(self, deadline: float) -> int | None:
        """Collect in the time left before ``deadline`` (the next tick, on :attr:`clock`):
        generation 0 if at least :data:`SLACK_NEEDED` remains, generation 1 every
        :data:`OLDER_EVERY` of them.

        Parameters
        ----------
        deadline : float
            The next tick's time, s.

        Returns
        -------
        int or None
            The generation collected, or None (not enough slack).
        """
        if deadline - self._clock() < SLACK_NEEDED:
            return None
        self.young += 1
        generation = 1 if self.young % OLDER_EVERY == 0 else 0
        if generation:
            self.older += 1
        gc.collect(generation)
        return generation

    def stop(self) -> None:
        """Unhook, unfreeze and give the collector its previous state back."""
        if self._was_enabled is None:
            return
        if self.pauses in gc.callbacks:
            gc.callbacks.remove(self.pauses)
        gc.unfreeze()
        if self._was_enabled:
            gc.enable()
        self._was_enabled = None

    def summary(self) -> dict:
        """:meth:`CollectorPauses.summary` and the collections run in the slack.

        Returns
        -------
        dict
            The figures.
        """
        return {**self.pauses.summary(), "policy": "freeze+disable, collect in the slack",
                "slack_collections": self.young, "slack_generation1": self.older}

    def __enter__(self) -> "ManagedCollector":
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
