"""The cost of ``drake-coop serve``'s tick against the batch cost of the same blocks:
``python bench/serve_tick.py [--ticks 2000] [--pairs 5] [--chunk 100] [--out FILE]``.

In one process, on ``memq://``, the paper's scenario, both arms, then each arm alone
(``serve --robot NAME`` against the batch of that arm's blocks, ``per_arm``):

* **serve**: :class:`~drake_coop.robot.serve_loop.ServeLoop` as ``serve`` runs it, fed by a
  scripted 1 kHz driver: per tick, nine statuses per arm published (pre-encoded bytes of the
  reference's ``q_d`` at the driver's cycles) and received (each one's bytes kept as it
  arrives, :class:`~drake_coop.robot.pacing.StatusArrivals`), all of them checked at once,
  the newest read and fed, the Simulator step (the blocks), each arm's watchdog on floats,
  each arm's command encoded and published; unpaced: no waiting. Each part is timed
  (``serve_parts_us_median``: ``receive``, ``check``, ``feed``, ``step``, ``watchdog``,
  ``command``); the scripted driver's own publishing (``driver``: the driver's process in
  reality) is left out of the ratio.
* **serve without the reception** (``without_reception_*``): the same loop with no LCM at
  all, each tick's newest status handed to it already read (outside the timing): what the
  1 kHz reception costs in all, its own time and its effect on the rest of the tick.
* **batch**: the same blocks (``AddCooperativeController`` per arm, the same references and
  prediction horizon) in a Diagram whose ``q`` comes from a C++ ``TrajectorySource`` holding
  the readings each serve tick uses (the newest status of the tick, zero-order hold; the
  observers start at the same reading), advanced in one ``AdvanceTo`` per chunk.

Each pair builds a fresh serve and batch outside the timing, then runs them in alternated
chunks of ``chunk`` ticks up to ``ticks`` each (on a shared machine the load changes within
seconds; the finer alternation cancels more of it); the figure is the ratio of CPU times
(``time.process_time``) of each pair, its median and range: the whole serve tick
(``ratio_cpu``), and its step, watchdog and commands alone (``ratio_cpu_step_and_command``:
the same blocks plus the watchdog, without the 1 kHz reception). Also reported: the Python
callbacks per serve tick (every ``drake_coop`` function called from C++, the LCM handlers
included: :func:`bench.callbacks._calls_from_builtins`; the watchdog, called by the loop,
is not one), and the Simulator steps per tick.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))   # the checkout: bench.*

#: The timed parts of a serve tick (``driver``: the scripted driver's publishing, not counted).
PARTS = ("driver", "receive", "check", "feed", "step", "watchdog", "command")


def _readings(scenario, plan, ticks: int, cycles: int) -> list[np.ndarray]:
    """Each arm's ``q_d`` at every driver cycle of ``ticks`` ticks (``cycles`` per tick)."""
    out = []
    for robot in plan.robots:
        n = robot.arm.kinematics.n
        traj = robot.reference
        t = np.arange(ticks * cycles) * (plan.h / cycles)
        out.append(np.array([traj.value(min(tk, plan.t_end)).ravel()[:n] for tk in t]))
    return out


def _status_bytes(q, utime: int) -> bytes:
    from drake import lcmt_panda_status

    msg = lcmt_panda_status()
    msg.utime = int(utime)
    msg.num_joints = len(q)
    msg.joint_position = [float(v) for v in q]
    for f in ("joint_velocity", "joint_torque", "joint_torque_external",
              "joint_position_desired", "joint_velocity_desired",
              "joint_acceleration_desired", "joint_torque_desired"):
        setattr(msg, f, [0.0] * len(q))
    return msg.encode()


class _Serve:
    """serve's side, built; :meth:`run` times ``ticks`` ticks."""

    def __init__(self, scenario, plan, specs, data, cycles, robots=None, fed=False):
        from pydrake.lcm import DrakeLcm

        from drake_coop.robot.serve_loop import ServeLoop, status_arrivals
        from drake_coop.robot.status import check_panda_status

        self.lcm = DrakeLcm("memq://")
        self.loop = ServeLoop(plan, self.lcm, specs, robots=robots)
        self.channels = [s.status_channel for s in self.loop.specs]
        self.arrivals = status_arrivals(self.lcm, self.loop.specs)
        index = [[s.robot for s in specs].index(s.robot) for s in self.loop.specs]
        self.data, self.cycles = [data[i] for i in index], cycles
        self.next = 0                # the next tick's readings (runs continue the stream)
        self.loop.start([self.data[i][0][1] for i in range(len(self.channels))])
        # fed: no LCM at all, each tick's newest status handed over already read (outside
        # the timing): the tick without the 1 kHz reception
        self.fed = None if not fed else [
            [check_panda_status(arm[j][0], s.n) for j in range(cycles - 1, len(arm), cycles)]
            for arm, s in zip(self.data, self.loop.specs)]

    def run(self, ticks: int) -> dict[str, float]:
        """CPU seconds of ``ticks`` ticks by part: ``driver`` (the scripted driver's
        publishing: the driver's process in reality), ``receive`` (LCM's dispatch of every
        status to its handler, which keeps the bytes), ``check`` (every status of the tick
        checked at once), ``feed`` (the newest read and set), ``step`` (``λ̂(k)`` and the
        Simulator step: the blocks),
        ``watchdog`` (each arm's checks on floats), ``command`` (each arm's command encoded
        and published)."""
        lcm, loop, arrivals, channels = self.lcm, self.loop, self.arrivals, self.channels
        data, cycles = self.data, self.cycles
        first = self.next
        self.next += ticks
        clock = time.process_time
        parts = dict.fromkeys(PARTS, 0.0)
        if self.fed is not None:
            return self._run_fed(first, ticks)
        for k in range(first, first + ticks):
            a = clock()
            for j in range(k * cycles, (k + 1) * cycles):
                for i, c in enumerate(channels):
                    lcm.Publish(c, data[i][j][0])
            b = clock()
            lcm.HandleSubscriptions(0)
            c_ = clock()
            arrivals.faulty                  # every status of the tick checked
            c2 = clock()
            for i, c in enumerate(channels):
                loop.feed(i, arrivals.take_parsed(c))
            d = clock()
            loop.step()                      # ServeLoop.tick, in its three parts
            e = clock()
            loop.check()
            f = clock()
            loop.send()
            g = clock()
            parts["driver"] += b - a
            parts["receive"] += c_ - b
            parts["check"] += c2 - c_
            parts["feed"] += d - c2
            parts["step"] += e - d
            parts["watchdog"] += f - e
            parts["command"] += g - f
        if loop.tripped() is not None:
            raise RuntimeError(f"benchmark serve run tripped: {loop.tripped()}")
        return parts

    def _run_fed(self, first: int, ticks: int) -> dict[str, float]:
        loop, fed, clock = self.loop, self.fed, time.process_time
        parts = dict.fromkeys(PARTS, 0.0)
        for k in range(first, first + ticks):
            c_ = clock()
            for i, statuses in enumerate(fed):
                loop.feed(i, statuses[k])
            d = clock()
            loop.step()
            e = clock()
            loop.check()
            f = clock()
            loop.send()
            g = clock()
            parts["feed"] += d - c_
            parts["step"] += e - d
            parts["watchdog"] += f - e
            parts["command"] += g - f
        if loop.tripped() is not None:
            raise RuntimeError(f"benchmark serve run tripped: {loop.tripped()}")
        return parts


class _Batch:
    """The same blocks with ``q`` from a C++ TrajectorySource; :meth:`run` times them."""

    def __init__(self, scenario, plan, readings, cycles, robots=None):
        from pydrake.systems.analysis import Simulator
        from pydrake.systems.framework import DiagramBuilder
        from pydrake.systems.primitives import TrajectorySource
        from pydrake.trajectories import PiecewisePolynomial

        from drake_coop.control.block import AddCooperativeController
        from drake_coop.plant.cooperative import build_plant
        from drake_coop.plant.model_error import controller_arm_model

        model_builder = DiagramBuilder()
        coop = build_plant(model_builder, plan)
        builder = DiagramBuilder()
        self.blocks = []
        for i, (handles, robot) in enumerate(zip(coop.arms, scenario.robots)):
            if robots is not None and robot.name not in robots:
                continue
            # the reading each serve tick uses: the newest of its statuses (the tick's last
            # driver cycle); the observers start at the stream's first reading, as serve's
            q = readings[i][cycles - 1::cycles]
            t = np.arange(len(q) + 1) * plan.h
            pp = PiecewisePolynomial.ZeroOrderHold(t, np.vstack([q, q[-1:]]).T)
            src = builder.AddSystem(TrajectorySource(pp))
            block = AddCooperativeController(
                builder, coop.plant, handles.instance, gains=robot.gains, period=plan.h,
                controller_model=controller_arm_model(handles.arm, robot.model_error),
                velocity_source=robot.velocity_source, force_source=robot.force_source,
                difference_cutoff_hz=robot.difference_cutoff_hz,
                prediction_horizon=robot.timing.prediction_horizon, q=src.get_output_port(),
                connect_actuation=False, name=robot.name)
            ref = builder.AddSystem(TrajectorySource(plan.robots[i].reference))
            builder.Connect(ref.get_output_port(), block.reference_input)
            self.blocks.append((block, readings[i][0]))
        self._keep = (model_builder, coop)
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        context = self.simulator.get_mutable_context()
        for block, q0 in self.blocks:
            source = block.velocity_source
            if hasattr(source, "set_initial_state"):
                source.set_initial_state(source.GetMyMutableContextFromRoot(context), q0)
        self.simulator.Initialize()
        self.h = plan.h

    def run(self, ticks: int) -> float:
        t = self.simulator.get_context().get_time()
        cpu = time.process_time()
        self.simulator.AdvanceTo(t + ticks * self.h)
        return time.process_time() - cpu


def _callbacks_per_tick(serve: _Serve, ticks: int) -> dict:
    import inspect

    from bench.callbacks import _calls_from_builtins

    counts: dict[str, int] = defaultdict(int)

    def count(frame):
        code, module = frame.f_code, frame.f_globals.get("__name__", "?")
        if module.startswith("drake_coop") and not code.co_flags & inspect.CO_GENERATOR:
            counts[f"{module}.{code.co_qualname}"] += 1

    with _calls_from_builtins(count):
        serve.run(ticks)
    return {"per_tick": sum(counts.values()) / ticks,
            "by_function": {k: v / ticks for k, v in sorted(counts.items(),
                                                          key=lambda kv: -kv[1])}}


def _steps_per_tick(serve: _Serve, ticks: int) -> float:
    before = serve.loop.simulator.get_num_steps_taken()
    serve.run(ticks)
    return (serve.loop.simulator.get_num_steps_taken() - before) / ticks


def _alternated(make_serve, make_batch, ticks: int, pairs: int, chunk: int,
                make_fed=None) -> dict:
    """``pairs`` pairs, each a fresh serve and batch (and ``make_fed``'s serve without the
    reception, if given) built outside the timing, then run in alternated chunks of
    ``chunk`` ticks up to ``ticks`` each (on a shared machine the load changes within
    seconds: the finer alternation cancels more of it)."""
    runs: dict[str, list] = {"serve": [], "fed": []}
    batch_cpu = []
    for _ in range(pairs):
        batch, serve = make_batch(), make_serve()
        fed = make_fed() if make_fed is not None else None
        b = 0.0
        parts = {"serve": dict.fromkeys(PARTS, 0.0), "fed": dict.fromkeys(PARTS, 0.0)}
        done = 0
        while done < ticks:
            n = min(chunk, ticks - done)
            b += batch.run(n)
            for name, runner in (("serve", serve), ("fed", fed)):
                if runner is not None:
                    for key, value in runner.run(n).items():
                        parts[name][key] += value
            done += n
        del batch, serve, fed
        batch_cpu.append(b / ticks)
        for name in runs:
            runs[name].append((b, parts[name]))
    out = {}
    for name, prefix in (("serve", ""), ("fed", "without_reception_")):
        if not runs[name] or make_fed is None and name == "fed":
            continue
        ratios = [sum(v for k, v in p.items() if k != "driver") / b for b, p in runs[name]]
        out[prefix + "ratio_cpu"] = ratios
        out[prefix + "ratio_cpu_median"] = statistics.median(ratios)
        out[prefix + "serve_parts_us_median"] = {
            k: statistics.median(1e6 * p[k] / ticks for _, p in runs[name]) for k in PARTS}
        if name == "serve":
            step = [(p["step"] + p["watchdog"] + p["command"]) / b for b, p in runs[name]]
            out["ratio_cpu_step_and_command"] = step
            out["ratio_cpu_step_and_command_median"] = statistics.median(step)
            out["serve_tick_cpu_us_median"] = statistics.median(
                1e6 * sum(v for k, v in p.items() if k != "driver") / ticks
                for _, p in runs[name])
    out["batch_tick_cpu_us_median"] = 1e6 * statistics.median(batch_cpu)
    return out


def serve_tick_benchmark(ticks: int = 2000, pairs: int = 5, chunk: int = 100,
                         per_arm: bool = True) -> dict:
    """The figures of the module's docstring."""
    from drake_coop.experiment.plan import plan_run
    from drake_coop.robot.driver_spec import driver_specs
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.model_check import check_models

    scenario = load_scenario()
    specs = driver_specs(scenario, check_models(scenario))
    cycles = int(round(scenario.control_period / specs[0].period))
    # enough readings for every run of the pairs plus the counting runs
    total = ticks + 150          # the counting runs continue after a timed run
    plan = plan_run(scenario, min(total * scenario.control_period, 90.0))
    readings = _readings(scenario, plan, total, cycles)
    data = [[(_status_bytes(q, j * 1000), q) for j, q in enumerate(r)] for r in readings]
    result = {"ticks": ticks, "pairs": pairs, "chunk": chunk,
              "machine": platform.processor() or platform.machine(),
              "cpus": os.cpu_count(), "load_average_start": os.getloadavg()[0]}
    result.update(_alternated(lambda: _Serve(scenario, plan, specs, data, cycles),
                              lambda: _Batch(scenario, plan, readings, cycles),
                              ticks, pairs, chunk,
                              lambda: _Serve(scenario, plan, specs, data, cycles, fed=True)))
    if per_arm:                  # serve --robot NAME against the batch of that arm's blocks
        result["per_arm"] = {
            s.robot: _alternated(
                lambda r=s.robot: _Serve(scenario, plan, specs, data, cycles, robots=[r]),
                lambda r=s.robot: _Batch(scenario, plan, readings, cycles, robots=[r]),
                ticks, pairs, chunk)
            for s in specs}
    serve = _Serve(scenario, plan, specs, data, cycles)
    serve.run(ticks)
    steps = _steps_per_tick(serve, 50)
    callbacks = _callbacks_per_tick(serve, 100)
    result.update({
        "load_average_end": os.getloadavg()[0],
        "simulator_steps_per_tick": steps,
        "python_callbacks_per_tick": callbacks["per_tick"],
        "callbacks_by_function": callbacks["by_function"],
    })
    return result


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=2000)
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--chunk", type=int, default=100,
                        help="ticks per alternated chunk within a pair")
    parser.add_argument("--no-per-arm", action="store_true",
                        help="skip the one-arm (serve --robot) pairs")
    parser.add_argument("--out", default=None, help="write the numbers as JSON")
    args = parser.parse_args()
    result = serve_tick_benchmark(args.ticks, args.pairs, args.chunk, not args.no_per_arm)
    text = json.dumps(result, indent=1)
    print(text)
    if args.out:
        Path(args.out).write_text(text + "\n")
