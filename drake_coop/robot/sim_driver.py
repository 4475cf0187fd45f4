"""``drake-coop sim-driver SCENARIO --lcm-url URL``: the scenario's plant behind each arm's
driver messages (:func:`~drake_coop.robot.drivers.add_driver_side`,
:class:`~drake_coop.robot.torque_driver.TorqueDriver`).

Paced (the default): at real time on the driver's wall clock; the status at rest is published
every cycle until a first command arrives, and each arm is then held by its driver's gravity
compensation and damping until its own first command. ``--lockstep``: the plant advances only
once every arm's command of the tick has arrived (simulated time and clock;
:mod:`drake_coop.robot.lockstep`), with ``serve --lockstep``. ``--emulate
drake-franka-driver``: that driver's torque mode point by point (7-joint arms only; a command
it throws on stops it: exit 1, one line). ``--log FILE``: the plant's ground truth at every
tick (:func:`write_truth_log`; written also when the paced driver is interrupted).
"""

from __future__ import annotations

import math
import sys
import time

from drake_coop.console import error as _error


def cmd_sim_driver(args, load) -> int:
    """``drake-coop sim-driver``: see the module's docstring.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    load : Callable
        The robot commands' preamble (``load(args, option, wait)``: the scenario, its driver
        specs and the LCM connection, or an exit code after one line;
        :mod:`drake_coop.robot.cli`).

    Returns
    -------
    int
        The exit code: 0 done, 1 no command within ``--command-wait`` (or an emulated
        driver stopped by a command it refuses), 2 bad input.
    """
    from drake_coop.robot.torque_driver import FRANKA_LOW_PASS_HZ

    loaded = load(args, "--command-wait", args.command_wait)
    if isinstance(loaded, int):
        return loaded
    scenario, specs, lcm = loaded
    emulate = getattr(args, "emulate", None)
    low_pass = getattr(args, "low_pass_freq", FRANKA_LOW_PASS_HZ)
    lockstep = getattr(args, "lockstep", False)
    if not (0 < low_pass < math.inf):
        return _error(f"--low-pass-freq must be a finite number > 0 Hz, got {low_pass}")
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from drake_coop.experiment.plan import plan_run
    from drake_coop.experiment.simulate import guard_chunks
    from drake_coop.robot.drivers import COMMAND_OFFSET, add_driver_side, add_lcm_interface
    from drake_coop.robot.hub_link import HUB_LOST_LINE, HubLost, hub_monitor, is_hub_failure
    from drake_coop.robot.loopback import initialize_sides
    from drake_coop.robot.pacing import pump_until
    from drake_coop.robot.torque_driver import DriverClock

    plan = plan_run(scenario, args.t_end)
    log = getattr(args, "log", None)
    if log is not None:
        from pathlib import Path

        if not str(log).endswith(".npz") or not Path(log).resolve().parent.is_dir():
            return _error(f"--log must name a .npz file in an existing folder, got {log!r}")
        if Path(log).exists():
            return _error(f"--log {log!r} exists; not replaced")
    if lockstep and any(s.clock_phase >= COMMAND_OFFSET for s in specs):
        late = [s.robot for s in specs if s.clock_phase >= COMMAND_OFFSET]
        return _error(f"--lockstep: the driver's clock_phase of {', '.join(late)} must be < "
                      f"{COMMAND_OFFSET:g} s (its first status before the first command)")
    builder = DiagramBuilder()
    if not lockstep:       # lockstep: pumped between the steps, by drive_lockstep
        add_lcm_interface(builder, lcm)
    # the driver's clock: its wall clock when paced, a simulated one in lockstep
    clock = DriverClock("epoch", wall=not lockstep)
    try:
        side = add_driver_side(builder, plan, lcm, specs, clock=clock, emulate=emulate,
                               low_pass_hz=low_pass)
    except ValueError as exc:
        return _error(str(exc))
    truth = add_truth_log(builder, side, plan.h, scenario) if log is not None else None
    if truth is not None:
        for arm in side.arms:          # each command as the driver took it
            arm.driver.journal = []
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    initialize_sides(plan, context, side, None)
    simulator.Initialize()
    plant_context = side.coop.plant.GetMyMutableContextFromRoot(context)
    if not args.quiet:
        print("drake-coop: sim-driver publishing "
              + ", ".join(s.status_channel for s in specs) + "; waiting for a command"
              + (" (lockstep)" if lockstep else "")
              + (f" (emulating {emulate})" if emulate else ""), file=sys.stderr)
    start = time.perf_counter()
    if lockstep:
        from drake_coop.robot.lockstep import drive_lockstep

        def at_tick(k):
            if k in plan.switches:
                side.coop.set_held(plant_context, plan.switches[k])
            return side.fault(context)

        try:
            reason = drive_lockstep(simulator, side, lcm, plan, args.command_wait,
                                    before_tick=at_tick, offset=COMMAND_OFFSET)
        except HubLost:
            reason = HUB_LOST_LINE
        if reason:
            print(f"drake-coop: sim-driver stopped at t = {context.get_time():.3f} s: "
                  f"{reason}", file=sys.stderr)
            if truth is not None:
                write_truth_log(log, truth, context)
            return 1
        worst = math.nan
    else:
        # The status at rest, every driver cycle, until a first command arrives (each arm is
        # then held by its driver's gravity compensation and damping until its own first).
        period = min(s.period for s in specs)
        deadline = time.perf_counter() + args.command_wait
        # (the command subscribers' own counts: a plain Python handler must not be pumped by
        # the LcmInterfaceSystem inside AdvanceTo, see add_lcm_interface)
        # the hub's death: a failed step, not an abort
        simulator.set_monitor(hub_monitor(lcm, simulator.get_system()))
        try:
            while not any(arm.command_subscriber.WaitForMessage(0, None, 1e-6) > 0
                          for arm in side.arms):
                if time.perf_counter() > deadline:
                    print(f"drake-coop: no command on "
                          f"{', '.join(s.command_channel for s in specs)} within "
                          f"{args.command_wait:g} s", file=sys.stderr)
                    return 1
                for arm in side.arms:
                    arm.driver.ForcedPublish(arm.driver.GetMyContextFromRoot(context))
                pump_until(lcm, time.perf_counter() + period)
        except HubLost:
            return _hub_lost(log, truth, context)
        simulator.set_target_realtime_rate(1.0)
        simulator.ResetStatistics()      # the wall clock starts now, not at Initialize()
        start = time.perf_counter()
        worst = 0.0          # how far the simulated time fell behind the wall clock (s)
        try:
            for k_stop in guard_chunks(plan, scenario.guards.check_period):
                try:
                    simulator.AdvanceTo(k_stop * plan.h)
                except RuntimeError as exc:
                    if not is_hub_failure(exc):
                        raise
                    return _hub_lost(log, truth, context)
                worst = max(worst, time.perf_counter() - start - context.get_time())
                fault = side.fault(context)
                if fault:
                    print(f"drake-coop: sim-driver stopped at t = {context.get_time():.3f} s: "
                          f"{emulate} threw on {fault}", file=sys.stderr)
                    return 1
                if k_stop in plan.switches:
                    side.coop.set_held(plant_context, plan.switches[k_stop])
        except KeyboardInterrupt:      # Ctrl-C or SIGTERM: the ground truth up to now kept
            if truth is not None:
                write_truth_log(log, truth, context)
            raise
    if truth is not None:
        write_truth_log(log, truth, context)
    if not args.quiet:
        expired = sum(arm.driver.counts(arm.driver.GetMyContextFromRoot(context))["expired"]
                      for arm in side.arms)
        print(f"drake-coop: sim-driver done at t = {context.get_time():.3f} s after "
              f"{time.perf_counter() - start:.3f} s of wall time"
              + ("" if math.isnan(worst) else
                 f" (at most {worst * 1e3:.1f} ms behind the wall clock)")
              + f"; {expired} commands expired", file=sys.stderr)
    return 0


def _hub_lost(log, truth, context) -> int:
    """The hub's death in a paced run: one line, ``--log`` written up to it, exit 1."""
    from drake_coop.robot.hub_link import HUB_LOST_LINE

    print(f"drake-coop: sim-driver stopped at t = {context.get_time():.3f} s: "
          f"{HUB_LOST_LINE}", file=sys.stderr)
    if truth is not None:
        write_truth_log(log, truth, context)
    return 1


def add_truth_log(builder, side, h: float, scenario=None) -> dict:
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
    scenario : Scenario or None
        The scenario: in ``planes`` and ``rigid`` modes the squeeze's ground truth is logged
        as the loopback run's (:func:`~drake_coop.robot.loopback.add_squeeze_truth`).

    Returns
    -------
    dict
        ``normals`` (each arm's constraint normals), ``arms`` (each arm's state logger),
        ``commanded`` (each arm's held command's logger), ``drivers`` (each arm's
        :class:`~drake_coop.robot.torque_driver.TorqueDriver`) and,
        in contact mode, ``pads`` (the pads' forces) and ``box`` (the box's state logger);
        in ``planes`` and ``rigid`` modes ``squeeze`` (the ground truth's log).
    """
    import numpy as np
    from pydrake.systems.primitives import LogVectorOutput

    coop = side.coop
    out: dict = {"normals": [np.asarray(a.arm.N, dtype=float) for a in coop.arms]}
    if coop.mode == "contact":
        from drake_coop.robot.loopback import add_pad_truth

        out["pads"] = add_pad_truth(builder, side, h)
        out["box"] = LogVectorOutput(coop.plant.get_state_output_port(
            coop.grasp.box.model_instance()), builder, publish_period=h)
    elif scenario is not None and coop.mode in ("planes", "rigid"):
        from drake_coop.robot.loopback import add_squeeze_truth

        out["squeeze"] = add_squeeze_truth(builder, scenario, side, h)
    out["commanded"] = [LogVectorOutput(a.driver.get_output_port(1), builder,
                                        publish_period=h) for a in side.arms]
    out["arms"] = [LogVectorOutput(coop.plant.get_state_output_port(a.instance), builder,
                                   publish_period=h) for a in coop.arms]
    out["drivers"] = [a.driver for a in side.arms]
    return out


def write_truth_log(path, truth: dict, context) -> None:
    """``sim-driver --log``'s file (written whole): ``t``; ``lambda`` (ticks × arms × m:
    ``N_i F_i`` in contact mode; in ``planes`` and ``rigid`` the loopback run's ground truth
    of each tick but the last); ``box_state`` (the box's positions and
    velocities, contact mode); ``arm<i>_state``; ``arm<i>_tau_commanded`` (the command the
    driver held at each tick, as received); ``arm<i>_counts`` (the driver's counts of
    expired commands and rate-limited cycles,
    :meth:`~drake_coop.robot.torque_driver.TorqueDriver.counts`) and, when the driver kept
    one, ``arm<i>_journal`` (a row per command taken,
    :data:`~drake_coop.robot.torque_driver.JOURNAL`) and ``arm<i>_expiries`` (``[now,
    utime]`` of each command dropped for its age).

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
    drivers = truth.get("drivers", [])
    t = arms[0].sample_times()
    data = {"t": t}
    normals = truth["normals"]
    if "pads" in truth:
        from drake_coop.robot.loopback import pad_squeeze

        data["lambda"] = pad_squeeze(truth["pads"].FindLog(context).data().T, normals)
        data["box_state"] = truth["box"].FindLog(context).data().T
    elif "squeeze" in truth:
        from drake_coop.robot.loopback import squeeze_truth

        n, forces = squeeze_truth(truth["squeeze"], context)
        data["lambda"] = np.stack([np.asarray(f["lambda_meas"]).reshape(n, -1)
                                   for f in forces], axis=1)
    for i, log in enumerate(arms):
        data[f"arm{i}_state"] = log.data().T
        data[f"arm{i}_tau_commanded"] = truth["commanded"][i].FindLog(context).data().T
        if i < len(drivers):
            driver = drivers[i]
            counts = driver.counts(driver.GetMyContextFromRoot(context))
            data[f"arm{i}_counts"] = np.array([counts["expired"], counts["rate_limited"]])
            if driver.journal is not None:
                data[f"arm{i}_journal"] = np.array(driver.journal, dtype=float).reshape(
                    len(driver.journal), -1)
                data[f"arm{i}_expiries"] = np.array(driver.expiries, dtype=float).reshape(-1, 2)
    buffer = io.BytesIO()
    np.savez(buffer, **data)
    atomic_write_bytes(path, buffer.getvalue())
