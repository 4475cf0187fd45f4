"""The real-time settings of the process that runs the controller side, read back from the
kernel: scheduling policy and priority, CPU affinity, locked memory
(:func:`realtime_settings`), what is missing for a real-time loop (:func:`missing_realtime`),
and ``mlockall``'s undo (:func:`unlock_memory`).

``drake-coop serve`` records them in its ``run.json`` and, with ``--require-rt``, refuses to
start without them (:mod:`drake_coop.robot.cli`).
"""

from __future__ import annotations

#: Scheduling policies that count as real-time.
REALTIME_POLICIES = ("SCHED_FIFO", "SCHED_RR")


def _policy_name(policy: int) -> str:
    import os

    for name in ("SCHED_OTHER", "SCHED_BATCH", "SCHED_IDLE", "SCHED_FIFO", "SCHED_RR",
                 "SCHED_DEADLINE"):
        if getattr(os, name, None) == policy:
            return name
    return f"policy {policy}"


def _locked_kib() -> int | None:
    """``VmLck`` of this process (kB; None where ``/proc`` does not say)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("VmLck:"):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return None


def _libc():
    import ctypes
    import ctypes.util

    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
    except OSError:
        return None


def _mlockall() -> int:
    """``mlockall(MCL_CURRENT | MCL_FUTURE)``: 0, or the errno of its failure (-1: no libc)."""
    import ctypes

    libc = _libc()
    if libc is None:
        return -1
    return 0 if libc.mlockall(1 | 2) == 0 else ctypes.get_errno()


def unlock_memory() -> None:
    """``munlockall()`` (undo :func:`realtime_settings`'s lock when the run does not start)."""
    libc = _libc()
    if libc is not None:
        libc.munlockall()


def realtime_settings(lock_memory: bool = False) -> dict:
    """The real-time settings this process actually has, read back from the kernel.

    ``policy`` and ``priority`` (``os.sched_getscheduler`` / ``os.sched_getparam``),
    ``cpu_affinity`` (``os.sched_getaffinity``) against ``cpus_online``, ``locked_kib``
    (``VmLck``), and ``mlockall``: ``"not requested"``, ``"ok"`` or the error of
    ``mlockall(MCL_CURRENT | MCL_FUTURE)``, called only when ``lock_memory``.

    Parameters
    ----------
    lock_memory : bool
        Call ``mlockall``.
    """
    import errno
    import os

    settings: dict = {}
    try:
        settings["policy"] = _policy_name(os.sched_getscheduler(0))
        settings["priority"] = int(os.sched_getparam(0).sched_priority)
    except (AttributeError, OSError):
        settings["policy"], settings["priority"] = "unknown", None
    try:
        settings["cpu_affinity"] = sorted(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        settings["cpu_affinity"] = None
    settings["cpus_online"] = os.cpu_count()
    if lock_memory:
        err = _mlockall()
        settings["mlockall"] = "ok" if err == 0 else (
            f"failed: {errno.errorcode.get(err, err)}" if err > 0 else "failed: no libc")
    else:
        settings["mlockall"] = "not requested"
    settings["locked_kib"] = _locked_kib()
    return settings


def missing_realtime(settings: dict, memory: bool = True) -> list[str]:
    """What :func:`realtime_settings` shows is missing for a real-time loop, one phrase each
    (empty: all granted): a real-time policy with a priority > 0, the process pinned to fewer
    CPUs than are online, and (``memory``) memory locked.

    Parameters
    ----------
    settings : dict
        :func:`realtime_settings`'.
    memory : bool
        Whether locked memory is required.
    """
    missing = []
    if settings.get("policy") not in REALTIME_POLICIES or not settings.get("priority"):
        missing.append(f"real-time scheduling (got {settings.get('policy')} priority "
                       f"{settings.get('priority')}: run under chrt -f 80)")
    affinity, online = settings.get("cpu_affinity"), settings.get("cpus_online")
    if affinity is None or online is None or (online > 1 and len(affinity) >= online):
        missing.append(f"CPU affinity (runs on {len(affinity or [])} of {online} CPUs: pin it "
                       "with taskset -c)")
    if memory and (settings.get("mlockall") != "ok" or not settings.get("locked_kib")):
        missing.append(f"locked memory (mlockall {settings.get('mlockall')}: needs "
                       "CAP_IPC_LOCK or ulimit -l unlimited)")
    return missing
