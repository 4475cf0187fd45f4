"""No client takes the tcpq hub down or holds it (:mod:`drake_coop.robot.tcpq_hub`): while
a hostile client does its worst — 500 nested groups, a catastrophic-backtracking pattern, a
reader that never reads, a client flooding its own channel, garbage bytes, huge lengths, 50
connections — two well-behaved clients keep exchanging messages through the hub.

The hub runs in a thread of the test; the well-behaved clients are plain sockets speaking
LCM's tcpq protocol (Drake's own client, run in another process, is in the last test). The
timeouts are seconds long: they detect a frozen hub, they do not measure latency
(``bench/`` does)."""

import socket
import struct
import subprocess
import sys
import time

import pytest

from drake_coop.robot.channel_pattern import ChannelPattern, PatternError
from drake_coop.robot.tcpq_hub import (
    MAGIC_CLIENT,
    MAGIC_SERVER,
    MAX_CLIENTS,
    PUBLISH,
    SUBSCRIBE,
    UNSUBSCRIBE,
    VERSION,
    TcpqHub,
)

FREEZE = 5.0            # s: longer than this without an answer is a frozen hub


class Client:
    """A tcpq client on a plain socket."""

    def __init__(self, port, greet=True):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=FREEZE)
        self.buf = b""
        if greet:
            self.sock.sendall(struct.pack(">II", MAGIC_CLIENT, VERSION))
            assert self._exactly(8) == struct.pack(">II", MAGIC_SERVER, VERSION)

    def _exactly(self, n):
        while len(self.buf) < n:
            chunk = self.sock.recv(1 << 16)
            if not chunk:
                raise ConnectionError("closed by the hub")
            self.buf += chunk
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def subscribe(self, pattern, kind=SUBSCRIBE):
        data = pattern.encode() if isinstance(pattern, str) else pattern
        self.sock.sendall(struct.pack(">II", kind, len(data)) + data)

    def publish(self, channel, data):
        c = channel.encode()
        self.sock.sendall(struct.pack(">II", PUBLISH, len(c)) + c
                          + struct.pack(">I", len(data)) + data)

    def receive(self):
        kind, size = struct.unpack(">II", self._exactly(8))
        assert kind == PUBLISH
        channel = self._exactly(size).decode()
        (length,) = struct.unpack(">I", self._exactly(4))
        return channel, self._exactly(length)

    def closed_by_hub(self):
        try:
            while True:
                if not self.sock.recv(1 << 16):
                    return True
        except (ConnectionResetError, BrokenPipeError):
            return True
        except socket.timeout:
            return False


@pytest.fixture
def hub():
    lines = []
    h = TcpqHub(0, log=lines.append).start()
    h.lines = lines
    yield h
    h.stop()


def roundtrip(hub, n=3, tag=b""):
    """Two fresh well-behaved clients: b subscribes, a publishes n messages, b gets them all
    in order (each within FREEZE s); the sender, subscribed, gets its own too."""
    a, b = Client(hub.port), Client(hub.port)
    b.subscribe("GOOD_.*")
    a.subscribe("GOOD_A")
    settle(hub)
    sent = [tag + bytes([k]) * (k + 1) for k in range(n)]
    for p in sent:
        a.publish("GOOD_A", p)
    assert [b.receive() for _ in sent] == [("GOOD_A", p) for p in sent]
    assert [a.receive() for _ in sent] == [("GOOD_A", p) for p in sent]
    a.sock.close()
    b.sock.close()


def settle(hub):
    """The subscriptions sent so far have reached the hub: a probe's own message comes back."""
    probe = Client(hub.port)
    probe.subscribe("PROBE")
    probe.publish("PROBE", b"p")
    assert probe.receive() == ("PROBE", b"p")
    probe.sock.close()


def test_500_nested_groups_are_refused_and_the_hub_relays_on(hub):
    bad = Client(hub.port)
    bad.subscribe("(" * 500 + "a" + ")" * 500)
    bad.subscribe("(" * 100 + "a" + ")" * 100)       # within the length, too deep
    roundtrip(hub)
    assert hub.refused == 2 and any("deeper" in line for line in hub.lines), hub.lines
    bad.publish("GOOD_A", b"still a client")         # kept: only its patterns were refused


def test_a_catastrophic_backtracking_pattern_matches_in_linear_time(hub):
    bad = Client(hub.port)
    bad.subscribe("(a|a)*b")
    bad.subscribe("(a*)*b")
    bad.subscribe("(.*a){12}")                       # refused: bounded repetition
    settle(hub)
    a, b = Client(hub.port), Client(hub.port)
    b.subscribe("a*")
    settle(hub)
    long_name = "a" * 1000                            # within MAX_CHANNEL
    a.publish(long_name, b"x")
    assert b.receive() == (long_name, b"x")           # both patterns tried on it: no match
    roundtrip(hub)


def test_a_client_that_never_reads_is_dropped_and_never_blocks_the_others(hub):
    lazy = Client(hub.port)
    lazy.subscribe("FLOOD")
    lazy.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    a, b = Client(hub.port), Client(hub.port)
    b.subscribe("GOOD_B")
    settle(hub)
    payload = b"z" * 60000
    dropped = False
    for k in range(2000):                 # 120 MB offered to a reader that never reads
        a.publish("FLOOD", payload)
        if k % 50 == 0:
            a.publish("GOOD_B", bytes([k % 256]))
            assert b.receive() == ("GOOD_B", bytes([k % 256]))   # the hub is not held
        if hub.dropped:
            dropped = True
            break
    assert dropped and any("does not read" in line for line in hub.lines), hub.lines
    roundtrip(hub)


def test_a_client_flooding_its_own_channel_is_dropped_and_the_others_go_on(hub):
    flood = Client(hub.port)
    flood.subscribe("SELF")
    settle(hub)
    flood.sock.setblocking(False)
    frame = struct.pack(">II", PUBLISH, 4) + b"SELF" + struct.pack(">I", 8000) + b"f" * 8000
    end = time.monotonic() + 30
    while not hub.dropped and time.monotonic() < end:
        try:
            flood.sock.send(frame * 8)
        except (BlockingIOError, ConnectionError, OSError):
            time.sleep(0.001)
    assert hub.dropped == 1
    roundtrip(hub)


@pytest.mark.parametrize("garbage", [
    b"\x00" * 64,                                              # bad magic
    b"GET / HTTP/1.0\r\n\r\n",
    bytes(range(256)) * 4,
])
def test_garbage_bytes_drop_that_client_only(hub, garbage):
    bad = Client(hub.port, greet=False)
    bad.sock.sendall(garbage)
    assert bad.closed_by_hub()
    roundtrip(hub)


@pytest.mark.parametrize("frame", [
    struct.pack(">II", 99, 4) + b"ABCD",                       # unknown kind
    struct.pack(">II", SUBSCRIBE, 0xFFFFFFFF),                 # a 4 GB pattern
    struct.pack(">II", PUBLISH, 0xFFFFFFF0),                   # a 4 GB channel
    struct.pack(">II", PUBLISH, 1) + b"C" + struct.pack(">I", 0xFFFFFFFF),   # a 4 GB message
    struct.pack(">II", SUBSCRIBE, 2) + b"\xff\xfe",            # not UTF-8
])
def test_huge_lengths_and_bad_frames_drop_that_client_only(hub, frame):
    bad = Client(hub.port)
    bad.sock.sendall(frame)
    assert bad.closed_by_hub()
    roundtrip(hub)


def test_too_many_subscriptions_drop_that_client(hub):
    bad = Client(hub.port)
    try:
        for k in range(300):
            bad.subscribe(f"CH{k}")
    except (ConnectionResetError, BrokenPipeError):
        pass                         # dropped while still sending: what the test asks
    else:
        assert bad.closed_by_hub()
    roundtrip(hub)


def test_a_half_sent_message_holds_nobody(hub):
    slow = Client(hub.port)
    slow.sock.sendall(struct.pack(">II", PUBLISH, 4) + b"GOOD" + struct.pack(">I", 1000)
                      + b"only part")
    roundtrip(hub)
    slow.sock.close()


def test_fifty_connections_and_the_hub_relays_between_two_more(hub):
    idle = [Client(hub.port, greet=k % 2 == 0) for k in range(50)]
    for c in idle[::2]:
        c.subscribe("GOOD_.*")                        # they get the messages, never read
    roundtrip(hub, n=20)
    for c in idle:
        c.sock.close()
    roundtrip(hub)


def test_beyond_the_client_bound_a_connection_is_closed_and_the_hub_goes_on(monkeypatch):
    from drake_coop.robot import tcpq_hub

    monkeypatch.setattr(tcpq_hub, "MAX_CLIENTS", 4)
    h = TcpqHub(0).start()
    try:
        held = [Client(h.port) for _ in range(2)]
        extra = [socket.create_connection(("127.0.0.1", h.port), timeout=FREEZE)
                 for _ in range(3)]
        assert extra[2].recv(1) == b""               # the fifth: closed at once
        extra[0].settimeout(0.2)
        with pytest.raises(socket.timeout):
            extra[0].recv(1)                          # the third: kept
        for s in extra:
            s.close()
        for c in held:
            c.sock.close()
        time.sleep(0.2)                               # the hub sees them leave
        roundtrip(h)                                  # three connections again
    finally:
        h.stop()
    assert MAX_CLIENTS >= 64


def test_unsubscribe_stops_the_relay(hub):
    a, b = Client(hub.port), Client(hub.port)
    b.subscribe("X.*")
    b.subscribe("Y")
    settle(hub)
    a.publish("XA", b"1")
    assert b.receive() == ("XA", b"1")
    b.subscribe("X.*", kind=UNSUBSCRIBE)
    settle(hub)
    a.publish("XA", b"2")
    a.publish("Y", b"3")
    assert b.receive() == ("Y", b"3")                 # XA's second message never came


@pytest.mark.parametrize("pattern, yes, no", [
    ("DRAKE_COOP_STOP", ["DRAKE_COOP_STOP"], ["DRAKE_COOP_STOPX", "XDRAKE_COOP_STOP"]),
    (".*", ["", "ANY"], []),
    ("PANDA_STATUS_.*", ["PANDA_STATUS_robot1"], ["PANDA_COMMAND_robot1"]),
    ("^A(B|C)+D?$", ["AB", "ACBD", "ABCBCB"], ["A", "AD", "ABE"]),
    ("[a-c_]x[^0-9]", ["_xa", "bx!"], ["dxa", "ax5"]),
    ("A\\.B", ["A.B"], ["AxB"]),
    ("a*", ["", "aaa"], ["ab"]),
])
def test_channel_patterns_match_as_a_regular_expression_engine_does(pattern, yes, no):
    import re

    compiled = ChannelPattern(pattern)
    for name in yes + no:            # the independent computation: Python's re
        assert compiled.fullmatch(name) == bool(re.fullmatch(pattern.strip("^$"), name))
        assert compiled.fullmatch(name) == (name in yes)


def test_random_patterns_agree_with_pythons_re():
    """Random patterns of the accepted syntax on random names: the automaton's answer is
    Python's backtracking engine's."""
    import random
    import re

    rng = random.Random(7)

    def gen(d=0):
        r = rng.random()
        if d > 3 or r < 0.35:
            return rng.choice(["a", "b", "_", "\\.", ".", "[ab]", "[^a]", "[a-c_]"])
        if r < 0.55:
            return gen(d + 1) + gen(d + 1)
        if r < 0.7:
            return "(" + gen(d + 1) + "|" + gen(d + 1) + ")"
        if r < 0.85:
            return "(" + gen(d + 1) + ")" + rng.choice("*+?")
        return gen(d + 1) + gen(d + 1) + gen(d + 1)

    for _ in range(500):
        pattern = gen()
        ours, theirs = ChannelPattern(pattern), re.compile(pattern)
        for _ in range(10):
            name = "".join(rng.choice("abc_.") for _ in range(rng.randint(0, 8)))
            assert ours.fullmatch(name) == bool(theirs.fullmatch(name)), (pattern, name)


@pytest.mark.parametrize("pattern, why", [
    ("(" * 500 + ")" * 500, "at most"),
    ("(" * 20 + "a" + ")" * 20, "deeper"),
    ("a{1,3}", "bounded repetition"),
    ("\\d+", "escape"),
    ("a**", "quantifier on a quantifier"),
    ("(a", "unclosed group"),
    ("a)", "unopened group"),
    ("[a", "unclosed bracket"),
    ("[z-a]", "reversed"),
    ("[[:alpha:]]", "character classes"),
    ("a^b", "allowed only at its ends"),
])
def test_patterns_outside_the_syntax_are_refused_in_one_line(pattern, why):
    with pytest.raises(PatternError, match=why) as info:
        ChannelPattern(pattern)
    assert "\n" not in str(info.value)


def test_drakes_own_subscribers_survive_a_hostile_client_of_the_hub(tmp_path):
    """The hub as its own process (``drake-coop tcpq-hub``) and Drake's LCM client in a
    subscriber-only process (the kind LCM's C client aborts when the hub dies): a client
    sends 500 nested groups and garbage; the hub stays up and the subscriber gets the message
    published after them, exit 0."""
    hub = subprocess.Popen([sys.executable, "-m", "drake_coop", "tcpq-hub", "--port", "0"],
                           stderr=subprocess.PIPE, text=True)
    try:
        url = hub.stderr.readline().split("--lcm-url ")[1].rstrip(")\n")
        port = int(url.rsplit(":", 1)[1])
        script = (
            "import sys, time\n"
            "from pydrake.lcm import DrakeLcm\n"
            f"lcm = DrakeLcm({url!r}); got = []\n"
            "lcm.Subscribe('AFTER', lambda d: got.append(bytes(d)))\n"
            "print('ready', flush=True)\n"
            "end = time.time() + 30\n"
            "while not got and time.time() < end: lcm.HandleSubscriptions(50)\n"
            "sys.exit(0 if got == [b'ok'] else 3)\n")
        sub = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                               text=True)
        assert sub.stdout.readline().strip() == "ready"
        bad = Client(port)
        bad.subscribe("(" * 500 + ")" * 500)
        bad.subscribe("(a|a)*b")
        bad.sock.sendall(b"\xde\xad\xbe\xef" * 100)
        assert bad.closed_by_hub()
        time.sleep(0.5)                               # the subscriber's SUBSCRIBE is in
        good = Client(port)
        good.publish("AFTER", b"ok")
        assert sub.wait(60) == 0
        assert hub.poll() is None                     # the hub is up
    finally:
        hub.terminate()
        hub.wait(10)
