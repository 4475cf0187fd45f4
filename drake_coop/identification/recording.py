"""A recording of what the wire carried during an identification experiment, in one format,
and the identification from it.

**The format** (one ``.npz`` file, NumPy's zip of arrays; :func:`write_recording`,
:func:`read_recording`): ``format`` = :data:`FORMAT`; ``meta``, a JSON text (``robots``: the
arms in the file, in order; per arm its ``source`` — ``wire`` or ``simulation`` —, its
scenario ``index``, the ``status_channel`` and ``command_channel`` and the ``excitation``
followed: ``q0``, ``a``, ``b``, ``period``, ``duration``, ``ramp``); and per arm ``NAME``,
one row per control tick ``k``:

``NAME/t`` (N,)
    ``t_k = k h``, s, from the excitation's start;
``NAME/q`` (N, n)
    the joint positions of the status the tick read (``lcmt_panda_status.joint_position``),
    rad;
``NAME/tau`` (N, n)
    the torque the tick's command carried (``lcmt_panda_command.joint_torque``, as encoded),
    N·m;
``NAME/status_utime``, ``NAME/command_utime`` (N,)
    the two messages' ``utime`` stamps, µs (int64);
``NAME/arrival_s`` (N,)
    when the status arrived in the recording process (``time.perf_counter``, s; NaN when the
    driver is stepped in lockstep);
``NAME/h`` ()
    the control period, s; ``NAME/torque_limits`` (n,): the limits the commands were clipped
    to, N·m (``inf``: none).

:func:`~drake_coop.identification.report.identify_recording` identifies an arm from it through
:func:`~drake_coop.identification.report.identify_from_data`, exactly the path of the
simulated experiment (:func:`~drake_coop.identification.report.identify_robot`): a recording
of the simulated experiment (:func:`recording_from_data`) identifies to the same model.
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from drake_coop.identification.collect import ExcitationData
from drake_coop.identification.excitation import FourierExcitation

__all__ = ["FORMAT", "WireRecording", "read_recording", "recording_from_data", "write_recording"]

#: The format's name and version, stored in the file.
FORMAT = "drake_coop.wire_recording/1"
#: The per-arm arrays of the format.
ARRAYS = ("t", "q", "tau", "status_utime", "command_utime", "arrival_s", "h", "torque_limits")


@dataclass
class WireRecording:
    """One arm's rows of a recording (see the module's docstring for each field).

    Attributes
    ----------
    robot : str
        The arm's name.
    index : int
        Its index in the scenario (0-based).
    excitation : FourierExcitation
        The excitation followed.
    t, q, tau : numpy.ndarray
        Tick times (N,), s; status positions (N, n), rad; commanded torques (N, n), N·m.
    status_utime, command_utime : numpy.ndarray
        The messages' stamps (N,), µs.
    arrival_s : numpy.ndarray
        The statuses' arrival (N,), s (NaN in lockstep).
    h : float
        The control period, s.
    torque_limits : numpy.ndarray
        The commands' limits (n,), N·m.
    source : str
        ``wire`` or ``simulation``.
    channels : list of str
        The status and command channels (empty for a simulation).
    """

    robot: str
    index: int
    excitation: FourierExcitation
    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    status_utime: np.ndarray
    command_utime: np.ndarray
    arrival_s: np.ndarray
    h: float
    torque_limits: np.ndarray
    source: str = "wire"
    channels: list[str] = field(default_factory=list)

    def data(self) -> ExcitationData:
        """The rows as the estimator reads the simulated experiment's (no truth: NaN).

        Returns
        -------
        ExcitationData
            ``t``, ``q``, ``tau``, ``h``, ``torque_limits``.
        """
        nan = np.full_like(self.q, math.nan)
        return ExcitationData(t=self.t, q=self.q, tau=self.tau, h=self.h,
                              torque_limits=self.torque_limits, q_true=nan, v_true=nan)


def _excitation_meta(e: FourierExcitation) -> dict:
    return {"q0": e.q0.tolist(), "a": e.a.tolist(), "b": e.b.tolist(), "period": e.period,
            "duration": e.duration, "ramp": e.ramp}


def recording_from_data(robot: str, index: int, excitation: FourierExcitation,
                        data: ExcitationData) -> WireRecording:
    """The simulated experiment's data as a recording (``source: simulation``; stamps from
    ``t``).

    Parameters
    ----------
    robot : str
        The arm's name.
    index : int
        Its index in the scenario.
    excitation : FourierExcitation
        The excitation followed.
    data : ExcitationData
        The simulated experiment's records.

    Returns
    -------
    WireRecording
        The simulated experiment's data in the wire recording's format.
    """
    stamps = np.round(np.asarray(data.t) * 1e6).astype(np.int64)
    return WireRecording(robot=robot, index=index, excitation=excitation, t=data.t, q=data.q,
                         tau=data.tau, status_utime=stamps, command_utime=stamps.copy(),
                         arrival_s=np.full(len(data.t), math.nan), h=float(data.h),
                         torque_limits=np.asarray(data.torque_limits, float),
                         source="simulation")


def write_recording(path: str | Path, recordings: list[WireRecording]) -> None:
    """Write ``recordings`` to ``path`` (``.npz``), whole or not at all.

    Parameters
    ----------
    path : str or Path
        The file.
    recordings : list of WireRecording
        One per arm.
    """
    from drake_coop.results.io import atomic_write_bytes

    arrays: dict[str, np.ndarray] = {"format": np.array(FORMAT)}
    meta = {"robots": [r.robot for r in recordings], "arms": {}}
    for r in recordings:
        meta["arms"][r.robot] = {"source": r.source, "index": r.index,
                                 "channels": list(r.channels),
                                 "excitation": _excitation_meta(r.excitation)}
        for key in ARRAYS:
            arrays[f"{r.robot}/{key}"] = np.asarray(getattr(r, key))
    arrays["meta"] = np.array(json.dumps(meta))
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    atomic_write_bytes(path, buffer.getvalue())


def read_recording(path: str | Path) -> dict[str, WireRecording]:
    """Read a recording.

    Parameters
    ----------
    path : str or Path
        The file.

    Returns
    -------
    dict of str to WireRecording
        Arm → its rows, in the file's order.

    Raises
    ------
    ValueError
        Not a recording of this format, or a field missing or inconsistent (one line naming
        it).
    """
    where = f"--recording {path}"
    try:
        with np.load(path, allow_pickle=False) as f:
            files = {k: f[k] for k in f.files}
    except (OSError, ValueError) as exc:
        raise ValueError(f"{where}: not a readable .npz file ({' '.join(str(exc).split())[:120]})"
                         ) from None
    if "format" not in files or str(files["format"]) != FORMAT:
        raise ValueError(f"{where}: format must be {FORMAT!r}, got "
                         f"{str(files.get('format', 'none'))!r}")
    meta = json.loads(str(files["meta"]))
    out = {}
    for robot in meta["robots"]:
        missing = [k for k in ARRAYS if f"{robot}/{k}" not in files]
        if missing:
            raise ValueError(f"{where}: {robot}/{missing[0]} is missing")
        a = {k: files[f"{robot}/{k}"] for k in ARRAYS}
        N = a["t"].shape[0]
        n = a["q"].shape[1] if a["q"].ndim == 2 else -1
        for k in ("q", "tau"):
            if a[k].shape != (N, n):
                raise ValueError(f"{where}: {robot}/{k} must be ({N}, {n}), got {a[k].shape}")
        if not (np.all(np.isfinite(a["q"])) and np.all(np.isfinite(a["tau"]))):
            raise ValueError(f"{where}: {robot}/q and {robot}/tau must be finite")
        arm = meta["arms"][robot]
        e = arm["excitation"]
        excitation = FourierExcitation(q0=np.asarray(e["q0"], float), a=np.asarray(e["a"], float),
                                       b=np.asarray(e["b"], float), period=float(e["period"]),
                                       duration=float(e["duration"]), ramp=float(e["ramp"]))
        out[robot] = WireRecording(
            robot=robot, index=int(arm["index"]), excitation=excitation, t=a["t"], q=a["q"],
            tau=a["tau"], status_utime=a["status_utime"], command_utime=a["command_utime"],
            arrival_s=a["arrival_s"], h=float(a["h"]), torque_limits=a["torque_limits"],
            source=arm["source"], channels=list(arm.get("channels", [])))
    return out
