"""A driver's status read defensively: the raw LCM bytes checked before anything reaches the
controller.

Drake's ``PandaStatusReceiver`` reads a status of ``num_joints = 0`` as ``q = 0`` (inside the
CRS arms' joint ranges, so a range check lets it through), and the message's generated Python
decoder raises on truncated or foreign bytes. Here the subscriber keeps the bytes as they came
(:class:`RawMessage`), and :func:`check_panda_status` reads them field by field against the
``lcmt_panda_status`` layout of an ``n``-joint arm::

    fingerprint (8) | utime int64 | num_joints int32 | 8 arrays of num_joints doubles
    | control_command_success_rate double | robot_mode int8 | robot_utime int64
    | control_mode int8                                         (38 + 64 n bytes)

giving the reading, the stamp and a fault code of :data:`~drake_coop.control.watchdog.
STATUS_FAULTS` for the :class:`~drake_coop.control.watchdog.Watchdog`'s ``status`` input.
"""

from __future__ import annotations

import math
import struct

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem

from drake import lcmt_panda_status
from drake_coop.control.watchdog import STATUS_NONE, STATUS_OK

#: The 8-byte fingerprint that starts every ``lcmt_panda_status``.
PANDA_STATUS_FINGERPRINT = lcmt_panda_status._get_packed_fingerprint()
#: Bytes before the first array (fingerprint, utime, num_joints) and after the last one.
_HEAD, _TAIL = 20, 18


def panda_status_size(n: int) -> int:
    """The bytes of an encoded ``lcmt_panda_status`` of ``n`` joints.

    Parameters
    ----------
    n : int
        The arm's joints.
    """
    return _HEAD + 64 * n + _TAIL


class RawMessage:
    """An LCM message's bytes as received: the value of a subscriber that decodes nothing
    (``LcmSubscriberSystem.Make(channel, RawMessage, lcm)``; ``data`` empty before the first
    message). Shared, not copied, when Drake copies the subscriber's state: it is never
    modified.

    Parameters
    ----------
    data : bytes
        The message's bytes.
    """

    __slots__ = ("data",)

    def __init__(self, data: bytes = b""):
        self.data = data

    @staticmethod
    def decode(data) -> "RawMessage":
        """The message of ``data`` (LCM's decoding protocol: the bytes kept as they are).

        Parameters
        ----------
        data : bytes-like
            The bytes received.
        """
        return RawMessage(bytes(data))

    def encode(self) -> bytes:
        """The message's bytes (LCM's encoding protocol).
        """
        return self.data

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self


def check_panda_status(data: bytes, n: int) -> tuple[np.ndarray, float, int, float]:
    """``(q, stamp, fault, value)`` of the bytes of one status for an ``n``-joint arm.

    ``q`` is NaN unless ``fault`` is ``STATUS_OK``; ``stamp`` is ``utime · 1e-6`` (NaN before
    the stamp is readable); ``fault`` and ``value`` as the watchdog's ``status`` input
    (:data:`~drake_coop.control.watchdog.STATUS_FAULTS`). Never raises.

    Parameters
    ----------
    data : bytes
        The status's bytes.
    n : int
        The arm's joints.

    Returns
    -------
    q : numpy.ndarray
        Joint positions (n,), rad.
    stamp : float
        The status's time, s.
    fault : int
        The fault code.
    value : float
        The fault's value.
    """
    size = len(data)
    if size == 0:
        return _nan(n), math.nan, STATUS_NONE, 0.0
    if size < 8 or data[:8] != PANDA_STATUS_FINGERPRINT:
        return _nan(n), math.nan, 2, float(size)
    if size < _HEAD:
        return _nan(n), math.nan, 3, float(size)
    utime, joints = struct.unpack_from(">qi", data, 8)
    stamp = utime * 1e-6
    if joints != n:
        return _nan(n), stamp, 4, float(joints)
    if size < panda_status_size(n):
        return _nan(n), stamp, 3, float(size)
    if size > panda_status_size(n):
        return _nan(n), stamp, 5, float(size)
    q = struct.unpack_from(f">{n}d", data, _HEAD)
    if not all(map(math.isfinite, q)):
        return _nan(n), stamp, 6, 0.0
    return np.array(q), stamp, STATUS_OK, 0.0


def _nan(n: int) -> np.ndarray:
    return np.full(n, math.nan)


def panda_status_ok(data: bytes, n: int) -> bool:
    """Whether :func:`check_panda_status` would find the bytes a valid status of an
    ``n``-joint arm (the same checks, on plain bytes and floats: cheap enough for every
    message at the driver's rate).

    Parameters
    ----------
    data : bytes
        The status's bytes.
    n : int
        The arm's joints.

    Returns
    -------
    bool
        True for a valid status.
    """
    if len(data) != _HEAD + 64 * n + _TAIL or data[:8] != PANDA_STATUS_FINGERPRINT:
        return False
    if struct.unpack_from(">i", data, 16)[0] != n:
        return False
    return all(map(math.isfinite, struct.unpack_from(f">{n}d", data, _HEAD)))


def first_bad_panda_status(messages: list[bytes], n: int) -> int:
    """The index of the first of ``messages`` that :func:`panda_status_ok` rejects (-1: none).

    The same checks, cheaper on messages that pass them: each message's size, fingerprint and
    joint count compared as bytes, and the first byte of every position (sign and high
    exponent bits) of all of them at once: a double is finite unless that byte is ``0x7f``
    or ``0xff`` (then, as on any other doubt, the messages are checked one by one with
    :func:`panda_status_ok`).

    Parameters
    ----------
    messages : list of bytes
        The raw ``lcmt_panda_status`` messages, in their order of arrival.
    n : int
        The arm's joint count.

    Returns
    -------
    int
        The index of the first rejected message, -1 when every one passes.
    """
    size, end = panda_status_size(n), _HEAD + 8 * n
    fingerprint, joints = PANDA_STATUS_FINGERPRINT, struct.pack(">i", n)
    if all(len(d) == size and d[:8] == fingerprint and d[16:_HEAD] == joints
           for d in messages):
        high = b"".join([d[_HEAD:end:8] for d in messages])
        if b"\x7f" not in high and b"\xff" not in high:
            return -1
    for i, data in enumerate(messages):
        if not panda_status_ok(data, n):
            return i
    return -1


class CheckedStatusReceiver(LeafSystem):
    """One arm's status, checked: the reading and ``[stamp, fault, value]`` of the newest raw
    ``lcmt_panda_status`` (:func:`check_panda_status`).

    .. pydrake_system::

        name: CheckedStatusReceiver
        input_ports:
        - message
        output_ports:
        - position_measured
        - status

    ``position_measured`` is NaN unless the status is valid; ``status`` feeds the
    :class:`~drake_coop.control.watchdog.Watchdog`. Each message is read once (the result is
    kept with the message it came from).

    Parameters
    ----------
    n : int
        The arm's joints.
    """

    def __init__(self, n: int):
        super().__init__()
        self._n = int(n)
        self._in = self.DeclareAbstractInputPort("message", AbstractValue.Make(RawMessage()))
        self._memo: tuple[object, tuple] | None = None
        self.DeclareVectorOutputPort("position_measured", self._n, self._calc_q)
        self.DeclareVectorOutputPort("status", 3, self._calc_status)

    def get_message_input_port(self):
        return self._in

    def get_position_measured_output_port(self):
        return self.GetOutputPort("position_measured")

    def get_status_output_port(self):
        return self.GetOutputPort("status")

    def _read(self, context: Context) -> tuple:
        msg = self._in.Eval(context)
        memo = self._memo
        if memo is not None and memo[0] is msg:
            return memo[1]
        result = check_panda_status(msg.data, self._n)
        self._memo = (msg, result)
        return result

    def _calc_q(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self._read(context)[0])

    def _calc_status(self, context: Context, output: BasicVector) -> None:
        _, stamp, fault, value = self._read(context)
        output.SetFromVector([stamp, float(fault), value])
