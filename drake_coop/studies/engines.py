"""Engines: run a study's cases, each in a fresh process, locally or on Ray.

Both engines call :func:`run_case` on the scenario's YAML text (the diagram is built inside the
worker; no pydrake object crosses a process boundary) and hand each result to ``on_result`` as
soon as it arrives, in completion order.

* :func:`run_local` — at most ``workers`` processes (``spawn`` start method), a fresh one per
  case (Python LeafSystems keep memory alive across runs in one process), each sending its
  record back through a pipe. The engine starts and joins them itself rather than through
  ``ProcessPoolExecutor(max_tasks_per_child=1)``: after its workers were terminated on SIGTERM,
  that executor hung the interpreter's exit (Python 3.11.7). Workers ignore SIGINT; on
  Ctrl-C/SIGTERM the parent terminates the running cases. A worker that dies without a record
  (a crash, ``kill -9``, the OOM killer) gives a ``died`` record, which is not a result: the
  study does not store it and runs the case again on its next resume. Each worker dies with
  its study, however the study ends: it asks the kernel for SIGKILL when its parent dies
  (``prctl(PR_SET_PDEATHSIG)`` on Linux) and a watchdog thread also ends it when its parent
  pid changes; a worker whose parent is gone exits quietly (no BrokenPipeError traceback).
* :func:`run_ray` — each case a ``@ray.remote(max_calls=1)`` task (a worker process is not
  reused after one case) on a local instance (``ray.init(num_cpus=workers)``) or an existing
  cluster (``ray.init(address=...)``). Every node needs ``drake_coop`` importable. A local
  instance is watched by :mod:`drake_coop.studies.reaper`, which ends Ray's helpers if the
  driver is killed; a task whose worker died gives a ``died`` record.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import multiprocessing.connection
import os
import signal
import sys
import threading
import time
from typing import TYPE_CHECKING, Callable

from drake_coop.studies.expand import Case

if TYPE_CHECKING:
    from drake_coop.scenario.schema import Scenario

__all__ = ["died", "die_with_parent", "run_case", "run_in_processes", "run_local", "run_ray"]

OnResult = Callable[[Case, dict], None]


def run_case(scenario_yaml: str, t_end: float | None, clocks=None,
             scenario: Scenario | None = None) -> dict:
    """Simulate one case and return its record (never raises).

    Parameters
    ----------
    scenario_yaml : str
        The case's scenario, YAML text.
    t_end : float or None
        The run's end, s; None for the task's.
    clocks : sequence of (Clock or None), optional
        Each robot's controller-side clock (:func:`~drake_coop.studies.sweep.run_one`);
        None: the run's grid.
    scenario : Scenario, optional
        The scenario already loaded and validated from ``scenario_yaml``, passed to
        :func:`~drake_coop.studies.sweep.run_one` (not loaded again); None: loaded there.

    Returns
    -------
    dict
        ``status`` (``ok``, ``diverged``, ``error``, ``interrupted`` or ``died``: out of
        memory, not a result), ``message``, ``t_reached`` (s), ``wall_time_s`` and ``metrics``
        (as in ``metrics.json``; empty on ``error``).
    """
    from drake_coop.studies.sweep import run_one

    start = time.perf_counter()
    try:
        result = run_one(scenario_yaml, t_end, clocks, scenario)
    except MemoryError:
        return died("the case ran out of memory (MemoryError)")
    except Exception as exc:          # a failure to build or run: recorded, not fatal
        return {"status": "error", "message": f"{type(exc).__name__}: "
                f"{' '.join(str(exc).split())[:300]}", "t_reached": 0.0,
                "wall_time_s": time.perf_counter() - start, "metrics": {}}
    meta = result["meta"]
    return {"status": meta["status"], "message": meta["message"],
            "t_reached": meta["t_end"], "wall_time_s": time.perf_counter() - start,
            "metrics": result["metrics"]}


def died(message: str) -> dict:
    """The record of a case that did not finish (not a result: it runs again).

    Parameters
    ----------
    message : str
        Why it did not finish.

    Returns
    -------
    dict
        The record (status ``died``).
    """
    return {"status": "died", "message": message, "t_reached": 0.0, "wall_time_s": 0.0,
            "metrics": {}}


def _exit_message(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            name = signal.Signals(-exitcode).name
        except ValueError:
            name = f"signal {-exitcode}"
        return f"the case's process was killed by {name}"
    return f"the case's process died (exit code {exitcode})"


PR_SET_PDEATHSIG = 1


def die_with_parent(parent: int) -> None:
    """End this process when process ``parent`` ends, however it ends.

    On Linux the kernel sends SIGKILL when the parent dies (``prctl(PR_SET_PDEATHSIG)``);
    a daemon thread also checks the parent pid every 0.5 s (other systems, and the case
    where the parent died before the ``prctl``).

    Parameters
    ----------
    parent : int
        The parent's pid.
    """
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:
        os._exit(1)

    def watch() -> None:
        while True:
            time.sleep(0.5)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="parent-watchdog", daemon=True).start()


_STOP_SIGNALS = {signal.SIGINT, signal.SIGTERM}


@contextlib.contextmanager
def _stop_signals_deferred():
    """Ctrl-C and SIGTERM wait until the block is done, then arrive as usual.

    Arriving inside ``Process.start()``, between the spawn and the write of the child's data,
    they left an unregistered child that printed an EOFError traceback. Blocking them in this
    thread is not enough: a signal is delivered to any thread that does not block it (NumPy's
    BLAS threads among them) and Python then runs its handler in this thread all the same. So
    the handlers are swapped for one that notes the signal, as well as blocked here (the
    child inherits the mask and unblocks it, :func:`_child`); the noted signal is raised again
    once the old handlers and mask are back.
    """
    noted: list[int] = []
    handlers = {}
    if threading.current_thread() is threading.main_thread():   # only it may set handlers
        handlers = {signum: signal.signal(signum, lambda signum, frame: noted.append(signum))
                    for signum in _STOP_SIGNALS}
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS)
    try:
        yield
    finally:
        for signum, handler in handlers.items():
            signal.signal(signum, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)   # a pending one arrives here
        if noted:
            signal.raise_signal(noted[0])


def _child(conn, work: Callable, args: tuple, parent: int | None = None) -> None:
    """Worker process: ``work(*args)``, send its result, exit (Ctrl-C is the parent's business).

    Dies with its parent (:func:`die_with_parent`); a parent gone by the time the result is
    sent ends the worker quietly.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # The parent blocked SIGINT/SIGTERM while starting this process (the mask is inherited):
    # a SIGTERM it sent since then is delivered here and ends the worker.
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _STOP_SIGNALS)
    if parent is not None:
        die_with_parent(parent)
    result = work(*args)
    try:
        conn.send(result)
        conn.close()
    except (BrokenPipeError, ConnectionError, EOFError, OSError):
        os._exit(1)


def run_in_processes(cases: list[Case], work: Callable, args_of: Callable[[Case], tuple],
                     on_result: Callable, on_death: Callable[[str], object], *,
                     workers: int = 2) -> None:
    """``work(*args_of(case))`` for every case in at most ``workers`` parallel processes, one
    fresh ``spawn`` process per case, each result handed to ``on_result(case, result)`` as it
    arrives.

    ``work`` must be a module-level function (it is pickled into the child). A child that dies
    without a result (a crash, ``kill -9``, the OOM killer) gives ``on_death(message)`` instead.
    Every child dies with this process (:func:`die_with_parent`) and ignores Ctrl-C. An
    exception in the parent (Ctrl-C, SIGTERM, ``on_result`` failing) terminates the running
    children and propagates; queued cases are not started. :func:`run_local` (studies) and the
    stability map's grid share this loop.

    Parameters
    ----------
    cases : list of Case
        The cases.
    work : Callable
        A module-level function.
    args_of : Callable[[Case], tuple]
        A case's arguments of ``work``.
    on_result : Callable
        ``on_result(case, result)``.
    on_death : Callable[[str], object]
        The result of a child that died, from its message.
    workers : int
        The parallel processes.
    """
    context = multiprocessing.get_context("spawn")
    queue = list(cases)
    running: dict = {}                   # receiving end of the pipe -> (process, case)
    try:
        while queue or running:
            while queue and len(running) < max(1, workers):
                case = queue.pop(0)
                receiver, sender = context.Pipe(duplex=False)
                process = context.Process(target=_child, name=f"case-{case.hash}",
                                          args=(sender, work, args_of(case), os.getpid()),
                                          daemon=True)
                with _stop_signals_deferred():
                    process.start()
                    running[receiver] = (process, case)
                sender.close()
            for receiver in multiprocessing.connection.wait(list(running)):
                process, case = running.pop(receiver)
                try:
                    result = receiver.recv()
                except (EOFError, OSError):
                    process.join()
                    result = on_death(_exit_message(process.exitcode))
                receiver.close()
                process.join()
                on_result(case, result)
    finally:
        for receiver, (process, _) in running.items():
            process.terminate()
        for receiver, (process, _) in running.items():
            process.join(timeout=10)
            receiver.close()


def run_local(cases: list[Case], t_end: float | None, on_result: OnResult, *,
              workers: int = 2) -> None:
    """Run ``cases`` in at most ``workers`` parallel processes, one fresh process per case
    (:func:`run_in_processes` with :func:`run_case`; a died case gives a :func:`died` record).

    An exception in the parent (Ctrl-C, SIGTERM, ``on_result`` failing) terminates the running
    cases and propagates; queued cases are not started.

    Parameters
    ----------
    cases : list of Case
        The cases.
    t_end : float or None
        The runs' end, s; None for each task's.
    on_result : Callable
        ``on_result(case, record)``.
    workers : int
        The parallel processes.
    """
    run_in_processes(cases, run_case, lambda case: (case.scenario_yaml, t_end), on_result,
                     died, workers=workers)


def run_ray(cases: list[Case], t_end: float | None, on_result: OnResult, *,
            address: str | None = None, workers: int = 2) -> None:
    """Run ``cases`` as Ray tasks; ``address=None`` starts a local instance of ``workers``
    CPUs (shut down afterwards), otherwise connects to the cluster at ``address``.

    Parameters
    ----------
    cases : list of Case
        The cases.
    t_end : float or None
        The runs' end, s; None for each task's.
    on_result : Callable
        ``on_result(case, record)``.
    address : str or None
        The Ray cluster's address; None starts a local one.
    workers : int
        The local instance's CPUs.

    Raises
    ------
    ImportError
        If ray is not installed (``pip install "drake_coop[ray]"``).
    """
    import ray

    started = False
    reaper = None
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    if not ray.is_initialized():
        if address is None:
            from drake_coop.studies.reaper import start as start_reaper

            reaper = start_reaper()      # ends Ray's helpers if this process is killed
            ray.init(num_cpus=max(1, workers), include_dashboard=False, log_to_driver=False,
                     configure_logging=False)
        else:
            ray.init(address=address, log_to_driver=False, configure_logging=False)
        started = True
    for signum, handler in saved.items():      # ray.init installs its own; keep the caller's
        signal.signal(signum, handler)
    task = ray.remote(max_calls=1, num_cpus=1)(run_case)
    refs = {task.remote(c.scenario_yaml, t_end): c for c in cases}
    pending = list(refs)
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                try:
                    result = ray.get(ref)
                except (ray.exceptions.RayError, OSError) as exc:   # a worker or node died
                    result = died(f"the case's Ray task failed: {type(exc).__name__}")
                on_result(refs[ref], result)
    except BaseException:
        # On a cluster of others the cases must stop; a local instance of ours stops with
        # ray.shutdown() below. Force-cancelling there too raced with replies in flight and
        # aborted the driver inside Ray ("Tried to complete task that was not pending").
        if not (started and address is None):
            for ref in pending:
                ray.cancel(ref, force=True)
        raise
    finally:
        if started:
            ray.shutdown()
        if reaper is not None:
            reaper.done()
