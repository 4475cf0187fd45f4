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
algorithm waiting for a delayed ACK). LCM's documentation says tcpq is not meant for
real-time traffic: its latency is measured, not assumed (docs/guide/real_robot.md).

No client can take the hub down or hold it: every socket is non-blocking; a client's
messages wait in its own send queue (at most :data:`MAX_QUEUE_BYTES` and
:data:`MAX_QUEUE_FRAMES`), and a client whose queue is full (it does not read) is dropped;
a subscription pattern is matched in linear time (:class:`~drake_coop.robot.channel_pattern.ChannelPattern`:
no backtracking, no recursion beyond :data:`~drake_coop.robot.channel_pattern.MAX_DEPTH`
groups; a pattern outside its syntax is ignored with one line on the hub's stderr, the client
kept); a client that breaks the protocol (bad magic, unknown kind, a channel longer than
:data:`MAX_CHANNEL`, a message longer than :data:`MAX_DATA`, more than :data:`MAX_PATTERNS`
subscriptions) is dropped; each client is read at most :data:`READ_CHUNK` bytes per turn
(one that floods cannot starve the others); beyond :data:`MAX_CLIENTS` connections a new one
is closed at once; and any error while serving one client drops that client only.
"""

from __future__ import annotations

import collections
import selectors
import socket
import struct
import sys
import threading

from drake_coop.robot.channel_pattern import ChannelPattern, PatternError

MAGIC_SERVER, MAGIC_CLIENT, VERSION = 0x287617FA, 0x287617FB, 0x0100
PUBLISH, SUBSCRIBE, UNSUBSCRIBE = 1, 2, 3
#: Linux's TCP_QUICKACK (None elsewhere). LCM's C client writes a message in five small
#: ``send`` calls without TCP_NODELAY: Nagle's algorithm holds each one until the previous is
#: acknowledged, and a delayed ACK (up to 40 ms) would hold the message that long.
_QUICKACK = getattr(socket, "TCP_QUICKACK", None)
#: Largest channel name or pattern (bytes) and message (bytes) accepted.
MAX_CHANNEL, MAX_DATA = 1024, 4 << 20
#: A client's send queue: beyond either bound the client is dropped (it does not read).
MAX_QUEUE_BYTES, MAX_QUEUE_FRAMES = 16 << 20, 20000
#: Most subscriptions of one client, and most clients at once.
MAX_PATTERNS, MAX_CLIENTS = 256, 256
#: Most bytes read from one client per turn of the loop.
READ_CHUNK = 1 << 16
#: Entries of a client's channel → match cache before it is cleared.
_CACHE = 4096


class _Client:
    def __init__(self, sock: socket.socket, name: str):
        self.sock = sock
        self.name = name
        self.buffer = bytearray()
        self.greeted = False
        self.patterns: dict[str, ChannelPattern | None] = {}   # None: refused, kept out
        self.cache: dict[str, bool] = {}
        self.queue: collections.deque = collections.deque()    # memoryviews to send
        self.queued = 0                                          # their bytes
        self.writing = False                                     # EVENT_WRITE registered

    def wants(self, channel: str) -> bool:
        hit = self.cache.get(channel)
        if hit is None:
            if len(self.cache) >= _CACHE:
                self.cache.clear()
            hit = self.cache[channel] = any(p is not None and p.fullmatch(channel)
                                            for p in self.patterns.values())
        return hit


class TcpqHub:
    """The hub, listening on ``127.0.0.1:port`` (0: any free port, see :attr:`port`).

    :meth:`serve_forever` runs it (until :meth:`stop`); :meth:`start` runs it in a thread.
    ``dropped`` counts the clients dropped for a fault of theirs, ``refused`` the patterns
    refused.

    Parameters
    ----------
    port : int
        The TCP port (0: any free one).
    log : Callable[[str], None] or None
        Receives one line per dropped client or refused pattern (None: nothing said).
    """

    def __init__(self, port: int = 7700, log=None):
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
        self._listener.listen(128)
        self._listener.setblocking(False)
        self.port = self._listener.getsockname()[1]
        self._selector = selectors.DefaultSelector()
        self._selector.register(self._listener, selectors.EVENT_READ, None)
        self._clients: dict[socket.socket, _Client] = {}
        self._stop_r, self._stop_w = socket.socketpair()
        self._selector.register(self._stop_r, selectors.EVENT_READ, "stop")
        self._thread: threading.Thread | None = None
        self._log = log
        self.relayed = 0
        self.dropped = 0
        self.refused = 0

    @property
    def url(self) -> str:
        """The hub's LCM URL, ``tcpq://127.0.0.1:<port>``."""
        return f"tcpq://127.0.0.1:{self.port}"

    def start(self) -> "TcpqHub":
        """Run :meth:`serve_forever` in a daemon thread.

        Returns
        -------
        TcpqHub
            This hub, serving in its thread (for ``hub = TcpqHub(0).start()``).
        """
        self._thread = threading.Thread(target=self.serve_forever, daemon=True,
                                        name="tcpq-hub")
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the hub (and wait up to 5 s for its thread)."""
        try:
            self._stop_w.send(b"x")
        except OSError:
            pass                                   # already stopped
        if self._thread is not None:
            self._thread.join(5)

    def serve_forever(self) -> None:
        """Relay every published message to every client subscribed to its channel (the sender
        too) until :meth:`stop`; then close every connection."""
        try:
            while True:
                for key, events in self._selector.select():
                    if key.data == "stop":
                        return
                    if key.data is None:
                        self._accept()
                        continue
                    client = key.data
                    if client.sock not in self._clients:
                        continue                   # dropped earlier in this turn
                    try:
                        if events & selectors.EVENT_WRITE:
                            self._flush(client)
                        if events & selectors.EVENT_READ and client.sock in self._clients:
                            self._read(client)
                    except Exception as exc:       # this client's fault or not: it goes
                        self._drop(client, f"{type(exc).__name__}: {exc}")
        finally:
            for client in list(self._clients.values()):
                self._drop(client)
            self._selector.close()
            self._listener.close()
            self._stop_r.close()
            self._stop_w.close()

    def _say(self, text: str) -> None:
        if self._log is not None:
            self._log(" ".join(str(text).split())[:300])

    def _accept(self) -> None:
        for _ in range(64):                        # a burst of connections, then the others
            try:
                sock, peer = self._listener.accept()
            except OSError:
                return
            if len(self._clients) >= MAX_CLIENTS:
                sock.close()
                self._say(f"tcpq-hub: refused a connection: {MAX_CLIENTS} clients already")
                continue
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            sock.setblocking(False)
            client = _Client(sock, f"{peer[0]}:{peer[1]}")
            self._clients[sock] = client
            self._selector.register(sock, selectors.EVENT_READ, client)

    def _drop(self, client: _Client, why: str | None = None) -> None:
        if self._clients.pop(client.sock, None) is not None:
            self._selector.unregister(client.sock)
            if why is not None:
                self.dropped += 1
                self._say(f"tcpq-hub: dropped client {client.name}: {why}")
        client.queue.clear()
        client.sock.close()

    def _read(self, client: _Client) -> None:
        try:
            chunk = client.sock.recv(READ_CHUNK)
            if _QUICKACK is not None:     # ACK at once: the client's Nagle waits for it
                client.sock.setsockopt(socket.IPPROTO_TCP, _QUICKACK, 1)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            chunk = b""
        if not chunk:
            self._drop(client)                    # it left
            return
        client.buffer += chunk
        try:
            self._parse(client)
        except (ValueError, UnicodeDecodeError) as exc:
            self._drop(client, str(exc))

    def _send(self, client: _Client, frame: bytes) -> None:
        """Queue ``frame`` for ``client`` and send what the socket takes now; a client whose
        queue is full is dropped (it does not read)."""
        if client.queued + len(frame) > MAX_QUEUE_BYTES or len(client.queue) >= MAX_QUEUE_FRAMES:
            self._drop(client, f"its send queue is full ({client.queued} bytes in "
                               f"{len(client.queue)} messages): it does not read")
            return
        client.queue.append(memoryview(frame))
        client.queued += len(frame)
        if len(client.queue) == 1:
            self._flush(client)

    def _flush(self, client: _Client) -> None:
        """Send from ``client``'s queue until the socket would block; EVENT_WRITE while some
        is left."""
        queue = client.queue
        while queue:
            try:
                sent = client.sock.send(queue[0])
            except (BlockingIOError, InterruptedError):
                break
            except OSError as exc:
                self._drop(client, f"send: {exc.strerror or exc}")
                return
            client.queued -= sent
            if sent == len(queue[0]):
                queue.popleft()
            else:
                queue[0] = queue[0][sent:]
        want = bool(queue)
        if want != client.writing and client.sock in self._clients:
            client.writing = want
            self._selector.modify(client.sock, selectors.EVENT_READ
                                  | (selectors.EVENT_WRITE if want else 0), client)

    def _subscribe(self, client: _Client, kind: int, channel: str) -> None:
        if kind == UNSUBSCRIBE:
            client.patterns.pop(channel, None)
        elif channel not in client.patterns:
            if len(client.patterns) >= MAX_PATTERNS:
                raise ValueError(f"more than {MAX_PATTERNS} subscriptions")
            try:
                client.patterns[channel] = ChannelPattern(channel)
            except PatternError as exc:
                client.patterns[channel] = None   # kept out: nothing matches it
                self.refused += 1
                self._say(f"tcpq-hub: client {client.name}: subscription ignored: {exc}")
        client.cache.clear()

    def _parse(self, client: _Client) -> None:
        buf = client.buffer
        while client.sock in self._clients:
            if not client.greeted:
                if len(buf) < 8:
                    return
                magic, _ = struct.unpack_from(">II", buf)
                if magic != MAGIC_CLIENT:
                    raise ValueError("not an LCM tcpq client")
                del buf[:8]
                client.greeted = True
                self._send(client, struct.pack(">II", MAGIC_SERVER, VERSION))
                continue
            if len(buf) < 8:
                return
            kind, size = struct.unpack_from(">II", buf)
            if kind not in (PUBLISH, SUBSCRIBE, UNSUBSCRIBE):
                raise ValueError(f"bad tcpq message kind {kind}")
            if size > MAX_CHANNEL:
                raise ValueError(f"a channel of {size} bytes (at most {MAX_CHANNEL})")
            if len(buf) < 8 + size:
                return
            channel = bytes(buf[8:8 + size]).decode("utf-8")
            if kind != PUBLISH:
                del buf[:8 + size]
                self._subscribe(client, kind, channel)
                continue
            if len(buf) < 12 + size:
                return
            (length,) = struct.unpack_from(">I", buf, 8 + size)
            if length > MAX_DATA:
                raise ValueError(f"a message of {length} bytes (at most {MAX_DATA})")
            end = 12 + size + length
            if len(buf) < end:
                return
            frame = struct.pack(">I", PUBLISH) + bytes(buf[4:end])
            del buf[:end]
            for other in list(self._clients.values()):
                if other.greeted and other.wants(channel):
                    self._send(other, frame)
                    self.relayed += 1


def _background_log(stream, size: int = 100):
    """A ``log`` callable that never blocks the hub: lines go through a bounded queue to a
    daemon thread that writes them (a full queue — a stream nobody reads, a pipe full —
    drops the line)."""
    import queue

    lines: queue.Queue = queue.Queue(size)

    def write() -> None:
        while True:
            line = lines.get()
            try:
                print(line, file=stream, flush=True)
            except (OSError, ValueError):
                return

    threading.Thread(target=write, daemon=True, name="tcpq-hub-log").start()

    def log(line: str) -> None:
        try:
            lines.put_nowait(line)
        except queue.Full:
            pass
    return log


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
    try:
        hub = TcpqHub(args.port, log=None if args.quiet else _background_log(sys.stderr))
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
