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
  (a crash) gives an ``error`` record.
* :func:`run_ray` — each case a ``@ray.remote(max_calls=1)`` task (a worker process is not
  reused after one case) on a local instance (``ray.init(num_cpus=workers)``) or an existing
  cluster (``ray.init(address=...)``). Every node needs ``drake_coop`` importable.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import signal
import time
from typing import Callable

from drake_coop.studies.expand import Case

__all__ = ["run_case", "run_local", "run_ray"]

OnResult = Callable[[Case, dict], None]


def run_case(scenario_yaml: str, t_end: float | None) -> dict:
    """Simulate one case and return its record (never raises).

    Returns
    -------
    dict
        ``status`` (``ok``, ``diverged``, ``error`` or ``interrupted``), ``message``,
        ``t_reached`` (s), ``wall_time_s`` and ``metrics`` (as in ``metrics.json``; empty on
        ``error``).
    """
    from drake_coop.studies.sweep import run_one

    start = time.perf_counter()
    try:
        result = run_one(scenario_yaml, t_end)
    except Exception as exc:          # a failure to build or run: recorded, not fatal
        return {"status": "error", "message": f"{type(exc).__name__}: "
                f"{' '.join(str(exc).split())[:300]}", "t_reached": 0.0,
                "wall_time_s": time.perf_counter() - start, "metrics": {}}
    meta = result["meta"]
    return {"status": meta["status"], "message": meta["message"],
            "t_reached": meta["t_end"], "wall_time_s": time.perf_counter() - start,
            "metrics": result["metrics"]}


def _child(conn, scenario_yaml: str, t_end: float | None) -> None:
    """Worker process: run one case, send its record, exit (Ctrl-C is the parent's business)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    conn.send(run_case(scenario_yaml, t_end))
    conn.close()


def run_local(cases: list[Case], t_end: float | None, on_result: OnResult, *,
              workers: int = 2) -> None:
    """Run ``cases`` in at most ``workers`` parallel processes, one fresh process per case.

    An exception in the parent (Ctrl-C, SIGTERM, ``on_result`` failing) terminates the running
    cases and propagates; queued cases are not started.
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
                                          args=(sender, case.scenario_yaml, t_end),
                                          daemon=True)
                process.start()
                sender.close()
                running[receiver] = (process, case)
            for receiver in multiprocessing.connection.wait(list(running)):
                process, case = running.pop(receiver)
                try:
                    result = receiver.recv()
                except EOFError:
                    process.join()
                    result = {"status": "error", "message": "the case's process died "
                              f"(exit code {process.exitcode})", "t_reached": 0.0,
                              "wall_time_s": 0.0, "metrics": {}}
                receiver.close()
                process.join()
                on_result(case, result)
    finally:
        for receiver, (process, _) in running.items():
            process.terminate()
        for receiver, (process, _) in running.items():
            process.join(timeout=10)
            receiver.close()


def run_ray(cases: list[Case], t_end: float | None, on_result: OnResult, *,
            address: str | None = None, workers: int = 2) -> None:
    """Run ``cases`` as Ray tasks; ``address=None`` starts a local instance of ``workers``
    CPUs (shut down afterwards), otherwise connects to the cluster at ``address``.

    Raises
    ------
    ImportError
        If ray is not installed (``pip install "drake_coop[ray]"``).
    """
    import ray

    started = False
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    if not ray.is_initialized():
        if address is None:
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
                on_result(refs[ref], ray.get(ref))
    except BaseException:
        for ref in pending:
            ray.cancel(ref, force=True)
        raise
    finally:
        if started:
            ray.shutdown()
