"""``drake-coop serve SCENARIO --lcm-url URL --out DIR`` and
``drake-coop sim-driver SCENARIO --lcm-url URL``: the experiment split at the robot's cable.

``serve`` runs each arm's control blocks against the wall clock over its driver's LCM
messages (:mod:`drake_coop.robot.drivers`, :mod:`drake_coop.robot.pacing`): it waits for a
status from every arm, starts the observers at the first reading, and then ticks every ``h``;
it stops at the task's end, when a watchdog trips (one line: which arm, why), or on Ctrl-C /
SIGTERM, and in every case sends each driver its safe command last. The run folder gets
``run.json`` (status, reason, pacing summary against the delay margin), ``pacing.csv`` and
``pacing.png``.

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


def add_robot_parsers(sub) -> None:
    """Register ``serve`` and ``sim-driver`` on the ``drake-coop`` subparsers."""
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
    serve.add_argument("--quiet", action="store_true", help="no progress messages")
    serve.set_defaults(func=cmd_serve)
    drv = sub.add_parser("sim-driver", help="the scenario's simulated arms behind their "
                                            "drivers' LCM messages, at real time")
    drv.add_argument("scenario", help="scenario YAML or shipped scenario name")
    drv.add_argument("--lcm-url", default=None, help="LCM URL (default: LCM's own)")
    drv.add_argument("--t-end", type=float, default=None, help="stop earlier (s)")
    drv.add_argument("--command-wait", type=float, default=60.0,
                     help="wait for the first command (s, default 60)")
    drv.add_argument("--quiet", action="store_true", help="no progress messages")
    drv.set_defaults(func=cmd_sim_driver)


def _error(message: str) -> int:
    from drake_coop.console import error

    return error(message)


def _load(args, wait_option: str, wait: float):
    """The scenario, its driver specs and the LCM connection, or an exit code (2) after one
    line: the preamble ``serve`` and ``sim-driver`` share (``wait_option`` names the command's
    own waiting time, ``wait`` its value, checked with the rest before anything starts)."""
    from drake_coop.robot.drivers import driver_specs
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.model_check import check_models
    from drake_coop.scenario.resources import find_scenario
    from drake_coop.scenario.schema import ScenarioError
    from drake_coop.experiment.plan import check_run_size

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


def _make_lcm(url):
    from pydrake.lcm import DrakeLcm

    if url is not None and (not isinstance(url, str) or "://" not in url):
        raise ValueError(f"--lcm-url must be a URL such as memq:// or udpm://239.255.76.67:7667"
                         f"?ttl=0, got {url!r}")
    try:
        return DrakeLcm(url) if url is not None else DrakeLcm()
    except Exception as exc:
        raise ValueError(f"--lcm-url {url!r}: {' '.join(str(exc).split())[:200]}") from None


def cmd_serve(args) -> int:
    """``drake-coop serve``: see the module's docstring."""
    if args.delay_margin is not None and not (0 <= args.delay_margin < 1):
        return _error(f"--delay-margin must be a number in [0, 1) s, got {args.delay_margin}")
    loaded = _load(args, "--status-wait", args.status_wait)
    if isinstance(loaded, int):
        return loaded
    scenario, specs, lcm = loaded
    from drake_coop.experiment.plan import plan_run
    from drake_coop.results.run_folder import OutputFolderError, RunFolder

    plan = plan_run(scenario, args.t_end)
    folder = RunFolder(args.out)
    try:
        staging = folder.prepare(plan.k_end + 1, robots=len(specs), replace=args.force)
    except OutputFolderError as exc:
        return _error(str(exc))
    try:
        return _serve(args, scenario, specs, plan, lcm, folder, staging)
    except BaseException:
        folder.discard()
        raise


def _serve(args, scenario, specs, plan, lcm, folder, staging) -> int:
    import numpy as np
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from drake import lcmt_panda_status
    from drake_coop.results.io import atomic_write_text
    from drake_coop.robot.drivers import (
        COMMAND_OFFSET,
        add_controller_side,
        safe_command_message,
    )
    from drake_coop.robot.loopback import initialize_sides, tripped
    from drake_coop.robot.pacing import (
        PacingRecord,
        StatusArrivals,
        delay_margin,
        pacing_summary,
        plot_pacing,
        pump_until,
        run_paced,
        summary_line,
        write_pacing_csv,
    )
    from drake_coop.scenario.loading import dump_scenario

    quiet = args.quiet
    margin = args.delay_margin
    if margin is None:
        if not quiet:
            print("drake-coop: computing the delay margin (stability map, free point)",
                  file=sys.stderr)
        margin = delay_margin(scenario)
        margin = None if math.isnan(margin) else margin
    builder = DiagramBuilder()
    # No LcmInterfaceSystem: the wall-clock loop pumps LCM between ticks (and records each
    # status's arrival with a plain handler, which must not run inside AdvanceTo).
    side = add_controller_side(builder, scenario, lcm, plan, specs)
    diagram = builder.Build()
    arrivals = StatusArrivals(lcm, [s.status_channel for s in specs])
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    record = PacingRecord(period=plan.h, driver_period=max(s.period for s in specs))
    status, message, code = "ok", f"completed {plan.t_end:g} s", 0
    interrupted: BaseException | None = None
    last_q = [None] * len(specs)

    def send_safe() -> None:
        """Each driver's safe command (zero torque, or the hold torque at the last reading)."""
        for i, (arm, spec) in enumerate(zip(side.arms, specs)):
            q = last_q[i]
            tau = (np.zeros(spec.n) if spec.safe_command == "zero_torque" or q is None
                   else arm.hold_torque(q))
            msg = safe_command_message(spec, tau, int(time.time() * 1e6))
            lcm.Publish(spec.command_channel, msg.encode())

    try:
        if not quiet:
            print("drake-coop: waiting for the status of "
                  + ", ".join(s.status_channel for s in specs), file=sys.stderr)
        deadline = time.perf_counter() + args.status_wait
        while not arrivals.all_arrived() and time.perf_counter() < deadline:
            pump_until(lcm, min(deadline, time.perf_counter() + 0.05))
        if not arrivals.all_arrived():
            missing = [c for c, n in arrivals.count.items() if n == 0]
            print(f"drake-coop: no status on {', '.join(missing)} within "
                  f"{args.status_wait:g} s (is the driver running, on the same --lcm-url?)",
                  file=sys.stderr)
            folder.discard()
            return 1
        q0 = []
        for spec in specs:
            msg = lcmt_panda_status.decode(arrivals.message[spec.status_channel])
            if msg.num_joints != spec.n:
                print(f"drake-coop: robots[{specs.index(spec)}].driver: the status on "
                      f"{spec.status_channel} has {msg.num_joints} joints, the arm "
                      f"{spec.n}", file=sys.stderr)
                folder.discard()
                return 2
            q0.append(np.asarray(msg.joint_position, dtype=float))
        last_q[:] = q0
        initialize_sides(scenario, plan, context, None, side, q0)
        simulator.Initialize()

        def after_tick(k: int) -> str:
            for i, arm in enumerate(side.arms):
                q = arm.status_receiver.get_position_measured_output_port().Eval(
                    arm.status_receiver.GetMyContextFromRoot(context))
                if np.all(np.isfinite(q)):
                    last_q[i] = np.array(q)
            return tripped(side, context) or ""

        if not quiet:
            print(f"drake-coop: serving {len(specs)} arms at h = {plan.h * 1e3:g} ms to "
                  f"t = {plan.t_end:g} s", file=sys.stderr)
        reason = run_paced(simulator, lcm, arrivals, plan.h, plan.k_end, COMMAND_OFFSET,
                           record, after_tick)
        if reason:
            status, code = "stopped", 1
            message = f"watchdog at t = {context.get_time():.3f} s: {reason}"
    except KeyboardInterrupt as exc:    # Ctrl-C, or SIGTERM (raised as one by the command line)
        status, interrupted = "interrupted", exc
        message = f"interrupted at t = {context.get_time():.3f} s"
    finally:
        send_safe()
    summary = pacing_summary(record, margin)
    meta = {"status": status, "message": message, "command": "serve",
            "lcm_url": args.lcm_url, "control_period": plan.h,
            "channels": {s.robot: [s.status_channel, s.command_channel] for s in specs},
            "safe_command": {s.robot: s.safe_command for s in specs},
            "pacing": summary}
    write_pacing_csv(staging / "pacing.csv", record)
    if record.k:
        plot_pacing(staging / "pacing.png", record, summary)
    atomic_write_text(staging / "scenario.yaml", dump_scenario(scenario))
    atomic_write_text(staging / "run.json", json.dumps(meta, indent=1, default=float))
    folder.commit()
    print(f"drake-coop: {message}; safe command sent", file=sys.stderr)
    if record.k:
        print(f"drake-coop: {summary_line(summary)}", file=sys.stderr)
    if interrupted is not None:
        raise interrupted      # the command line's exit code: 130 (Ctrl-C) or 143 (SIGTERM)
    return code


def cmd_sim_driver(args) -> int:
    """``drake-coop sim-driver``: see the module's docstring."""
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
    builder = DiagramBuilder()
    add_lcm_interface(builder, lcm)
    side = add_driver_side(builder, scenario, lcm, specs)
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
    if not args.quiet:
        print(f"drake-coop: sim-driver done at t = {context.get_time():.3f} s after "
              f"{time.perf_counter() - start:.3f} s of wall time (at most {worst * 1e3:.1f} ms "
              "behind the wall clock)", file=sys.stderr)
    return 0
