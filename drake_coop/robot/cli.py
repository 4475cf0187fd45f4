"""``drake-coop serve SCENARIO --lcm-url URL --out DIR`` and
``drake-coop sim-driver SCENARIO --lcm-url URL``: the experiment split at the robot's cable.

``serve`` runs each arm's control blocks against the wall clock over its driver's LCM
messages (:mod:`drake_coop.robot.drivers`, :mod:`drake_coop.robot.pacing`): it waits for a
status from every arm, starts the observers at the first reading, and then ticks every ``h``;
it stops at the task's end, when a watchdog trips (one line: which arm, why), or on Ctrl-C /
SIGTERM, and in every case sends each driver its safe command last. The run folder gets
``run.json`` (status, reason, pacing summary against the delay margin), ``pacing.csv`` and
``pacing.png``.

Before anything starts, the LCM URL's provider is checked (``udpm``, ``mpudpm``, ``tcpq``,
``memq``; ``memq://`` is in-process only: ``serve`` says so, since no driver in another
process can reach it). The loop starts once every arm's status channel has carried a message;
the watchdog checks each status at the tick it arrives (its bytes, its age, its reading:
:mod:`drake_coop.robot.status`, :class:`~drake_coop.control.watchdog.Watchdog`); a trip ends
the run with one line naming the robot, the status channel and what was wrong. The run folder
is committed only once the loop has ticked: an interrupted wait for the first status leaves
the folder (and a previous run in it) as it was.

``run.json`` also records the real-time settings the process actually got, read back from
the kernel (scheduling policy and priority, CPU affinity, locked memory:
:func:`~drake_coop.robot.realtime.realtime_settings`); ``--require-rt`` refuses to start (exit 2,
one line naming what is missing) without a real-time policy, a CPU affinity narrower than the
online CPUs and memory locked (``mlockall``, attempted once the other two are granted).

``sim-driver`` runs the scenario's plant behind the same messages at the driver's rate,
paced at real time; its arms are held still (brakes on) until the first command arrives.

Exit codes: 0 done, 1 stopped by the watchdog (or no status), 2 bad input (one line naming
the field), 130 Ctrl-C, 143 SIGTERM.
"""

from __future__ import annotations

import json
import math
import sys
import time

#: Default wait for the first status of every arm (s).
STATUS_WAIT = 10.0
#: The LCM providers ``--lcm-url`` accepts (``file://`` would write a log outside the run).
LCM_PROVIDERS = ("udpm", "mpudpm", "tcpq", "memq")
#: Said of ``memq://`` where it matters.
MEMQ_NOTE = ("memq:// is in-process only: a driver in another process cannot reach it; "
             "use udpm:// or tcpq://")


def add_robot_parsers(sub) -> None:
    """Register ``serve`` and ``sim-driver`` on the ``drake-coop`` subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``drake-coop`` subparsers.
    """
    serve = sub.add_parser("serve", help="run the control blocks against the wall clock over "
                                         "the arms' LCM drivers")
    serve.add_argument("scenario", help="scenario YAML or shipped scenario name")
    serve.add_argument("--lcm-url", default=None,
                       help="LCM URL (default: LCM's own, udpm://239.255.76.67:7667?ttl=0)")
    serve.add_argument("--out", required=True, help="run folder for the pacing figures")
    serve.add_argument("--force", action="store_true", help="replace a previous run's folder")
    serve.add_argument("--t-end", type=float, default=None, help="stop earlier (s)")
    serve.add_argument("--delay-margin", type=float, default=None, metavar="SECONDS",
                       help="the loop's delay margin (default: computed by the stability map)")
    serve.add_argument("--status-wait", type=float, default=STATUS_WAIT,
                       help=f"wait for the first status (s, default {STATUS_WAIT:g})")
    serve.add_argument("--require-rt", action="store_true",
                       help="refuse to start without real-time scheduling (SCHED_FIFO/RR), "
                            "a CPU affinity and locked memory (mlockall, attempted then)")
    serve.add_argument("--robot", default=None, metavar="NAME",
                       help="serve this arm only (one serve per arm; a trip in one stops "
                            "the others through the DRAKE_COOP_STOP channel)")
    serve.add_argument("--tick", choices=("grid", "arrival"), default="grid",
                       help="tick on the wall clock (default) or on each arm's fresh status")
    serve.add_argument("--quiet", action="store_true", help="no progress messages")
    serve.set_defaults(func=cmd_serve)
    hub = sub.add_parser("tcpq-hub", help="the hub of LCM's tcpq:// provider on 127.0.0.1 "
                                          "(two processes on one machine, no multicast)")
    hub.add_argument("--port", type=int, default=7700, help="TCP port (default 7700)")
    hub.add_argument("--quiet", action="store_true", help="no progress messages")
    hub.set_defaults(func=_cmd_tcpq_hub)
    drv = sub.add_parser("sim-driver", help="the scenario's simulated arms behind their "
                                            "drivers' LCM messages, at real time")
    drv.add_argument("scenario", help="scenario YAML or shipped scenario name")
    drv.add_argument("--lcm-url", default=None, help="LCM URL (default: LCM's own)")
    drv.add_argument("--t-end", type=float, default=None, help="stop earlier (s)")
    drv.add_argument("--command-wait", type=float, default=60.0,
                     help="wait for the first command (s, default 60)")
    drv.add_argument("--log", default=None, metavar="FILE",
                     help="write the plant's ground truth at every tick to FILE (.npz): "
                          "t, each arm's squeeze λ (contact mode: from the pads' contact "
                          "forces) and the box's pose")
    drv.add_argument("--quiet", action="store_true", help="no progress messages")
    drv.set_defaults(func=cmd_sim_driver)


def _cmd_tcpq_hub(args) -> int:
    from drake_coop.robot.tcpq_hub import cmd_tcpq_hub

    return cmd_tcpq_hub(args)


def _error(message: str) -> int:
    from drake_coop.console import error

    return error(message)


def _load(args, wait_option: str, wait: float):
    """The scenario, its driver specs and the LCM connection, or an exit code (2) after one
    line: the preamble ``serve`` and ``sim-driver`` share (``wait_option`` names the command's
    own waiting time, ``wait`` its value, checked with the rest before anything starts)."""
    from drake_coop.robot.driver_spec import driver_specs
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.model_check import check_models
    from drake_coop.scenario.resources import find_scenario
    from drake_coop.scenario.schema import ScenarioError
    from drake_coop.experiment.plan import check_run_size

    try:
        check_lcm_url(args.lcm_url)
    except ValueError as exc:
        return _error(str(exc))
    if args.t_end is not None and not (0 < args.t_end < math.inf):
        return _error(f"--t-end must be a finite number > 0, got {args.t_end}")
    try:
        scenario = load_scenario(args.scenario and find_scenario(args.scenario))
        check_run_size(scenario, args.t_end)
        specs = driver_specs(scenario, check_models(scenario))
    except ScenarioError as exc:
        return _error(str(exc))
    if not (0 < wait < math.inf):
        return _error(f"{wait_option} must be a finite number > 0, got {wait}")
    try:
        lcm = _make_lcm(args.lcm_url)
    except ValueError as exc:
        return _error(str(exc))
    return scenario, specs, lcm


def check_lcm_url(url) -> None:
    """Raise ``ValueError`` (one line naming ``--lcm-url``) unless ``url`` is None or a URL of
    one of :data:`LCM_PROVIDERS`.

    Parameters
    ----------
    url : str or None
        ``--lcm-url``'s value.
    """
    if url is None:
        return
    if not isinstance(url, str) or "://" not in url:
        raise ValueError(f"--lcm-url must be a URL such as memq:// or udpm://239.255.76.67:7667"
                         f"?ttl=0, got {url!r}")
    provider = url.split("://", 1)[0]
    if provider not in LCM_PROVIDERS:
        raise ValueError(f"--lcm-url {url!r}: unknown LCM provider {provider!r}; one of "
                         + ", ".join(f"{p}://" for p in LCM_PROVIDERS))


def _make_lcm(url):
    from pydrake.lcm import DrakeLcm

    check_lcm_url(url)
    try:
        return DrakeLcm(url) if url is not None else DrakeLcm()
    except Exception as exc:
        raise ValueError(f"--lcm-url {url!r}: {' '.join(str(exc).split())[:200]}") from None


def cmd_serve(args) -> int:
    """``drake-coop serve``: see the module's docstring.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit code: 0 done, 1 stopped by the watchdog (or no status), 2 bad input.
    """
    if args.delay_margin is not None and not (0 <= args.delay_margin < 1):
        return _error(f"--delay-margin must be a number in [0, 1) s, got {args.delay_margin}")
    loaded = _load(args, "--status-wait", args.status_wait)
    if isinstance(loaded, int):
        return loaded
    scenario, specs, lcm = loaded
    robots = [s.robot for s in specs]
    if getattr(args, "robot", None) is not None and args.robot not in robots:
        return _error(f"--robot: one of {', '.join(robots)} (got {args.robot!r})")
    from drake_coop.experiment.plan import plan_run
    from drake_coop.results.run_folder import OutputFolderError, RunFolder
    from drake_coop.robot.realtime import missing_realtime, realtime_settings, unlock_memory

    rt = realtime_settings()
    if getattr(args, "require_rt", False):
        # memory is locked (for good: MCL_FUTURE) only once the rest is granted
        missing = missing_realtime(rt, memory=False)
        if not missing:
            rt = realtime_settings(lock_memory=True)
            missing = missing_realtime(rt)
            if missing:
                unlock_memory()
        else:
            missing.append("locked memory (not attempted without the rest)")
        if missing:
            return _error("--require-rt: missing " + "; ".join(missing))
    plan = plan_run(scenario, args.t_end)
    folder = RunFolder(args.out)
    try:
        staging = folder.prepare(plan.k_end + 1, robots=1 if args.robot else len(specs),
                                 replace=args.force)
    except OutputFolderError as exc:
        if rt["mlockall"] == "ok":
            unlock_memory()
        return _error(str(exc))
    try:
        return _serve(args, scenario, specs, plan, lcm, folder, staging, rt)
    except BaseException:
        folder.discard()
        raise


def _serve(args, scenario, specs, plan, lcm, folder, staging, realtime) -> int:
    import numpy as np

    from drake_coop.control.watchdog import STATUS_OK
    from drake_coop.experiment.simulate import rest_posture
    from drake_coop.results.io import atomic_write_text
    from drake_coop.robot.collector import ManagedCollector
    from drake_coop.robot.pacing import (
        PacingRecord,
        pacing_summary,
        pump_until,
        summary_line,
        write_pacing_csv,
    )
    from drake_coop.robot.pacing_plot import plot_pacing
    from drake_coop.robot.realtime import missing_realtime
    from drake_coop.robot.serve_loop import (
        STOP_CHANNEL,
        ServeLoop,
        StopListener,
        run_on_arrival,
        status_arrivals,
    )
    from drake_coop.robot.status import check_panda_status
    from drake_coop.scenario.loading import dump_scenario

    quiet = args.quiet
    memq = isinstance(args.lcm_url, str) and args.lcm_url.startswith("memq://")
    names = [s.robot for s in specs]
    served = names if args.robot is None else [args.robot]
    margin, margins, margin_reason = serve_margin(scenario, served, args.delay_margin, quiet)
    index = [names.index(r) for r in served]
    loop = ServeLoop(scenario, plan, lcm, specs, robots=served)
    specs = loop.specs                    # the arms served, their torque limits resolved
    arrivals = status_arrivals(lcm, specs)   # every message's bytes checked as it arrives
    stop = StopListener(lcm, served)
    record = PacingRecord(period=plan.h, driver_period=max(s.period for s in specs))
    status, message, code, trip = "ok", f"completed {plan.t_end:g} s", 0, None
    interrupted: BaseException | None = None
    started = False          # the loop has begun commanding the arms
    collector = ManagedCollector()

    try:
        if not quiet:
            print("drake-coop: waiting for the status of "
                  + ", ".join(s.status_channel for s in specs)
                  + (f" ({MEMQ_NOTE})" if memq else ""), file=sys.stderr)
        deadline = time.perf_counter() + args.status_wait
        while not arrivals.all_arrived() and time.perf_counter() < deadline:
            pump_until(lcm, min(deadline, time.perf_counter() + 0.05))
        if not arrivals.all_arrived():
            missing = [c for c, n in arrivals.count.items() if n == 0]
            print(f"drake-coop: no status on {', '.join(missing)} within "
                  f"{args.status_wait:g} s ("
                  + (MEMQ_NOTE if memq else "is the driver running, on the same --lcm-url?")
                  + "); nothing written", file=sys.stderr)
            folder.discard()
            return 1
        rest, _ = rest_posture(scenario, list(plan.arms))
        q0 = []
        for i, spec in zip(index, specs):
            q, _, fault, value = arrivals.parsed(spec.status_channel)
            if fault == STATUS_OK and arrivals.faulty[spec.status_channel] is not None:
                fault = check_panda_status(arrivals.faulty[spec.status_channel], spec.n)[2]
            if fault == 4:           # a driver of another arm: a setup error, nothing started
                print(f"drake-coop: robots[{i}].driver: the status on {spec.status_channel} "
                      f"has {value:.0f} joints, the arm {spec.n}", file=sys.stderr)
                folder.discard()
                return 2
            # any other fault trips the watchdog at the first tick
            q0.append(q if fault == STATUS_OK else np.asarray(rest[i], dtype=float))
        loop.start(q0)
        if not quiet:
            print(f"drake-coop: serving {', '.join(served)} at h = {plan.h * 1e3:g} ms to "
                  f"t = {plan.t_end:g} s, ticking on "
                  + ("each status's arrival" if args.tick == "arrival" else "the wall clock"),
                  file=sys.stderr)
        started = True
        try:
            with collector:          # Python's collector only in the slack after a command
                reason = run_on_arrival(loop, lcm, arrivals, plan.k_end, record,
                                        lambda k: "tripped" if loop.tripped() else "",
                                        stop=stop, on_arrival=args.tick == "arrival",
                                        collector=collector)
        except Exception as exc:       # a defect, not an input: the record is kept all the same
            status, code = "failed", 1
            message = (f"error at t = {loop.time():.3f} s: {type(exc).__name__}: "
                       + " ".join(str(exc).split())[:200])
        else:
            trip = loop.tripped() if reason else None
            if trip is not None:
                status, code = "stopped", 1
                message = (f"watchdog at t = {loop.time():.3f} s: {trip['robot']}: "
                           f"{trip['reason']} on {trip['channel']}")
            elif reason.startswith("stop: "):
                status, code = "stopped", 1
                trip = {"robot": reason[6:].split(":", 1)[0], "channel": STOP_CHANNEL,
                        "reason": reason[6:]}
                message = (f"stopped at t = {loop.time():.3f} s by another serve on "
                           f"{STOP_CHANNEL}: {reason[6:]}")
    except KeyboardInterrupt as exc:    # Ctrl-C, or SIGTERM (raised as one by the command line)
        status, interrupted = "interrupted", exc
        message = f"interrupted at t = {loop.time():.3f} s"
    finally:
        if started:
            loop.send_safe()
            if status != "ok" and not (trip and trip["channel"] == STOP_CHANNEL):
                # the other arms' serve processes stop too (a trip, a defect, Ctrl-C)
                StopListener.publish(lcm, served[0], trip["reason"] if trip else message)
    if not started:                     # interrupted while waiting: nothing to keep
        folder.discard()
        print("drake-coop: interrupted while waiting for the first status; nothing written",
              file=sys.stderr)
        raise interrupted
    summary = pacing_summary(record, margin, margin_reason=margin_reason,
                             collector=collector.summary())
    meta = {"status": status, "message": message, "command": "serve",
            "watchdog": trip, "robots": served, "tick": args.tick,
            "stop_channel": STOP_CHANNEL,
            "lcm_url": args.lcm_url, "control_period": plan.h,
            "channels": {s.robot: [s.status_channel, s.command_channel] for s in specs},
            "safe_command": {s.robot: s.safe_command for s in specs},
            "torque_limits": {s.robot: [float(v) for v in s.torque_limits] for s in specs},
            "realtime": realtime, "realtime_missing": missing_realtime(realtime),
            "pacing": summary, "delay_margin": margins}
    write_pacing_csv(staging / "pacing.csv", record)
    if record.k:
        plot_pacing(staging / "pacing.png", record, summary)
    atomic_write_text(staging / "scenario.yaml", dump_scenario(scenario))
    atomic_write_text(staging / "run.json", json.dumps(meta, indent=1, default=float))
    folder.commit()
    print(f"drake-coop: {message}; safe command sent", file=sys.stderr)
    if record.k and not quiet:
        print(f"drake-coop: {summary_line(summary)}", file=sys.stderr)
    if interrupted is not None:
        raise interrupted      # the command line's exit code: 130 (Ctrl-C) or 143 (SIGTERM)
    return code


def serve_margin(scenario, served: list[str], given: float | None, quiet: bool = False
                 ) -> tuple[float | None, dict, str]:
    """The delay margin ``serve`` checks its loop's delay against: ``--delay-margin`` when
    given, else the margins of the served arms from the stability map, without and with delay
    compensation (:func:`~drake_coop.stability.margin.delay_margins`), the scenario's own one
    checked; when there is none, one line saying why (printed, and kept in ``run.json``).

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    served : list of str
        The arms this ``serve`` runs.
    given : float or None
        ``--delay-margin``, s.
    quiet : bool
        No progress lines.

    Returns
    -------
    (margin, margins, reason)
        The margin checked (s, or None), ``run.json``'s ``delay_margin`` entry, and why there
        is no margin (``''`` when there is one).
    """
    if given is not None:
        return given, {"given_s": given, "line": f"delay margin {given * 1e3:g} ms (given)"}, ""
    from drake_coop.stability.margin import delay_margins

    if not quiet:
        print("drake-coop: computing the delay margin of " + ", ".join(served)
              + " without and with delay compensation (stability map, free point)",
              file=sys.stderr)
    try:
        margins = delay_margins(scenario, robots=served)
    except Exception as exc:       # the map's own failures are rows; this is anything else
        reason = ("the stability map could not be built for this scenario: "
                  f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}")
        if not quiet:
            print(f"drake-coop: no delay margin: {reason}", file=sys.stderr)
        return None, {"line": reason, "error": reason}, reason
    m = margins.configured
    entry = margins.as_dict()
    if not quiet:
        print(f"drake-coop: {entry['line']}", file=sys.stderr)
    return m.margin_s, entry, m.reason


def cmd_sim_driver(args) -> int:
    """``drake-coop sim-driver``: see the module's docstring.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit code: 0 done, 1 no command within ``--command-wait``, 2 bad input.
    """
    loaded = _load(args, "--command-wait", args.command_wait)
    if isinstance(loaded, int):
        return loaded
    scenario, specs, lcm = loaded
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.simulate import guard_chunks
    from drake_coop.robot.drivers import add_driver_side, add_lcm_interface
    from drake_coop.robot.loopback import initialize_sides
    from drake_coop.robot.pacing import pump_until

    plan = plan_run(scenario, args.t_end)
    log = getattr(args, "log", None)
    if log is not None:
        from pathlib import Path

        if not str(log).endswith(".npz") or not Path(log).resolve().parent.is_dir():
            return _error(f"--log must name a .npz file in an existing folder, got {log!r}")
        if Path(log).exists():
            return _error(f"--log {log!r} exists; not replaced")
    builder = DiagramBuilder()
    add_lcm_interface(builder, lcm)
    side = add_driver_side(builder, scenario, lcm, specs)
    truth = add_truth_log(builder, side, plan.h) if log is not None else None
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    initialize_sides(scenario, plan, context, side, None)
    simulator.Initialize()
    # Brakes on: the status at rest, every driver cycle, until the first command arrives.
    period = min(s.period for s in specs)
    deadline = time.perf_counter() + args.command_wait
    if not args.quiet:
        print("drake-coop: sim-driver publishing "
              + ", ".join(s.status_channel for s in specs) + "; waiting for a command",
              file=sys.stderr)
    # (the command subscribers' own counts: a plain Python handler must not be pumped by the
    # LcmInterfaceSystem inside AdvanceTo, see add_lcm_interface)
    while not any(arm.command_subscriber.WaitForMessage(0, None, 1e-6) > 0
                  for arm in side.arms):
        if time.perf_counter() > deadline:
            print(f"drake-coop: no command on {', '.join(s.command_channel for s in specs)} "
                  f"within {args.command_wait:g} s", file=sys.stderr)
            return 1
        for arm in side.arms:
            arm.status_publisher.ForcedPublish(arm.status_publisher.GetMyContextFromRoot(context))
        pump_until(lcm, time.perf_counter() + period)
    simulator.set_target_realtime_rate(1.0)
    simulator.ResetStatistics()      # the wall clock starts now, not at Initialize()
    plant_context = side.coop.plant.GetMyMutableContextFromRoot(context)
    start = time.perf_counter()
    worst = 0.0          # how far the simulated time fell behind the wall clock (s)
    for k_stop in guard_chunks(plan, scenario.guards.check_period):
        simulator.AdvanceTo(k_stop * plan.h)
        worst = max(worst, time.perf_counter() - start - context.get_time())
        if k_stop in plan.switches:
            side.coop.set_held(plant_context, plan.switches[k_stop])
    if truth is not None:
        write_truth_log(log, truth, context)
    if not args.quiet:
        print(f"drake-coop: sim-driver done at t = {context.get_time():.3f} s after "
              f"{time.perf_counter() - start:.3f} s of wall time (at most {worst * 1e3:.1f} ms "
              "behind the wall clock)", file=sys.stderr)
    return 0


def add_truth_log(builder, side, h: float) -> dict:
    """Loggers of the driver's plant's ground truth at every tick ``h`` (``sim-driver
    --log``): in contact mode each arm's pad contact force (the C++ hold of
    :func:`~drake_coop.plant.ground_truth.add_pad_force_log`: the force of the plant step
    before the tick) and the box's state; in the other modes the arms' state only.

    Parameters
    ----------
    builder : DiagramBuilder
        The driver side's builder (before ``Build``).
    side : object
        The simulated driver's side (its ``coop`` plant handles).
    h : float
        The control period, s: the loggers publish every tick.

    Returns
    -------
    dict
        ``normals`` (each arm's constraint normals), ``arms`` (each arm's state logger) and,
        in contact mode, ``pads`` (the pads' forces) and ``box`` (the box's state logger).
    """
    import numpy as np
    from pydrake.systems.primitives import LogVectorOutput

    coop = side.coop
    out: dict = {"normals": [np.asarray(a.arm.N, dtype=float) for a in coop.arms]}
    if coop.mode == "contact":
        from drake_coop.plant.ground_truth import add_pad_force_log

        pads = add_pad_force_log(builder, coop, h, [], log=False)
        out["pads"] = LogVectorOutput(pads.hold, builder, publish_period=h)
        out["box"] = LogVectorOutput(coop.plant.get_state_output_port(
            coop.grasp.box.model_instance()), builder, publish_period=h)
    out["arms"] = [LogVectorOutput(coop.plant.get_state_output_port(a.instance), builder,
                                   publish_period=h) for a in coop.arms]
    return out


def write_truth_log(path, truth: dict, context) -> None:
    """``sim-driver --log``'s file (written whole): ``t``; ``lambda`` (ticks × arms × m:
    ``N_i F_i``, NaN outside contact mode); ``box_state`` (the box's positions and
    velocities, contact mode); ``arm<i>_state``.

    Parameters
    ----------
    path : str or Path
        The ``.npz`` file to write (whole, or not at all).
    truth : dict
        The loggers of :func:`add_truth_log`.
    context : Context
        The driver's root context at the end of the run.
    """
    import io

    import numpy as np

    from drake_coop.results.io import atomic_write_bytes

    arms = [log.FindLog(context) for log in truth["arms"]]
    t = arms[0].sample_times()
    data = {"t": t}
    normals = truth["normals"]
    if "pads" in truth:
        F = truth["pads"].FindLog(context).data().T          # ticks × 3·arms
        lam = [np.atleast_2d(N) @ F[:, 3 * i:3 * i + 3].T for i, N in enumerate(normals)]
        data["lambda"] = np.stack([x.T for x in lam], axis=1)
        data["box_state"] = truth["box"].FindLog(context).data().T
    for i, log in enumerate(arms):
        data[f"arm{i}_state"] = log.data().T
    buffer = io.BytesIO()
    np.savez(buffer, **data)
    atomic_write_bytes(path, buffer.getvalue())
