"""The hub of LCM's ``tcpq://`` provider, bound to 127.0.0.1: two processes on one machine
without multicast (``drake-coop tcpq-hub --port PORT``, then ``--lcm-url
tcpq://127.0.0.1:PORT`` for ``serve`` and ``sim-driver``).

Neither the drake wheel nor the ``lcm`` package ships a hub (LCM's own is the Java
``TCPService``), so this is one: LCM's tcpq protocol (``lcm/lcm_tcpq.c``), every integer a
big-endian uint32::

    client → hub   MAGIC_CLIENT, VERSION               (hub answers MAGIC_SERVER, VERSION)
    client → hub   SUBSCRIBE | UNSUBSCRIBE, len, channel (a regular expression)
    client → hub   PUBLISH, len, channel, size, data
    hub → client   PUBLISH, len, channel, size, data    (to every client with a matching
                                                         subscription, the sender too)

One thread, ``selectors``; ``TCP_NODELAY`` on every connection (the hub's own sends are not
delayed) and ``TCP_QUICKACK`` after every read (the clients' are not held by Nagle's
algorithm waiting for a delayed ACK); a client that breaks the protocol is disconnected. LCM's documentation says tcpq is
not meant for real-time traffic: its latency is measured, not assumed (docs/guide/real_robot.md).
"""

from __future__ import annotations

import re
import selectors
import socket
import struct
import threading

MAGIC_SERVER, MAGIC_CLIENT, VERSION = 0x287617FA, 0x287617FB, 0x0100
PUBLISH, SUBSCRIBE, UNSUBSCRIBE = 1, 2, 3
#: Linux's TCP_QUICKACK (None elsewhere). LCM's C client writes a message in five small
#: ``send`` calls without TCP_NODELAY: Nagle's algorithm holds each one until the previous is
#: acknowledged, and a delayed ACK (up to 40 ms) would hold the message that long.
_QUICKACK = getattr(socket, "TCP_QUICKACK", None)
#: Largest channel name and message accepted (bytes).
MAX_CHANNEL, MAX_DATA = 1024, 64 << 20


class _Client:
    def __init__(self, sock: socket.socket):
        self.sock = sock
        self.buffer = bytearray()
        self.greeted = False
        self.patterns: dict[str, re.Pattern] = {}

    def wants(self, channel: str) -> bool:
        return any(p.fullmatch(channel) for p in self.patterns.values())


class TcpqHub:
    """The hub, listening on ``127.0.0.1:port`` (0: any free port, see :attr:`port`).

    :meth:`serve_forever` runs it (until :meth:`stop`); :meth:`start` runs it in a thread.

    Parameters
    ----------
    port : int
        The TCP port (0: any free one).
    """

    def __init__(self, port: int = 7700):
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ValueError(f"port: an integer in [0, 65535] is required (got {port!r})")
        self._listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._listener.bind(("127.0.0.1", port))
        except OSError as exc:
            self._listener.close()
            raise ValueError(f"port: cannot listen on 127.0.0.1:{port} ({exc.strerror})") \
                from None
        self._listener.listen(16)
        self._listener.setblocking(False)
        self.port = self._listener.getsockname()[1]
        self._selector = selectors.DefaultSelector()
        self._selector.register(self._listener, selectors.EVENT_READ, None)
        self._clients: dict[socket.socket, _Client] = {}
        self._stop_r, self._stop_w = socket.socketpair()
        self._selector.register(self._stop_r, selectors.EVENT_READ, "stop")
        self._thread: threading.Thread | None = None
        self.relayed = 0

    @property
    def url(self) -> str:
        """The hub's LCM URL, ``tcpq://127.0.0.1:<port>``."""
        return f"tcpq://127.0.0.1:{self.port}"

    def start(self) -> "TcpqHub":
        """Run :meth:`serve_forever` in a daemon thread.

        Returns
        -------
        TcpqHub
            The hub.
        """
        self._thread = threading.Thread(target=self.serve_forever, daemon=True,
                                        name="tcpq-hub")
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the hub (and wait up to 5 s for its thread)."""
        self._stop_w.send(b"x")
        if self._thread is not None:
            self._thread.join(5)

    def serve_forever(self) -> None:
        """Relay every published message to every client subscribed to its channel (the sender
        too) until :meth:`stop`; then close every connection."""
        try:
            while True:
                for key, _ in self._selector.select():
                    if key.data == "stop":
                        return
                    if key.data is None:
                        self._accept()
                    else:
                        self._read(key.data)
        finally:
            for client in list(self._clients.values()):
                self._drop(client)
            self._selector.close()
            self._listener.close()
            self._stop_r.close()
            self._stop_w.close()

    def _accept(self) -> None:
        try:
            sock, _ = self._listener.accept()
        except OSError:
            return
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setblocking(True)
        client = _Client(sock)
        self._clients[sock] = client
        self._selector.register(sock, selectors.EVENT_READ, client)

    def _drop(self, client: _Client) -> None:
        if self._clients.pop(client.sock, None) is not None:
            self._selector.unregister(client.sock)
        client.sock.close()

    def _read(self, client: _Client) -> None:
        try:
            chunk = client.sock.recv(1 << 16)
            if _QUICKACK is not None:     # ACK at once: the client's Nagle waits for it
                client.sock.setsockopt(socket.IPPROTO_TCP, _QUICKACK, 1)
        except OSError:
            chunk = b""
        if not chunk:
            self._drop(client)
            return
        client.buffer += chunk
        try:
            self._parse(client)
        except (ValueError, OSError, re.error):
            self._drop(client)

    def _parse(self, client: _Client) -> None:
        buf = client.buffer
        while True:
            if not client.greeted:
                if len(buf) < 8:
                    return
                magic, _ = struct.unpack_from(">II", buf)
                if magic != MAGIC_CLIENT:
                    raise ValueError("not an LCM tcpq client")
                del buf[:8]
                client.sock.sendall(struct.pack(">II", MAGIC_SERVER, VERSION))
                client.greeted = True
                continue
            if len(buf) < 8:
                return
            kind, size = struct.unpack_from(">II", buf)
            if kind not in (PUBLISH, SUBSCRIBE, UNSUBSCRIBE) or size > MAX_CHANNEL:
                raise ValueError("bad tcpq message")
            if len(buf) < 8 + size:
                return
            channel = bytes(buf[8:8 + size]).decode("utf-8")
            if kind != PUBLISH:
                del buf[:8 + size]
                if kind == SUBSCRIBE:
                    client.patterns[channel] = re.compile(channel)
                else:
                    client.patterns.pop(channel, None)
                continue
            if len(buf) < 12 + size:
                return
            (length,) = struct.unpack_from(">I", buf, 8 + size)
            if length > MAX_DATA:
                raise ValueError("tcpq message too large")
            end = 12 + size + length
            if len(buf) < end:
                return
            frame = struct.pack(">I", PUBLISH) + bytes(buf[4:end])
            del buf[:end]
            for other in list(self._clients.values()):
                if other.greeted and other.wants(channel):
                    try:
                        other.sock.sendall(frame)
                        self.relayed += 1
                    except OSError:
                        self._drop(other)


def cmd_tcpq_hub(args) -> int:
    """``drake-coop tcpq-hub``: run the hub until Ctrl-C / SIGTERM.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit code: 0 stopped, 2 bad input.
    """
    import sys

    try:
        hub = TcpqHub(args.port)
    except ValueError as exc:
        from drake_coop.console import error

        return error(f"--{exc}")
    if not args.quiet:
        print(f"drake-coop: LCM tcpq hub on 127.0.0.1:{hub.port} (--lcm-url {hub.url})",
              file=sys.stderr)
    try:
        hub.serve_forever()
    except KeyboardInterrupt:
        pass
    return 0
