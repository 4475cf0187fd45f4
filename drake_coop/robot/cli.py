"""``drake-coop serve SCENARIO --lcm-url URL --out DIR`` and
``drake-coop sim-driver SCENARIO --lcm-url URL``: the experiment split at the robot's cable.

``serve`` runs each arm's control blocks against the wall clock over its driver's LCM
messages (:mod:`drake_coop.robot.drivers`, :mod:`drake_coop.robot.pacing`): it waits for a
status from every arm, starts the observers at the first reading, and then ticks every ``h``;
it stops at the task's end, when a watchdog trips (one line: which arm, why), or on Ctrl-C /
SIGTERM, and in every case sends each driver its safe command last. The run folder gets
``run.json`` (status, reason, pacing summary against the delay margin), ``pacing.csv`` and
``pacing.png``.

Before anything starts, the LCM URL is checked: required (no multicast by default), of a
known provider (``tcpq``, ``memq``, or an explicit ``udpm`` / ``mpudpm``; ``memq://`` is
in-process only: ``serve`` says so, since no driver in another process can reach it). The loop starts once every arm's status channel has carried a message;
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

``sim-driver`` runs the scenario's plant behind the same messages at the driver's rate
(:mod:`drake_coop.robot.sim_driver`): paced at real time, or in lockstep with ``serve
--lockstep`` (both: ``--lockstep``; :mod:`drake_coop.robot.lockstep`), optionally emulating
drake-franka-driver (``--emulate``).

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
#: ``--lcm-url``'s help.
LCM_URL_HELP = ("LCM URL, required: tcpq://127.0.0.1:PORT (with drake-coop tcpq-hub), memq:// "
                "(one process) or an explicit udpm:// (multicast)")
#: drake-franka-driver's emulation (``sim-driver --emulate``), its default cutoff and
#: libfranka's "no filter" (Hz): :mod:`drake_coop.robot.torque_driver`.
EMULATE = "drake-franka-driver"
FRANKA_LOW_PASS_HZ = 30.0
FRANKA_NO_FILTER_HZ = 1000.0
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
    serve.add_argument("--lcm-url", default=None, help=LCM_URL_HELP)
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
    serve.add_argument("--lockstep", action="store_true",
                       help="tick only once every arm's status of the tick has arrived "
                            "(simulated time; with sim-driver --lockstep)")
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
    drv.add_argument("--lcm-url", default=None, help=LCM_URL_HELP)
    drv.add_argument("--emulate", choices=(EMULATE,), default=None,
                     help="emulate drake-franka-driver's torque mode point by point (7-joint "
                          "arms only)")
    drv.add_argument("--low-pass-freq", type=float, default=FRANKA_LOW_PASS_HZ, metavar="HZ",
                     help="with --emulate: the driver's torque cutoff (its --low_pass_freq, "
                          f"default {FRANKA_LOW_PASS_HZ:g}; {FRANKA_NO_FILTER_HZ:g}: none)")
    drv.add_argument("--lockstep", action="store_true",
                     help="advance the plant only once every arm's command of the tick has "
                          "arrived (simulated time; with serve --lockstep)")
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
    from drake_coop.experiment.ticks import check_run_size

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
    """Raise ``ValueError`` (one line naming ``--lcm-url``) unless ``url`` is a URL of one of
    :data:`LCM_PROVIDERS` (required: none, LCM's own default, would be multicast).

    Parameters
    ----------
    url : str or None
        ``--lcm-url``'s value.
    """
    if url is None:
        raise ValueError("--lcm-url is required (no multicast by default): "
                         "tcpq://127.0.0.1:PORT with drake-coop tcpq-hub, memq:// in one "
                         "process, or udpm://GROUP:PORT?ttl=0 explicitly")
    if not isinstance(url, str) or "://" not in url:
        raise ValueError(f"--lcm-url must be a URL such as memq:// or udpm://239.255.76.67:7667"
                         f"?ttl=0, got {url!r}")
    provider = url.split("://", 1)[0]
    if provider not in LCM_PROVIDERS:
        raise ValueError(f"--lcm-url {url!r}: unknown LCM provider {provider!r}; one of "
                         + ", ".join(f"{p}://" for p in LCM_PROVIDERS))


def _make_lcm(url):
    from drake_coop.robot.hub_link import WatchedLcm   # tcpq://: the hub's death is caught

    check_lcm_url(url)
    try:
        return WatchedLcm(url)
    except Exception as exc:
        raise ValueError(f"--lcm-url {url!r}: {' '.join(str(exc).split())[:200]}") from None


def cmd_serve(args) -> int:
    """``drake-coop serve``'s exit code: 0 done, 1 stopped by the watchdog (or no status), 2 bad
    input (the command: see the module's docstring).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
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
        return _serve(args, specs, plan, lcm, folder, staging, rt)
    except BaseException:
        folder.discard()
        raise


def _serve(args, specs, plan, lcm, folder, staging, realtime) -> int:
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
    from drake_coop.robot.cell import (
        CELL_CHANNEL,
        START_GRACE,
        CellStops,
        CellWatch,
        printable,
    )
    from drake_coop.robot.safe_start import arms_refusal, first_readings, start_ramp
    from drake_coop.robot.status import check_panda_status
    from drake_coop.robot.hub_link import HUB_LOST_LINE, HubLost
    from drake_coop.scenario.cell import CellSettings
    from drake_coop.scenario.loading import dump_scenario

    scenario = plan.scenario
    quiet = args.quiet
    memq = isinstance(args.lcm_url, str) and args.lcm_url.startswith("memq://")
    names = [s.robot for s in specs]
    served = names if args.robot is None else [args.robot]
    margin, margins, margin_reason = serve_margin(scenario, served, args.delay_margin, quiet)
    index = [names.index(r) for r in served]
    loop = ServeLoop(plan, lcm, specs, robots=served)
    specs = loop.specs                    # the arms served, their torque limits resolved
    arrivals = status_arrivals(lcm, specs)   # every message's bytes checked as it arrives
    lockstep = None
    if getattr(args, "lockstep", False):      # every status by its stamp, from the first
        from drake_coop.robot.lockstep import LockstepStatuses

        lockstep = LockstepStatuses(lcm, specs)
    settings = scenario.cell if scenario.cell is not None else CellSettings()
    cell = CellWatch(lcm, served, names, silence_ticks=settings.partner_silence_ticks,
                     grace_ticks=int(math.ceil(START_GRACE / plan.h)))
    stop = StopListener(lcm, served, session=cell.session)
    record = PacingRecord(period=plan.h, driver_period=max(s.period for s in specs))
    status, message, code, trip = "ok", f"completed {plan.t_end:g} s", 0, None
    interrupted: BaseException | None = None
    started = False          # the loop has begun commanding the arms
    hub_lost = False         # the tcpq hub died: nothing can be sent any more
    collector = ManagedCollector()

    try:
        if not quiet:
            print("drake-coop: waiting for the status of "
                  + ", ".join(s.status_channel for s in specs)
                  + (f" ({MEMQ_NOTE})" if memq else ""), file=sys.stderr)
        deadline = time.perf_counter() + args.status_wait
        first = {}                     # each arm's first reading and when it came
        while time.perf_counter() < deadline:
            if cell.ready() and arrivals.all_arrived() or cell.reason is not None:
                break                  # (ready() first: it checks the heartbeats heard)
            cell.announce("waiting")
            pump_until(lcm, min(deadline, time.perf_counter() + 0.05))
            first_readings(arrivals, specs, first)
        if cell.reason is not None:    # a duplicate: this one does not begin
            print(f"drake-coop: {'--robot: ' if args.robot else ''}{cell.reason}; nothing "
                  "written", file=sys.stderr)
            folder.discard()
            return 2
        if not arrivals.all_arrived():
            missing = [c for c, n in arrivals.count.items() if n == 0]
            print(f"drake-coop: no status on {', '.join(missing)} within "
                  f"{args.status_wait:g} s ("
                  + (MEMQ_NOTE if memq else "is the driver running, on the same --lcm-url?")
                  + "); nothing written", file=sys.stderr)
            folder.discard()
            return 1
        if cell.missing():
            print(f"drake-coop: no serve for {', '.join(cell.missing())} within "
                  f"{args.status_wait:g} s on {CELL_CHANNEL} (start one serve per arm with "
                  "--robot, on the same --lcm-url); nothing written", file=sys.stderr)
            folder.discard()
            return 1
        rest, _ = rest_posture(plan)
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
        refusal = arms_refusal(arrivals, specs, index, q0, rest, first, settings)
        if refusal is not None:        # an arm moving or away from its start: nothing begins
            print(f"drake-coop: {refusal}; nothing written", file=sys.stderr)
            cell.announce("stopped")
            StopListener.publish(lcm, ",".join(served), refusal, session=cell.session)
            folder.discard()
            return 1
        loop.start(q0)
        loop.ramp = start_ramp(loop, q0, settings.start_ramp, plan.h)
        cell.begin()
        if not quiet:
            print(f"drake-coop: serving {', '.join(served)} at h = {plan.h * 1e3:g} ms to "
                  f"t = {plan.t_end:g} s, ticking on "
                  + ("the driver's messages (lockstep: simulated time)" if lockstep is not None
                     else "each status's arrival" if args.tick == "arrival"
                     else "the wall clock"),
                  file=sys.stderr)
        started = True
        try:
            def after_tick(k):
                return "tripped" if loop.tripped() else (cell.tick() or "")

            if lockstep is not None:    # simulated time: no deadline for the collector to miss
                from drake_coop.robot.lockstep import run_lockstep

                def after_lockstep_tick(k):   # the heartbeat went out before the command
                    return "tripped" if loop.tripped() else (cell.watch() or "")

                reason = run_lockstep(loop, lcm, lockstep, plan.k_end, record,
                                      after_lockstep_tick, stop=CellStops(stop, cell),
                                      timeout=args.status_wait, before_send=cell.beat)
            else:
                with collector:          # Python's collector only in the slack after a command
                    reason = run_on_arrival(loop, lcm, arrivals, plan.k_end, record, after_tick,
                                            stop=CellStops(stop, cell),
                                            on_arrival=args.tick == "arrival",
                                            collector=collector)
        except HubLost:
            raise
        except Exception as exc:       # a defect, not an input: the record is kept all the same
            status, code = "failed", 1
            message = (f"error at t = {loop.time():.3f} s: {type(exc).__name__}: "
                       + " ".join(str(exc).split())[:200])
        else:
            trip = loop.tripped() if reason else None
            if reason and trip is None and cell.reason is not None:   # silent, duplicate
                status, code = "stopped", 1
                trip = {"robot": cell.arm, "channel": CELL_CHANNEL,
                        "reason": cell.reason.removeprefix(f"{cell.arm}: ")}
                message = f"stopped at t = {loop.time():.3f} s: {cell.reason}"
            elif trip is not None:
                status, code = "stopped", 1
                message = (f"watchdog at t = {loop.time():.3f} s: {trip['robot']}: "
                           f"{trip['reason']} on {trip['channel']}")
            elif reason.startswith("stop: "):
                status, code = "stopped", 1
                trip = {"robot": reason[6:].split(":", 1)[0], "channel": STOP_CHANNEL,
                        "reason": reason[6:]}
                message = (f"stopped at t = {loop.time():.3f} s by another serve on "
                           f"{STOP_CHANNEL}: {reason[6:]}")
            elif reason:                      # lockstep: the driver went silent
                status, code = "stopped", 1
                message = f"stopped at t = {loop.time():.3f} s: {reason}"
    except KeyboardInterrupt as exc:    # Ctrl-C, or SIGTERM (raised as one by the command line)
        status, interrupted = "interrupted", exc
        message = f"interrupted at t = {loop.time():.3f} s"
    except HubLost:                     # caught before LCM's C client aborts the process
        status, code, hub_lost = "stopped", 1, True
        message = f"stopped at t = {loop.time():.3f} s: {HUB_LOST_LINE}"
    finally:
        if started and not hub_lost:
            loop.send_safe()
            cell.announce("done" if status == "ok" else "stopped")
            if status != "ok" and not (trip and trip["channel"] == STOP_CHANNEL):
                # the other arms' serve processes stop too (a trip, a defect, Ctrl-C),
                # told which arm tripped (this process's arms for any other stop)
                StopListener.publish(lcm, trip["robot"] if trip else ",".join(served),
                                     trip["reason"] if trip else message,
                                     session=cell.session)
    if not started and hub_lost:
        folder.discard()
        print(f"drake-coop: {HUB_LOST_LINE}, while waiting for the first status; nothing "
              "written", file=sys.stderr)
        return 1
    if not started:                     # interrupted while waiting: nothing to keep
        folder.discard()
        print("drake-coop: interrupted while waiting for the first status; nothing written",
              file=sys.stderr)
        raise interrupted
    summary = pacing_summary(record, margin, margin_reason=margin_reason,
                             collector=collector.summary())
    message = printable(message, 1000)         # no control bytes to a terminal or run.json
    if trip is not None:
        trip = {key: printable(value, 1000) for key, value in trip.items()}
    meta = {"status": status, "message": message, "command": "serve",
            "watchdog": trip, "robots": served, "tick": args.tick,
            "lockstep": lockstep is not None,
            "stop_channel": STOP_CHANNEL,
            "cell": {"channel": CELL_CHANNEL, "session": cell.session, "pid": cell.pid,
                     "partners": cell.partners, "ignored_heartbeats": cell.ignored,
                     "start_ramp_ticks": loop.ramp.ticks if loop.ramp is not None else 0},
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
    print(f"drake-coop: {message}" + ("" if hub_lost else "; safe command sent"),
          file=sys.stderr)
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
    """``drake-coop sim-driver``'s exit code, from
    :func:`drake_coop.robot.sim_driver.cmd_sim_driver`.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from drake_coop.robot.sim_driver import cmd_sim_driver as run

    return run(args, _load)
