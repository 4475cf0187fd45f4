"""SIGINT and SIGTERM of a ``drake-coop`` command: :class:`Signals`, and :data:`SIGNALS`, the
running command's (replaced by :func:`~drake_coop.cli.main` at each call)."""

from __future__ import annotations

import contextlib
import signal


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C's KeyboardInterrupt: the same code stops the run and keeps
    what was logged."""


class Signals:
    """SIGINT and SIGTERM of the command: raised as :class:`KeyboardInterrupt` /
    :class:`Terminated`, or only recorded inside :meth:`deferred` (start-up, writing)."""

    EXIT_CODES = {signal.SIGINT: 130, signal.SIGTERM: 143}

    def __init__(self):
        self.received: int | None = None
        self.count = 0
        self._defer = 0

    def handler(self, signum, frame) -> None:
        """The signal handler: record, then raise unless deferred.

        Parameters
        ----------
        signum : int
            The signal's number.
        frame : frame or None
            The interrupted frame (unused).
        """
        self.count += 1
        if self.received is None:
            self.received = signum
        if not self._defer:
            raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()

    @contextlib.contextmanager
    def deferred(self):
        """Signals inside the block are recorded only (see :attr:`received`).

        Yields
        ------
        Signals
            This object.
        """
        self._defer += 1
        try:
            yield self
        finally:
            self._defer -= 1

    def exit_code(self, exc: BaseException | None = None) -> int:
        """130 for SIGINT, 143 for SIGTERM.

        Parameters
        ----------
        exc : BaseException or None
            The exception that ended the command, if any.
        """
        if isinstance(exc, Terminated):
            return 143
        return self.EXIT_CODES.get(self.received, 130)

    @property
    def name(self) -> str:
        """``SIGTERM`` or ``Ctrl-C``: the signal received, as a message names it."""
        return "SIGTERM" if self.received == signal.SIGTERM else "Ctrl-C"


#: The signals of the running command (installed by :func:`main`).
SIGNALS = Signals()
