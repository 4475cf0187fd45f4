"""The Python callbacks of a run: each system's exclusive time (:func:`_timed_callbacks`) and
their number per control tick (:func:`_count_callbacks`)."""

from __future__ import annotations

import contextlib
import functools
import time
from collections import defaultdict


_TIMED = {
    "velocity observer (15)-(16)": ("drake_coop.control.observers", "VelocityObserver",
                                    ("_calc_qdot_hat", "_calc_qdot_o", "_update_observer")),
    "force observer (22)": ("drake_coop.control.observers", "ForceObserver",
                            ("_calc_lambda_hat", "_update_integral")),
    "controller (13)": ("drake_coop.control.controller", "Controller",
                        ("_update_latch",)),
    "force sensor (ground truth)": ("drake_coop.plant.wrist", "ForceSensor",
                                    ("_calc_force_cache", "_calc_force", "_calc_lambda",
                                     "_update_step")),
    "F/T sensor model": ("drake_coop.sensing.force_sensor", "FTSensor", ("_update_reading",)),
    "wrist kinematics (all arms)": ("drake_coop.plant.wrist", "WristKinematics",
                                    ("_calc_signals",)),
    "wrist dynamics (all arms)": ("drake_coop.plant.wrist_dynamics", "WristDynamics",
                                  ("_calc_signals", "_calc_last_step", "_update_step")),
    "pad forces (contact ground truth, all arms)": ("drake_coop.plant.grasp", "PadForces",
                                                    ("_calc_forces",)),
    "load feedforward (object_model)": ("drake_coop.control.object", "LoadFeedforward",
                                        ("_update",)),
    "mass estimator (object_model: estimated)": ("drake_coop.control.object", "MassEstimator",
                                                 ("_update",)),
}


@contextlib.contextmanager
def _timed_callbacks(totals: dict):
    """Time the Python callbacks of the systems in :data:`_TIMED` (exclusive time).

    ``totals[(label, system name)]`` accumulates seconds. Systems built inside the block are
    timed (their callbacks are bound when they are declared).
    """
    import importlib

    stack: list[float] = []     # time spent in nested timed callbacks, per open frame
    # CPU time of this thread: the other processes of a shared machine do not count.
    patched = []

    def wrap(label, fn):
        @functools.wraps(fn)
        def timed(self, *args):
            stack.append(0.0)
            start = time.thread_time()
            try:
                return fn(self, *args)
            finally:
                elapsed = time.thread_time() - start
                nested = stack.pop()
                totals[(label, self.get_name())] += elapsed - nested
                if stack:
                    stack[-1] += elapsed
        return timed

    for label, (module, cls_name, methods) in _TIMED.items():
        cls = getattr(importlib.import_module(module), cls_name)
        for m in methods:
            original = getattr(cls, m, None)
            if original is None:     # an older version of the system (before/after runs)
                continue
            patched.append((cls, m, original))
            setattr(cls, m, wrap(label, original))
    try:
        yield
    finally:
        for cls, m, original in patched:
            setattr(cls, m, original)


def _builtin(callable_):
    """The compiled function a call reaches (a builtin, a pybind11 or nanobind function), or
    None for anything else (a Python function, a class): a bound method's function is
    unwrapped, as the interpreter does before calling it."""
    import types

    func = callable_.__func__ if isinstance(callable_, types.MethodType) else callable_
    if isinstance(func, (types.BuiltinFunctionType, types.MethodDescriptorType)) \
            or type(func).__module__ == "nanobind":      # drake >= 1.52 binds with nanobind
        return func
    return None


@contextlib.contextmanager
def _calls_from_builtins(count):
    """Call ``count(frame)`` for every Python frame entered directly from inside a builtin
    (pybind) call while the block runs.

    Drake 1.51 (Python 3.11) binds with pybind11, whose functions are builtins that
    ``sys.setprofile`` reports (``c_call``/``c_return``). Drake 1.58 (Python 3.12+) binds with
    nanobind, whose functions ``sys.setprofile`` does not report at all (and 3.12 drops the
    ``c_call`` of any bound builtin method), so from 3.12 on the calls are taken from
    ``sys.monitoring``, whose ``CALL``/``C_RETURN`` events see every callable.
    """
    import sys

    inside: list = []        # (frame, builtin) of the builtin calls in progress

    if sys.version_info < (3, 12):
        def hook(frame, event, arg):
            if event == "c_call":
                inside.append((frame, arg))
            elif event in ("c_return", "c_exception"):
                if inside:
                    inside.pop()
            elif event == "call" and inside and inside[-1][0] is frame.f_back:
                count(frame)

        sys.setprofile(hook)
        try:
            yield
        finally:
            sys.setprofile(None)
        return

    mon = sys.monitoring
    E = mon.events
    tool = next((i for i in range(mon.PROFILER_ID, 6) if mon.get_tool(i) is None), None)
    if tool is None:
        raise RuntimeError("no free sys.monitoring tool id to count callbacks")

    def on_call(code, offset, callable_, arg0):
        func = _builtin(callable_)
        if func is not None:
            inside.append((sys._getframe(1), func))

    def on_c_end(code, offset, callable_, arg0, *exc):
        if inside and inside[-1][1] is _builtin(callable_):
            inside.pop()

    def on_start(code, offset):
        frame = sys._getframe(1)
        if inside and inside[-1][0] is frame.f_back:
            count(frame)

    mon.use_tool_id(tool, "drake_coop bench")
    try:
        mon.register_callback(tool, E.CALL, on_call)
        mon.register_callback(tool, E.C_RETURN, on_c_end)
        mon.register_callback(tool, E.C_RAISE, on_c_end)
        mon.register_callback(tool, E.PY_START, on_start)
        mon.set_events(tool, E.CALL | E.C_RETURN | E.C_RAISE | E.PY_START)
        yield
    finally:
        mon.set_events(tool, 0)
        mon.free_tool_id(tool)


def _count_callbacks(scenario, t_end: float) -> dict:
    """Python callbacks per control tick of a run to ``t_end``: every Python function that
    C++ calls (an event, an output port, a cache entry, a monitor), counted as a call of a
    ``drake_coop`` function (not a generator) made directly from inside a builtin (pybind)
    call (:func:`_calls_from_builtins`).
    Returns the total per tick and the count per tick of each function (``module.qualname``).
    """
    import inspect

    from drake_coop.experiment.ticks import num_ticks_until
    from drake_coop.experiment.simulate import simulate
    from drake_coop.experiment.ticks import time_grid

    counts: dict[str, int] = defaultdict(int)
    counting = contextlib.ExitStack()

    def count(frame):
        code, module = frame.f_code, frame.f_globals.get("__name__", "?")
        # Not a generator resumed by sum()/tuple(), not NumPy's own Python.
        if module.startswith("drake_coop") and not code.co_flags & inspect.CO_GENERATOR:
            counts[f"{module}.{code.co_qualname}"] += 1

    def start(exp, simulator):
        counts.clear()
        counting.enter_context(_calls_from_builtins(count))

    with counting:
        result = simulate(scenario, t_end=t_end, on_start=start)
    if not result.ok:
        raise RuntimeError(f"benchmark run failed: {result.meta['message']}")
    h, _ = time_grid(scenario)
    ticks = num_ticks_until(t_end, h)
    return {"per_tick": sum(counts.values()) / ticks,
            "by_function": {k: v / ticks for k, v in sorted(counts.items(),
                                                          key=lambda kv: -kv[1])}}
