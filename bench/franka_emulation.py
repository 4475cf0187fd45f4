"""What drake-franka-driver's torque mode does to the paper's controller on two Pandas:
``python -m bench.franka_emulation [--t-end 4.0] [--out docs/results/franka_emulation.json]``.

The loopback run (both sides in one process, ``memq://``,
:func:`~drake_coop.robot.loopback.run_loopback`) of ``scenarios/two_pandas.yaml`` on a
compressed task (grasp 1.5 s, circle 2–4 s, as the robot tests compress it), with

* ``plain``: the plain simulated driver (the wire's conventions only: the robot adds g(q),
  commands expire after 0.1 s);
* ``emulated``: ``sim-driver --emulate drake-franka-driver``'s driver: libfranka's control loop
  as the driver calls it, torque low-pass filtered at its ``--low_pass_freq`` (30 Hz) and
  rate-limited to 1000 N·m/s;
* ``emulated_unfiltered``: the same with the cutoff at libfranka's "no filter" (1000 Hz),
  the rate limit alone.

Per case: the run's status and message, the circle's RMS squeeze error per arm (N), the
wall time and the load average. Simulated time only: the figures do not depend on the
machine's load (the wall time does).

``--driver-cpu`` adds what the simulated driver costs (:func:`driver_cpu`): the CPU time of
the driver's side alone (plant, drivers, statuses) per simulated second, plain and emulated,
in alternated pairs.

``--external-torque`` adds the external-torque estimate's accuracy
(:func:`external_torque_accuracy`): against the contact's torque while squeezed, and in free
motion at every driver cycle against the plant's discretization
(:func:`free_motion_cycles`, :func:`discretization_term`).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

CASES = {"plain": (None, None), "emulated": ("drake-franka-driver", None),
         "emulated_unfiltered": ("drake-franka-driver", 1000.0)}


def compressed(name: str):
    """The scenario with the robot tests' compressed task (circle 2–4 s)."""
    from drake_coop.scenario.loading import dump_scenario, load_scenario
    from drake_coop.scenario.resources import find_scenario

    s = load_scenario(find_scenario(name))
    t = s.task
    t.t_pregrasp, t.t_grasp, t.t_circle_start = 1.0, 1.5, 2.0
    t.t_circle_end, t.t_release, t.t_end = 4.0, 4.5, 6.0
    t.force_omega = 3 * np.pi / 2.0
    return load_scenario(data=dump_scenario(s))


def run_case(scenario, t_end: float, emulate, low_pass) -> dict:
    """One loopback run and its figures."""
    from drake_coop.robot.loopback import run_loopback, squeeze_error

    start = time.perf_counter()
    run = run_loopback(scenario, t_end, emulate=emulate, low_pass_hz=low_pass)
    wall = time.perf_counter() - start
    error = squeeze_error(run.logs, scenario)
    reached = max(float(log["t"][-1]) if len(log["t"]) else 0.0 for log in run.logs.values())
    return {"status": run.status, "message": run.message, "t_reached_s": reached,
            "circle_squeeze_error_rms_N": {k: (None if not np.isfinite(v) else float(v))
                                           for k, v in error.items()},
            "wall_s": wall, "load_after": list(os.getloadavg())}


def wire_check(log, scenario) -> dict:
    """What the emulated driver did with the commands of a run over the wire, from its
    ``sim-driver --log`` file (each command's row as taken,
    :data:`~drake_coop.robot.torque_driver.JOURNAL`, and the driver's counts).

    Per arm: the commands taken, expired (all; in the run: all but the last command, the
    safe command ``serve`` sends as it stops, which expires 0.1 s later by design) and the
    cycles the rate limit changed ``τ_d``;
    ``chain_max_Nm``: ``max |τ_d − τ_wire|`` on the cycle each command was taken (the
    torque libfranka is given against the wire's: 0 without the low-pass, unless the rate
    limit bound: more than 1e-12 N·m); ``gravity_once_max_Nm``:
    ``max |τ_applied − τ_wire − g(q)|`` over the
    commands taken on a cycle the rate limit left alone, ``g`` the controller model's
    gravity (the arm's URDF: Drake's gravity generalized forces of a plant of the arm alone,
    computed here, not by the driver's ``InverseDynamics``) at the cycle's ``q``: the
    controller's ``τ`` (sent as ``τ − g``) reaches the arm with gravity counted once.

    Parameters
    ----------
    log : str or Path
        The driver's ``.npz`` (``sim-driver --log``).
    scenario : str or Path
        The run's scenario (YAML).

    Returns
    -------
    dict
        Per arm name, the figures above.
    """
    from pydrake.systems.framework import DiagramBuilder

    from drake_coop.experiment.plan import plan_run
    from drake_coop.plant.cooperative import build_plant
    from drake_coop.plant.model_error import controller_arm_model
    from drake_coop.scenario.loading import load_scenario

    data = np.load(log)
    loaded = load_scenario(Path(scenario))
    coop = build_plant(DiagramBuilder(), plan_run(loaded, 0.1))
    out = {}
    for i, robot in enumerate(loaded.robots):
        plant = controller_arm_model(coop.arms[i].arm, None).plant
        ctx = plant.CreateDefaultContext()
        rows = data[f"arm{i}_journal"]
        n = (rows.shape[1] - 2) // 5
        tau_wire, tau_d, _, applied, q = (rows[:, 2 + j * n:2 + (j + 1) * n] for j in range(5))
        chain = np.abs(tau_d - tau_wire).max(axis=1)
        free = chain <= 1e-12          # the rate limit left it alone (rounding aside)
        gravity = np.empty_like(q)
        for k in range(len(q)):
            plant.SetPositions(ctx, q[k])
            gravity[k] = -plant.CalcGravityGeneralizedForces(ctx)
        once = np.abs(applied - tau_wire - gravity).max(axis=1)
        expired, limited = (int(v) for v in data[f"arm{i}_counts"])
        drops = data[f"arm{i}_expiries"]
        last = rows[-1, 1] if len(rows) else np.inf
        out[robot.name] = {
            "commands_taken": int(len(rows)), "commands_expired": expired,
            "commands_expired_in_run": int((drops[:, 1] < last).sum()),
            "last_command_expired_after_s": float((drops[-1, 0] - last) * 1e-6)
            if len(drops) and drops[-1, 1] == last else None,
            "rate_limited_cycles": limited, "taken_rate_limited": int((~free).sum()),
            "chain_max_Nm": float(chain.max()) if len(rows) else None,
            "gravity_once_max_Nm": float(once[free].max()) if free.any() else None,
            "gravity_max_Nm": float(np.abs(gravity).max()) if len(rows) else None,
            "command_age_max_s": float(np.abs(rows[:, 0] - rows[:, 1]).max() * 1e-6)
            if len(rows) else None}
    return out


def external_torque_accuracy(name: str = "two_pandas", t_end: float = 2.6) -> dict:
    """The emulated driver's external-torque estimate against the simulated truth: the
    loopback run of ``name``'s compressed task behind the emulated driver without its filter,
    per arm and tick the estimate (``tau_external``) against ``−J_xᵀ Nᵀ λ`` (the contact's
    torque with Franka's sign: ``λ`` the plant's squeeze, ``J_x`` the pad's Jacobian, ``N``
    its normal). Per arm: while squeezed (the circle, from 2 s) the RMS of the error and of
    the truth over every joint and tick and their ratio; before the grasp (no contact,
    to 1.45 s) the largest estimate on a joint (what the estimate reads in free motion).

    Parameters
    ----------
    name : str
        The shipped scenario.
    t_end : float
        The run's end, s.

    Returns
    -------
    dict
        Per arm name, the figures above (N·m).
    """
    from pydrake.systems.framework import DiagramBuilder

    from drake_coop.experiment.plan import plan_run
    from drake_coop.plant.cooperative import build_plant
    from drake_coop.plant.model_error import controller_arm_model
    from drake_coop.robot.loopback import run_loopback

    scenario = compressed(name)
    run = run_loopback(scenario, t_end, emulate="drake-franka-driver", low_pass_hz=1000.0)
    coop = build_plant(DiagramBuilder(), plan_run(scenario, 0.1))
    out = {"status": run.status, "t_end_s": t_end}
    for i, (robot, log) in enumerate(run.logs.items()):
        model = controller_arm_model(coop.arms[i].arm, None)
        N = np.atleast_2d(model.N)
        truth = np.array([-(model.J_x(q).T @ N.T @ np.atleast_1d(lam))
                          for q, lam in zip(log["q"], log["lambda_meas"])])
        est, t = np.asarray(log["tau_external"]), np.asarray(log["t"])
        held, free = t >= 2.0, t < 1.45
        err = float(np.sqrt(np.mean((est[held] - truth[held]) ** 2)))
        scale = float(np.sqrt(np.mean(truth[held] ** 2)))
        out[robot] = {"squeezed_error_rms_Nm": err, "squeezed_truth_rms_Nm": scale,
                      "squeezed_ratio": err / scale,
                      "squeezed_truth_max_Nm": float(np.abs(truth[held]).max()),
                      "free_estimate_max_Nm": float(np.abs(est[free]).max())}
    cycles = free_motion_cycles(name)
    term = discretization_term(cycles["model"], cycles["x"], cycles["period"])
    est = cycles["tau_external"]
    out["free_cycles_robot1"] = {
        "cycles": int(len(cycles["t"]) - 2),
        "estimate_max_Nm": float(np.abs(est[2:]).max()),
        "discretization_max_Nm": float(np.abs(term[2:]).max()),
        "estimate_minus_discretization_max_Nm": float(np.abs(est[2:] - term[2:]).max()),
        "tick_estimate_max_Nm": float(np.abs(cycles["tau_external_tick"]).max())}
    return out


def free_motion_cycles(name: str = "two_pandas", t_end: float = 1.45) -> dict:
    """Robot 1 at every driver cycle of the loopback run of ``name``'s compressed task
    behind the unfiltered emulation, in free motion (before the grasp): what the cycle's
    status reads.

    Parameters
    ----------
    name : str
        The shipped scenario (two Pandas).
    t_end : float
        The run's end, s (before the grasp at 1.5 s).

    Returns
    -------
    dict
        ``t`` (K,), s, the driver's cycles; ``x`` (K, 2n), the arm's state at each (before
        that instant's updates: what the status publishes); ``tau_applied`` (K, n), the torque
        on the arm from the cycle before; ``tau_external`` (K, n), the estimate the cycle's
        status publishes; ``t_tick``, ``tau_external_tick``: the estimate as read at the
        controller's ticks (the loopback run's log), N·m; ``period``, the driver's cycle, s;
        ``model``, the arm's exact model.
    """
    from pydrake.lcm import DrakeLcm
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import LogVectorOutput

    from drake_coop.experiment.plan import plan_run
    from drake_coop.plant.model_error import controller_arm_model
    from drake_coop.robot.drivers import add_controller_side, add_driver_side, add_lcm_interface
    from drake_coop.robot.loopback import initialize_sides
    from drake_coop.robot.torque_driver import DriverClock

    plan = plan_run(compressed(name), t_end)
    lcm = DrakeLcm("memq://")
    builder = DiagramBuilder()
    add_lcm_interface(builder, lcm)
    clock = DriverClock("epoch")
    driver = add_driver_side(builder, plan, lcm, clock=clock, emulate="drake-franka-driver",
                             low_pass_hz=1000.0)
    controller = add_controller_side(builder, plan, lcm, clock=clock)
    arm, plant = driver.arms[0], driver.coop.plant
    period = driver.arms[0].spec.period
    state = plant.get_state_output_port(driver.coop.arms[0].instance)
    logs = {"x": LogVectorOutput(state, builder, publish_period=period),
            "tau_applied": LogVectorOutput(arm.driver.get_output_port(0), builder,
                                           publish_period=period),
            "tau_external": LogVectorOutput(arm.driver.get_output_port(2), builder,
                                            publish_period=period),
            "tau_external_tick": LogVectorOutput(arm.driver.get_output_port(2), builder,
                                                 publish_period=plan.h)}
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    initialize_sides(plan, context, driver, controller)
    simulator.Initialize()
    simulator.AdvanceTo(t_end)
    out = {key: log.FindLog(context).data().T for key, log in logs.items()}
    out["t"] = logs["x"].FindLog(context).sample_times()
    out["t_tick"] = logs["tau_external_tick"].FindLog(context).sample_times()
    out["period"] = period
    out["model"] = controller_arm_model(driver.coop.arms[0].arm, None)
    return out


def discretization_term(model, x: np.ndarray, period: float) -> np.ndarray:
    """What the estimate reads in free motion with the exact model, from the plant's step:
    ``ID(q₋, v₋, a) − ID(q, v, a)`` at each cycle (``a = (v − v₋)/period``, ``ID`` the model's
    inverse dynamics). The plant's step is ``ID(q₋, v₋, a) = τ`` (its dynamics at the step's
    start), the estimate ``τ − ID(q, v, a)`` (at its end); their difference is the change of
    the model's terms over one step, about ``period·(∂g/∂q·v + …)``.

    Parameters
    ----------
    model : ArmModel
        The arm's exact model.
    x : numpy.ndarray
        (K, 2n) the state at each cycle.
    period : float
        The cycle, s.

    Returns
    -------
    numpy.ndarray
        (K, n), N·m; row 0 zeros (no cycle before it).
    """
    n = x.shape[1] // 2
    out = np.zeros((x.shape[0], n))
    for k in range(1, x.shape[0]):
        (q0, v0), (q1, v1) = (x[k - 1, :n], x[k - 1, n:]), (x[k, :n], x[k, n:])
        a = (v1 - v0) / period
        out[k] = model.inverse_dynamics_terms(q0, v0, a) - model.inverse_dynamics_terms(q1, v1, a)
    return out


def _driver_side_cpu(scenario, t_end: float, emulate: str | None) -> dict:
    """The CPU seconds (this process's, ``time.process_time``) of ``t_end`` simulated
    seconds of the driver's side alone: the plant and each arm's simulated driver publishing
    its statuses on ``memq://``, no controller (no command arrives: the arms are held by
    gravity compensation and damping), building left out."""
    from pydrake.lcm import DrakeLcm
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from drake_coop.experiment.plan import plan_run
    from drake_coop.robot.drivers import add_driver_side, add_lcm_interface
    from drake_coop.robot.loopback import initialize_sides
    from drake_coop.robot.torque_driver import DriverClock

    plan = plan_run(scenario, t_end)
    lcm = DrakeLcm("memq://")
    builder = DiagramBuilder()
    add_lcm_interface(builder, lcm)
    driver = add_driver_side(builder, plan, lcm, clock=DriverClock("epoch"), emulate=emulate)
    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    initialize_sides(plan, context, driver, None)
    simulator.Initialize()
    start = time.process_time()
    simulator.AdvanceTo(plan.t_end)
    cpu = time.process_time() - start
    return {"cpu_s": cpu, "t_end_s": float(context.get_time()),
            "fault": driver.fault(context)}


def driver_cpu(name: str = "two_pandas", t_end: float = 2.0, pairs: int = 5) -> dict:
    """The simulated driver's CPU time per simulated second, plain and emulated
    (drake-franka-driver at its default cutoff): the share of one CPU it takes at real
    time.

    The driver's side runs alone in this process (:func:`_driver_side_cpu`: the plant at
    its step, each arm's driver, every status encoded and published; no command arrives,
    so decoding the commands is not counted). The two drivers alternate (plain first in
    even pairs, emulated first in odd ones) after one discarded run of each, so that a change
    of the machine's load falls on both; CPU time, not wall time.

    Parameters
    ----------
    name : str
        The shipped scenario.
    t_end : float
        Simulated seconds per run, s.
    pairs : int
        Alternated pairs.

    Returns
    -------
    dict
        Per driver (``plain``, ``emulated``) the runs' CPU s per simulated s and their
        median; ``emulated_minus_plain``: the median of the pairs' differences; the load
        average before and after.
    """
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.resources import find_scenario

    scenario = load_scenario(find_scenario(name))
    drivers = {"plain": None, "emulated": "drake-franka-driver"}
    out = {"scenario": name, "t_end_s": t_end, "pairs": pairs,
           "method": "driver side alone in one process (plant, drivers, statuses on memq, "
                     "no command), time.process_time per simulated second, alternated pairs "
                     "after one discarded run of each",
           "load_before": list(os.getloadavg()),
           **{key: {"per_run": [], "faults": []} for key in drivers}}
    for emulate in drivers.values():
        _driver_side_cpu(scenario, t_end, emulate)          # warm-up, discarded
    for i in range(pairs):
        for key in (("plain", "emulated") if i % 2 == 0 else ("emulated", "plain")):
            run = _driver_side_cpu(scenario, t_end, drivers[key])
            out[key]["per_run"].append(run["cpu_s"] / run["t_end_s"])
            out[key]["faults"].append(run["fault"])
            print(key, i, run, flush=True)
    for key in drivers:
        out[key]["median"] = float(np.median(out[key]["per_run"]))
    out["emulated_minus_plain"] = float(np.median(
        np.subtract(out["emulated"]["per_run"], out["plain"]["per_run"])))
    out["load_after"] = list(os.getloadavg())
    return out


def _add_result(out: Path, key: str, value) -> int:
    """``value`` stored under ``key`` in the results file ``out`` (kept or created), and
    printed; the exit code 0."""
    data = json.loads(out.read_text()) if out.exists() else {}
    data[key] = value
    out.write_text(json.dumps(data, indent=1) + "\n")
    print(json.dumps(value), flush=True)
    return 0


def main(argv=None) -> int:
    """Run the cases and write the JSON.

    Parameters
    ----------
    argv : list of str or None
        The command line.

    Returns
    -------
    int
        0.
    """
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="two_pandas")
    parser.add_argument("--t-end", type=float, default=4.0)
    parser.add_argument("--out", default="docs/results/franka_emulation.json")
    parser.add_argument("--external-torque", action="store_true",
                        help="only the external-torque estimate's accuracy "
                             "(external_torque_accuracy), added to --out as external_torque")
    parser.add_argument("--driver-cpu", action="store_true",
                        help="only the simulated driver's CPU time per simulated second, "
                             "plain and emulated (driver_cpu), added to --out as driver_cpu")
    args = parser.parse_args(argv)
    if args.driver_cpu:
        return _add_result(Path(args.out), "driver_cpu", driver_cpu(args.scenario))
    if args.external_torque:
        return _add_result(Path(args.out), "external_torque", external_torque_accuracy(args.scenario))
    scenario = compressed(args.scenario)
    result = {"scenario": args.scenario, "t_end_s": args.t_end,
              "task": "compressed: grasp 1.5 s, circle 2-4 s", "load_before":
              list(os.getloadavg()), "cases": {}}
    for name, (emulate, low_pass) in CASES.items():
        result["cases"][name] = run_case(scenario, args.t_end, emulate, low_pass)
        print(name, json.dumps(result["cases"][name]), flush=True)
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
