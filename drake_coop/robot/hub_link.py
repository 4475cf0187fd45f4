"""A process's connection to the ``tcpq://`` hub, watched: the hub's death is one line and a
clean stop with the records kept, never an abort inside LCM's C library.

What aborts, read from LCM's C tcpq client (``lcm/lcm_tcpq.c``) and ``lcm_handle_timeout``
(``lcm/lcm.c``) and reproduced here: when the hub's end of the connection goes away, the
client's next read returns 0 (or a send fails); it closes its socket and sets its descriptor
to -1. A publish then tries to reconnect (and fails, printing "LCM tcpq: connecting..." and
"Unable to connect to server"); the next wait for messages — ``DrakeLcm.HandleSubscriptions``
calls ``lcm_handle_timeout``, which puts the provider's descriptor in an ``fd_set`` for
``select`` — puts -1 there, and glibc's checked ``FD_SET`` aborts the process ("bit out of
range 0 - FD_SETSIZE on fd_set", SIGABRT, exit 134) with whatever it had not yet written.
A client started while no hub listens gets -1 at once, and the same abort at its first wait.

So the descriptor is watched from Python, where the abort cannot be caught but can be
forestalled: :class:`HubLink` finds the socket the tcpq client opened (the new socket of
this process connected to the hub's port, from ``/proc/self/fd``) and remembers its inode;
:meth:`HubLink.lost` is true once that descriptor is closed or names another socket (LCM
closed it, or reconnected to a new hub). :class:`WatchedLcm` is a ``DrakeLcm`` whose
``HandleSubscriptions`` checks the link before and after LCM's wait and raises
:class:`HubLost` instead of reaching the abort; :func:`hub_monitor` does the same after every
step of a Simulator whose ``LcmInterfaceSystem`` pumps inside ``AdvanceTo``. ``serve`` and
``sim-driver`` catch :class:`HubLost`: one line ("hub connection lost at t = …"), exit 1,
their records written up to the death.

On a real cell the hub's death stops the commands: a real arm's driver (drake-franka-driver)
drops a command older than its expiry (0.1 s by default) and then holds the arm by its
gravity compensation and damping — the same hold the simulated driver applies.

Linux only (``/proc``); elsewhere nothing is watched (the abort remains).
"""

from __future__ import annotations

import os
import socket

from pydrake.lcm import DrakeLcm

__all__ = ["HUB_LOST_LINE", "HUB_LOST_MARK", "HubLink", "HubLost", "WatchedLcm", "hub_monitor",
           "is_hub_failure", "tcpq_port"]


#: The text of :func:`hub_monitor`'s failure (found again in ``AdvanceTo``'s exception).
HUB_LOST_MARK = "hub connection lost"
#: The reason ``serve`` and ``sim-driver`` give when the hub dies.
HUB_LOST_LINE = (f"{HUB_LOST_MARK} (the tcpq hub died or dropped this process): nothing can be "
                 "sent; a real arm's driver drops the last command once it expires and holds "
                 "the arm")


class HubLost(RuntimeError):
    """The connection to the ``tcpq://`` hub is gone (the hub died or closed it)."""


def _sockets() -> dict[int, int]:
    """This process's open socket descriptors → their inodes (empty without ``/proc``)."""
    out = {}
    try:
        names = os.listdir("/proc/self/fd")
    except OSError:
        return out
    for name in names:
        try:
            target = os.readlink(f"/proc/self/fd/{name}")
        except OSError:
            continue
        if target.startswith("socket:["):
            out[int(name)] = int(target[8:-1])
    return out


def _peer_port(fd: int) -> int | None:
    """The remote port of socket ``fd`` (None if it is not a connected IPv4 TCP socket)."""
    try:
        probe = socket.socket(fileno=os.dup(fd))
    except OSError:
        return None
    try:
        if probe.family != socket.AF_INET or probe.type != socket.SOCK_STREAM:
            return None
        return probe.getpeername()[1]
    except OSError:
        return None
    finally:
        probe.close()


def tcpq_port(url: str) -> int | None:
    """The hub's port of a ``tcpq://HOST:PORT`` URL (LCM's default 7700 without one), or
    None for another provider.

    Parameters
    ----------
    url : str
        An LCM URL.

    Returns
    -------
    int or None
        The port, or None if ``url`` is not ``tcpq://``.
    """
    if not isinstance(url, str) or not url.startswith("tcpq://"):
        return None
    address = url[len("tcpq://"):].split("?", 1)[0]
    _, _, port = address.partition(":")
    try:
        return int(port) if port else 7700
    except ValueError:
        return None


class HubLink:
    """The socket of a tcpq client made between :meth:`before` and :meth:`after`, watched.

    Parameters
    ----------
    port : int
        The hub's port: the new socket connected to it is LCM's.
    """

    def __init__(self, port: int):
        self.port = port
        self.fd: int | None = None
        self.inode: int | None = None
        self._before: dict[int, int] = {}
        self.watched = os.path.isdir("/proc/self/fd")

    def before(self) -> None:
        """Note the sockets open before the LCM client is made."""
        self._before = _sockets()

    def after(self) -> bool:
        """Find the client's socket among the sockets opened since :meth:`before`.

        Returns
        -------
        bool
            True if found (or nothing can be watched here), False if the client has no
            connection (no hub listens on the port).
        """
        if not self.watched:
            return True
        for fd, inode in _sockets().items():
            if self._before.get(fd) != inode and _peer_port(fd) == self.port:
                self.fd, self.inode = fd, inode
                return True
        return False

    def lost(self) -> bool:
        """Whether the client's connection is gone.

        Returns
        -------
        bool
            True once LCM has closed the socket found by :meth:`after` (its descriptor is
            closed or now names another socket); always False where nothing is watched.
        """
        if not self.watched or self.fd is None:
            return False
        try:
            target = os.readlink(f"/proc/self/fd/{self.fd}")
        except OSError:
            return True
        return target != f"socket:[{self.inode}]"


class WatchedLcm(DrakeLcm):
    """A ``DrakeLcm`` whose ``HandleSubscriptions`` raises :class:`HubLost` (before LCM's C
    client would abort the process) once its ``tcpq://`` hub connection is gone.

    Parameters
    ----------
    url : str
        The LCM URL; for any provider but ``tcpq://`` nothing is watched.

    Raises
    ------
    ValueError
        ``tcpq://`` with no hub listening at ``url``.
    """

    def __init__(self, url: str):
        port = tcpq_port(url)
        self.link = HubLink(port if port is not None else -1)
        self.link.before()
        super().__init__(url)
        self.url = url
        if port is None:
            self.link.watched = False
        elif not self.link.after():
            raise ValueError(f"no hub listens at {url} (start drake-coop tcpq-hub first)")

    def check(self) -> None:
        """Raise :class:`HubLost` if the hub connection is gone."""
        if self.link.lost():
            raise HubLost(f"hub connection lost ({self.url})")

    def HandleSubscriptions(self, timeout_millis: int) -> int:  # noqa: N802 (Drake's name)
        """LCM's ``HandleSubscriptions``, the hub connection checked before and after.

        Parameters
        ----------
        timeout_millis : int
            The longest wait for a first message, ms.

        Returns
        -------
        int
            The messages handled.
        """
        self.check()
        count = super().HandleSubscriptions(timeout_millis)
        self.check()
        return count


def hub_monitor(lcm, system):
    """A Simulator monitor that fails the step after which ``lcm``'s hub connection is gone
    (``AdvanceTo`` then raises; see :func:`is_hub_failure`), before the next step's
    ``LcmInterfaceSystem`` pump would reach LCM's abort.

    Parameters
    ----------
    lcm : DrakeLcm
        The connection (a plain ``DrakeLcm``, not watched: the monitor never fails).
    system : System
        The system the failure is reported against (the Simulator's Diagram: newer Drake
        refuses an ``EventStatus.Failed`` without one).

    Returns
    -------
    Callable[[Context], EventStatus]
        For ``Simulator.set_monitor``.
    """
    from pydrake.systems.framework import EventStatus

    link = getattr(lcm, "link", None)

    def monitor(context):
        if link is not None and link.lost():
            return EventStatus.Failed(system, HUB_LOST_MARK)
        return EventStatus.Succeeded()

    return monitor


def is_hub_failure(exc: BaseException) -> bool:
    """Whether ``exc`` (raised by ``AdvanceTo``) is :func:`hub_monitor`'s failure.

    Parameters
    ----------
    exc : BaseException
        The exception.

    Returns
    -------
    bool
        True for :class:`HubLost` or a Simulator failure carrying :data:`HUB_LOST_MARK`.
    """
    return isinstance(exc, HubLost) or (isinstance(exc, RuntimeError)
                                        and HUB_LOST_MARK in str(exc))
