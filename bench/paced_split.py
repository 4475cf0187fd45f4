"""The paced split run, end to end: one ``serve`` per arm, the simulated driver and LCM's
tcpq hub, as four processes on 127.0.0.1, at real time; one results JSON.

Per case (a tick mode and a scheduling) it starts ``drake-coop tcpq-hub --port 0`` (on
127.0.0.1 only), then ``drake-coop serve SCENARIO --robot NAME`` for each arm (each waits for
its status), then ``drake-coop sim-driver SCENARIO`` (its first statuses release both serves
within the same millisecond), all on the hub's ``tcpq://127.0.0.1:PORT`` — never
``udpm://``. The scenario is the shipped one with delay compensation switched on
(``robots[].timing.prediction_horizon``, default 3 ms; ``--horizon 0`` leaves it as shipped),
written beside the runs. ``--sched fifo`` runs every process under ``chrt -f`` (the hub
highest, then the serves, then the driver) with each ``serve`` pinned to a CPU of its own
(``taskset -c``, round robin over the online CPUs) and started with ``--require-rt`` (so its
memory is locked and ``run.json`` says what it got); ``--sched default`` runs them at the
default priority, unpinned. Every process runs under ``timeout`` (a FIFO process that never
sleeps would freeze the machine).

Per arm the results give what the arm's ``run.json`` and ``pacing.csv`` say: the outcome, the
computation time, the status age, the lateness and the loop delay (status age + lateness +
one driver cycle, what the stability map calls the computation delay ``d``; p50, p99, max),
the missed deadlines and the real-time settings read back; per case the load average
(``/proc/loadavg``, sampled every second) and the driver's last line; and the bars of
the bars: computation p99 ≤ ``--compute-bar`` (0.5 ms), loop delay p99 within the margin
with half to spare (≤ ``--margin`` / 2), no missed deadline, the whole run completed::

    python -m bench.paced_split --t-end 90 --tick grid arrival --sched fifo default \\
        --out runs/paced --results docs/results/paced_split.json

``--tick-cost`` measures instead one arm's tick in this process, back to back and after a
paced sleep (:func:`tick_cost`; run it under the scheduling to measure). ``--contact NAME``
runs a lab-arm contact scenario over the cable, the sim-driver logging the plant's ground
truth, against the simulated run with the measured delay (:func:`contact_case`).
``--serve-cpus`` and ``--driver-cpu`` change the CPU layout (FIFO), ``--priorities`` the
FIFO priorities.

Each case is written into ``--results`` as soon as it ends (the file keeps the cases of other
calls; a case's key is ``<sched>_<tick>``, or ``--case`` with one case). Exit 0 once every
case ran (whatever its outcome: a stopped run is a result), 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

#: The margin the bars use by default (s): the delay up to which docs/stability.md's map
#: (continuous arm, p = 3 ms) gives ρ < 1 with every model it computed (exact: 8 ms; 30 %
#: light, 30 % heavy, identified: 6 ms, the largest delay computed for them).
MARGIN = 0.006
#: Computation bar (s) per tick and arm.
COMPUTE_BAR = 0.0005
#: FIFO priorities: the hub relays every message, the serves' ticks are short and
#: latency-critical, the driver's plant steps are the long work.
PRIORITY = {"hub": 70, "serve": 60, "driver": 50}
CLI = [sys.executable, "-m", "drake_coop"]


def compensated_scenario(name: str, horizon: float, out: Path) -> Path:
    """``name`` (shipped scenario or YAML) with ``prediction_horizon = horizon`` on every arm
    (0: unchanged), written to ``out`` (checked by :func:`drake_coop.scenario.validate`)."""
    from drake_coop.scenario import validate
    from drake_coop.scenario.loading import dump_scenario, load_scenario
    from drake_coop.scenario.resources import find_scenario

    scenario = load_scenario(find_scenario(name))
    if horizon > 0:
        for robot in scenario.robots:
            robot.timing.prediction_horizon = float(horizon)
    validate(scenario)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(dump_scenario(scenario))
    return out


def fifo_allowed() -> bool:
    """``chrt -f`` grants SCHED_FIFO to a child here (root, or CAP_SYS_NICE)."""
    if shutil.which("chrt") is None:
        return False
    return subprocess.run(["chrt", "-f", "1", "true"], capture_output=True).returncode == 0


def _wait_for_line(path: Path, text: str, proc: subprocess.Popen, timeout: float) -> str:
    """The first line of ``path`` containing ``text`` (``proc`` writes it), or raise."""
    end = time.perf_counter() + timeout
    while time.perf_counter() < end:
        lines = path.read_text(errors="replace").splitlines() if path.exists() else []
        for line in lines:
            if text in line:
                return line
        if proc.poll() is not None:
            raise RuntimeError(f"{proc.args[-1] if proc.args else 'process'} exited "
                               f"({proc.returncode}) before saying {text!r}: "
                               + " | ".join(lines[-3:]))
        time.sleep(0.05)
    raise RuntimeError(f"no {text!r} from {path.name} within {timeout:g} s")


class LoadSampler(threading.Thread):
    """``/proc/loadavg``'s 1-minute average every ``period`` seconds until stopped."""

    def __init__(self, period: float = 1.0):
        super().__init__(daemon=True)
        self.period, self.samples = period, []
        self._halt = threading.Event()

    @staticmethod
    def read() -> list[float]:
        try:
            return [float(v) for v in Path("/proc/loadavg").read_text().split()[:3]]
        except (OSError, ValueError):
            return [math.nan] * 3

    def run(self) -> None:
        while not self._halt.wait(self.period):
            self.samples.append(self.read()[0])

    def stop(self) -> None:
        self._halt.set()
        self.join(5)


def driver_lag(line: str) -> float:
    """How far the sim-driver's simulated time fell behind the wall clock at worst (s), from
    its last line (``... (at most 10.4 ms behind the wall clock)``); None if it does not say."""
    import re

    m = re.search(r"at most ([0-9.]+) ms behind", line)
    return float(m.group(1)) * 1e-3 if m else None


def _q(x, q: float) -> float:
    x = np.asarray(x, dtype=float)
    return float(np.percentile(x, q)) if x.size else math.nan


def arm_figures(folder: Path) -> dict:
    """One arm's outcome and pacing figures from its run folder (``run.json``,
    ``pacing.csv``), with ``run.json``'s collector counts (``collector``: its pauses over
    1 ms, those during a tick)."""
    meta = json.loads((folder / "run.json").read_text())
    rows = np.genfromtxt(folder / "pacing.csv", delimiter=",", names=True, ndmin=1)
    pacing = meta["pacing"]
    cycle = float(pacing["driver_period_s"])
    out = {"status": meta["status"], "message": meta["message"], "ticks": int(pacing["ticks"]),
           "t_reached_s": float(rows["t"][-1]) if rows.size else 0.0,
           "missed_deadlines": int(pacing["missed_deadlines"]),
           "realtime": meta.get("realtime"), "realtime_missing": meta.get("realtime_missing"),
           "tick": meta.get("tick"), "lcm_url": meta.get("lcm_url"),
           "collector": pacing.get("collector")}
    if rows.size:
        delay = rows["status_age_s"] + rows["lateness_s"] + cycle
        for key, values in (("compute", rows["compute_s"]), ("lateness", rows["lateness_s"]),
                            ("status_age", rows["status_age_s"]), ("loop_delay", delay),
                            ("wait", rows["wait_s"])):
            out[f"{key}_p50_s"] = _q(values, 50)
            out[f"{key}_p99_s"] = _q(values, 99)
            out[f"{key}_max_s"] = float(np.max(values))
    return out


def run_case(scenario: Path, out: Path, *, t_end: float, tick: str, sched: str,
             margin: float = MARGIN, compute_bar: float = COMPUTE_BAR,
             robots: list[str] | None = None, priority: dict | None = None,
             driver_log: Path | None = None, serve_cpus: list[int] | None = None,
             driver_cpu: int | None = None, emulate: bool = False) -> dict:
    """One paced split run (hub, one ``serve`` per arm, sim-driver); its figures and bars.

    ``out`` gets ``<robot>/`` (each serve's run folder) and the processes' stderr
    (``*.log``). ``sched``: ``fifo`` or ``default``; ``priority``: the FIFO priority of
    ``hub``, ``serve`` and ``driver`` (default :data:`PRIORITY`); ``driver_log``: the
    sim-driver's ground truth file (``sim-driver --log``); ``serve_cpus``: the CPUs the
    serves are pinned to in turn (default: every CPU, round robin); ``driver_cpu``: pin the
    driver too (FIFO only; default unpinned; the hub is then pinned to the first serve
    CPU); ``emulate``: the driver emulates
    drake-franka-driver without its low-pass (``--low-pass-freq 1000``, as the robot guide
    runs the real one), logging its ground truth (``out/truth.npz`` unless ``driver_log``),
    and the result's ``emulation`` says what it did with the commands
    (:func:`bench.franka_emulation.wire_check`).
    """
    from drake_coop.scenario.loading import load_scenario

    if sched not in ("fifo", "default"):
        raise ValueError(f"sched: 'fifo' or 'default', got {sched!r}")
    if tick not in ("grid", "arrival"):
        raise ValueError(f"tick: 'grid' or 'arrival', got {tick!r}")
    if not (0 < t_end < math.inf):
        raise ValueError(f"t_end must be a finite number > 0, got {t_end}")
    if robots is None:
        robots = [r.name for r in load_scenario(scenario).robots]
    if sched == "fifo" and not fifo_allowed():
        raise ValueError("sched: fifo needs chrt -f to be granted (root or CAP_SYS_NICE)")
    priority = dict(PRIORITY if priority is None else priority)
    out.mkdir(parents=True, exist_ok=True)
    if emulate and driver_log is None:
        driver_log = out / "truth.npz"
        driver_log.unlink(missing_ok=True)
    truth_log = driver_log
    cpus = sorted(os.sched_getaffinity(0)) if not serve_cpus else list(serve_cpus)
    limit = t_end + 120.0          # every process is stopped by then, whatever happens

    def prefix(role: str, cpu: int | None = None) -> list[str]:
        cmd = ["timeout", "-s", "TERM", "-k", "10", f"{limit:g}"]
        if sched == "fifo":
            cmd += ["chrt", "-f", str(priority[role])]
            if cpu is not None:
                cmd += ["taskset", "-c", str(cpu)]
        return cmd

    procs: list[subprocess.Popen] = []
    logs = []

    def start(name: str, cmd: list[str]) -> tuple[subprocess.Popen, Path]:
        log = out / f"{name}.log"
        f = open(log, "w")
        logs.append(f)
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=f, text=True)
        procs.append(proc)
        return proc, log

    load = LoadSampler()
    load_before = LoadSampler.read()
    result: dict = {"t_end": t_end, "tick": tick, "sched": sched, "scenario": scenario.name,
                    "margin_s": margin, "compute_bar_s": compute_bar,
                    "load_before": load_before,
                    "priority": priority if sched == "fifo" else None,
                    "serve_cpus": cpus if sched == "fifo" else None,
                    "driver_cpu": driver_cpu if sched == "fifo" else None}
    try:
        # a pinned driver gets its CPU to itself: the hub goes with the first serve
        hub, hub_log = start("hub", prefix("hub", cpus[0] if driver_cpu is not None else None)
                             + CLI + ["tcpq-hub", "--port", "0"])
        url = _wait_for_line(hub_log, "--lcm-url ", hub, 60).split("--lcm-url ")[1].rstrip(")")
        if not url.startswith("tcpq://127.0.0.1:"):
            raise RuntimeError(f"the hub is not on 127.0.0.1: {url}")
        serves = {}
        for i, robot in enumerate(robots):
            cmd = prefix("serve", cpus[i % len(cpus)]) + CLI + [
                "serve", str(scenario), "--robot", robot, "--lcm-url", url,
                "--out", str(out / robot), "--force", "--t-end", f"{t_end:g}",
                "--delay-margin", f"{margin:g}", "--status-wait", "120", "--tick", tick]
            if sched == "fifo":
                cmd.append("--require-rt")
            serves[robot] = start(f"serve_{robot}", cmd)
        for robot, (proc, log) in serves.items():
            _wait_for_line(log, "waiting for the status", proc, 300)
        driver, driver_log = start("driver", prefix("driver", driver_cpu) + CLI + [
            "sim-driver", str(scenario), "--lcm-url", url, "--t-end", f"{t_end + 2.0:g}",
            "--command-wait", "120"] + ([] if driver_log is None else ["--log", str(driver_log)])
            + (["--emulate", "drake-franka-driver", "--low-pass-freq", "1000"] if emulate
               else []))
        load.start()
        started = time.perf_counter()
        codes = {robot: proc.wait(limit + 30) for robot, (proc, _) in serves.items()}
        result["wall_s"] = time.perf_counter() - started
        try:
            driver.wait(30)
        except subprocess.TimeoutExpired:
            driver.terminate()
            driver.wait(15)
    finally:
        load.stop()
        for proc in reversed(procs):
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(15)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()
        for f in logs:
            f.close()
    result["lcm_url"] = url
    result["load_during"] = {"min": min(load.samples, default=math.nan),
                             "max": max(load.samples, default=math.nan),
                             "mean": float(np.mean(load.samples)) if load.samples else math.nan}
    driver_lines = [x for x in driver_log.read_text(errors="replace").splitlines()
                    if x.startswith("drake-coop:")]
    result["driver"] = {"returncode": driver.returncode,
                        "last_line": driver_lines[-1] if driver_lines else ""}
    result["driver"]["behind_max_s"] = driver_lag(result["driver"]["last_line"])
    if emulate:
        from bench.franka_emulation import wire_check

        result["emulation"] = (wire_check(truth_log, scenario) if truth_log.exists()
                               else None)
    result["robots"] = {}
    for robot in robots:
        folder = out / robot
        if (folder / "run.json").exists():
            fig = arm_figures(folder)
        else:
            lines = (out / f"serve_{robot}.log").read_text(errors="replace").splitlines()
            fig = {"status": "no run", "message": lines[-1] if lines else ""}
        fig["returncode"] = codes[robot]
        result["robots"][robot] = fig
    arms = result["robots"].values()
    done = all(a.get("status") == "ok" for a in arms)
    result["bars"] = {
        "completed": done,
        "compute_p99": all(a.get("compute_p99_s", math.inf) <= compute_bar for a in arms),
        "loop_delay_p99_half_margin": all(a.get("loop_delay_p99_s", math.inf) <= margin / 2
                                          for a in arms),
        "loop_delay_p99_margin": all(a.get("loop_delay_p99_s", math.inf) <= margin
                                     for a in arms),
        "no_missed_deadline": all(a.get("missed_deadlines", 1) == 0 for a in arms),
    }
    if emulate:
        em = (result["emulation"] or {}).values()
        result["bars"]["no_command_expired"] = bool(em) and all(
            a["commands_expired_in_run"] == 0 for a in em)
        result["bars"]["gravity_once_1e-9"] = bool(em) and all(
            a["gravity_once_max_Nm"] is not None and a["gravity_once_max_Nm"] <= 1e-9
            for a in em)
    result["bars"]["all"] = all(result["bars"][k] for k in (
        "completed", "compute_p99", "loop_delay_p99_half_margin", "no_missed_deadline"))
    return result


def tick_cost(scenario_name: str, horizons=(None, 0.003), *, robot: str = "robot2",
              ticks: int = 200, rounds: int = 3, idle: float = 0.008) -> dict:
    """Why a paced tick costs more than the same tick back to back: one arm's
    :class:`~drake_coop.robot.serve_loop.ServeLoop` on ``memq://`` in this process, fed the
    reference's statuses (nine per tick, as a 1 kHz driver's), timed (wall clock, the feed,
    the Simulator step and the command, as ``serve``'s ``compute``) back to back and with
    ``idle`` seconds of sleep before each tick (as in a paced run), alternated ``rounds``
    times, with and without compensation (``horizons``). Run it under the scheduling to
    measure (``chrt -f 60 taskset -c 1 python -m bench.paced_split --tick-cost ...``)."""
    from pydrake.lcm import DrakeLcm

    from bench.serve_tick import _readings, _status_bytes
    from drake_coop.experiment.plan import plan_run
    from drake_coop.robot.driver_spec import driver_specs
    from drake_coop.robot.serve_loop import ServeLoop, status_arrivals
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.model_check import check_models
    from drake_coop.scenario.resources import find_scenario

    cycles = 9
    out: dict = {"robot": robot, "ticks": ticks, "rounds": rounds, "idle_s": idle,
                 "realtime": None, "cases": {}}
    from drake_coop.robot.realtime import realtime_settings

    out["realtime"] = realtime_settings()
    loops = {}
    for horizon in horizons:
        scenario = load_scenario(find_scenario(scenario_name))
        for r in scenario.robots:
            r.timing.prediction_horizon = horizon
        plan = plan_run(scenario)
        specs = driver_specs(scenario, check_models(scenario))
        lcm = DrakeLcm("memq://")
        loop = ServeLoop(plan, lcm, specs, robots=[robot])
        i = [s.robot for s in specs].index(robot)
        q = _readings(scenario, plan, 2 * rounds * ticks + 10, cycles)[i]
        data = [_status_bytes(q[j], j * 1000) for j in range(len(q))]
        arrivals = status_arrivals(lcm, loop.specs)
        loop.start([q[0]])
        loops[horizon] = (loop, lcm, arrivals, data)
    k = 0
    times: dict = {(h, w): [] for h in horizons for w in (0.0, idle)}
    for _ in range(rounds):
        for wait in (0.0, idle):
            for horizon in horizons:
                loop, lcm, arrivals, data = loops[horizon]
                channel = loop.specs[0].status_channel
                for kk in range(k, k + ticks):
                    for j in range(kk * cycles, (kk + 1) * cycles):
                        lcm.Publish(channel, data[j])
                    lcm.HandleSubscriptions(0)
                    if wait:
                        time.sleep(wait)
                    start = time.perf_counter()
                    loop.feed(0, arrivals.take_parsed(channel))
                    loop.tick()
                    times[(horizon, wait)].append(time.perf_counter() - start)
            k += ticks
    for (horizon, wait), t in times.items():
        key = ("compensated" if horizon else "paper") + ("_idle" if wait else "_back_to_back")
        out["cases"][key] = {"horizon_s": horizon, "idle_s": wait, "p50_s": _q(t, 50),
                             "p99_s": _q(t, 99), "max_s": float(np.max(t))}
    return out


def contact_errors(t: np.ndarray, lam: np.ndarray, pose: np.ndarray, sim_logs: dict,
                   phases: list, t_end: float) -> dict:
    """Squeeze and box errors of a contact run, per phase (RMS, to ``t_end``), with the
    inputs a run does not change taken from the simulated run's logs on the same ticks
    (``lambda_d``, the arms' desired positions ``x_d``): per arm ``λ − λ_d``; the box's
    position error as :func:`drake_coop.results.object_metrics.object_signals` defines it
    (the box against the arms' desired midpoint plus their offset at the grasp tick, while
    held). ``t``: tick times; ``lam``: ticks × arms; ``pose``: ticks × 7 (quaternion, xyz)."""
    from drake_coop.results.metrics import phase_masks
    from drake_coop.results.object_metrics import _held_window

    robots = list(sim_logs)
    t_sim = np.asarray(sim_logs[robots[0]]["t"], dtype=float)
    h = float(t_sim[1] - t_sim[0])
    k_run = np.rint(np.asarray(t) / h).astype(int)
    k_sim = np.rint(t_sim / h).astype(int)
    common, i_run, i_sim = np.intersect1d(k_run, k_sim, return_indices=True)
    keep = common * h <= t_end + 1e-9
    i_run, i_sim, tt = i_run[keep], i_sim[keep], common[keep] * h
    mid_d = np.mean([np.asarray(sim_logs[r]["x_d"], dtype=float)[i_sim] for r in robots],
                    axis=0)
    p = np.asarray(pose, dtype=float)[i_run, 4:7]
    t_grasp, t_release = _held_window(tt, phases)
    k0 = int(np.searchsorted(tt, t_grasp - 1e-9))
    box = (np.linalg.norm(p - mid_d - (p[k0] - mid_d[k0]), axis=1) if k0 < tt.size
           else np.full(tt.size, np.nan))
    held = (tt >= t_grasp) & (tt < t_release)
    out: dict = {"t_end": float(tt[-1]), "ticks": int(tt.size)}
    masks = phase_masks(tt, phases)
    for phase in ("lift", "circle"):
        m = masks.get(phase)
        if m is None or not m.any():
            continue
        entry = {"from_s": float(tt[m][0]), "to_s": float(tt[m][-1])}
        for j, r in enumerate(robots):
            e = np.asarray(lam, dtype=float)[i_run, j] - np.asarray(
                sim_logs[r]["lambda_d"], dtype=float)[i_sim]
            entry[f"{r}_squeeze_error_rms_N"] = float(np.sqrt(np.nanmean(e[m] ** 2)))
        b = box[m & held]
        if b.size and np.isfinite(b).any():
            entry["box_position_error_rms_m"] = float(np.sqrt(np.nanmean(b ** 2)))
            entry["box_position_error_max_m"] = float(np.nanmax(b))
        out[phase] = entry
    return out


def contact_case(name: str, out: Path, *, t_end: float, tick: str, sched: str,
                 horizon: float = 0.003, margin: float = MARGIN,
                 priority: dict | None = None, serve_cpus: list[int] | None = None,
                 driver_cpu: int | None = None, object_mode: str = "estimated") -> dict:
    """The lab-arm contact scenario ``name``
    (:func:`bench.lab_arms_object.contact_scenario`: contact.yaml's plant, an estimated
    object model; compensation ``horizon``; ``every_arm/<row>``: that row of the every-arm
    benchmark with its derived gains, :func:`bench.delay_margins.every_arm_cases`) over the cable (:func:`run_case`, the
    sim-driver logging its ground truth), against the simulated run
    (:func:`~drake_coop.experiment.simulate.simulate`) with ``timing.computation_delay`` = the
    measured loop delay (the arms' median of the per-arm medians, at most ``h``): squeeze and
    box errors per phase to ``t_end`` (:func:`contact_errors`) and their ratios.
    ``object_mode``: the object model's mode (``estimated``, or ``known``)."""
    import copy

    from bench.lab_arms_object import contact_scenario
    from drake_coop.experiment.simulate import phases, simulate
    from drake_coop.scenario.loading import dump_scenario

    if name.startswith("every_arm/"):     # a lab pair as the every-arm benchmark set it up
        from bench.delay_margins import every_arm_cases
        from drake_coop.scenario.loading import dump_scenario as _dump

        out.mkdir(parents=True, exist_ok=True)
        (out / "pair.yaml").write_text(_dump(every_arm_cases()[name]()))
        scenario = contact_scenario(str(out / "pair.yaml"))
    else:
        scenario = contact_scenario(name)
    if object_mode not in ("estimated", "known"):
        raise ValueError(f"object_mode: 'estimated' or 'known', got {object_mode!r}")
    scenario.object_model.mode = object_mode
    if horizon > 0:
        for robot in scenario.robots:
            robot.timing.prediction_horizon = float(horizon)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "scenario.yaml"
    path.write_text(dump_scenario(scenario))
    log = out / "truth.npz"
    if log.exists():
        log.unlink()
    case = run_case(path, out / "cable", t_end=t_end, tick=tick, sched=sched, margin=margin,
                    priority=priority, driver_log=log, serve_cpus=serve_cpus,
                    driver_cpu=driver_cpu)
    result = {"scenario": name, "object_model": object_mode, "horizon_s": horizon,
              "cable": case}
    if not log.exists():
        result["comparison"] = None
        return result
    truth = np.load(log)
    delays = [a["loop_delay_p50_s"] for a in case["robots"].values()
              if "loop_delay_p50_s" in a]
    delay = float(min(np.median(delays), scenario.control_period))
    sim = copy.deepcopy(scenario)
    for robot in sim.robots:
        robot.timing.computation_delay = delay
    start = time.process_time()
    run = simulate(sim, t_end=t_end)
    result["simulated"] = {"computation_delay_s": delay, "status": run.meta["status"],
                           "cpu_s": time.process_time() - start}
    ph = phases(scenario)
    cable = contact_errors(truth["t"], truth["lambda"][:, :, 0], truth["box_state"][:, :7],
                           run.logs, ph, t_end)
    simulated = contact_errors(run.logs[next(iter(run.logs))]["t"],
                               np.column_stack([run.logs[r]["lambda_meas"] for r in run.logs]),
                               run.logs[next(iter(run.logs))]["object_pose"], run.logs, ph,
                               t_end)
    ratios = {}
    for phase in ("lift", "circle"):
        if phase in cable and phase in simulated:
            ratios[phase] = {k: cable[phase][k] / simulated[phase][k]
                             for k in cable[phase] if k.endswith(("_N", "_m"))
                             and simulated[phase][k] > 0}
    result["comparison"] = {"cable": cable, "simulated": simulated, "ratio": ratios,
                            "within_10_percent": bool(ratios) and all(
                                abs(v - 1) <= 0.1 for r in ratios.values() for v in r.values())}
    return result


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def write_case(path: Path, key: str, case: dict) -> None:
    """``case`` under ``cases.<key>`` of the JSON file ``path`` (read again just before: the
    file keeps the other cases), written whole."""
    data = json.loads(path.read_text()) if path.exists() else {"cases": {}}
    data["cases"][key] = case
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True, default=float) + "\n")
    tmp.replace(path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="paper", help="shipped scenario or YAML")
    parser.add_argument("--horizon", type=float, default=0.003,
                        help="robots[].timing.prediction_horizon (s; 0: as the scenario says)")
    parser.add_argument("--t-end", type=float, default=90.0)
    parser.add_argument("--tick", nargs="+", choices=("grid", "arrival"), default=["grid"])
    parser.add_argument("--sched", nargs="+", choices=("fifo", "default"), default=["fifo"])
    parser.add_argument("--margin", type=float, default=MARGIN,
                        help=f"the loop's delay margin for the bars (s, default {MARGIN:g})")
    parser.add_argument("--compute-bar", type=float, default=COMPUTE_BAR)
    parser.add_argument("--serve-cpus", type=int, nargs="+", metavar="CPU",
                        help="FIFO: the CPUs the serves are pinned to in turn (default all)")
    parser.add_argument("--driver-cpu", type=int, metavar="CPU",
                        help="FIFO: pin the sim-driver to this CPU (default unpinned)")
    parser.add_argument("--priorities", type=int, nargs=3, metavar=("HUB", "SERVE", "DRIVER"),
                        default=[PRIORITY[k] for k in ("hub", "serve", "driver")],
                        help="FIFO priorities (1-99) of the hub, the serves and the driver")
    parser.add_argument("--out", help="folder for the runs")
    parser.add_argument("--results", required=True, help="results JSON (cases added)")
    parser.add_argument("--contact", metavar="NAME",
                        help="instead of the paper's runs: the lab-arm contact scenario NAME "
                             "(e.g. two_pandas) over the cable against the simulated run "
                             "with the measured delay (contact_case), as case contact_<NAME>")
    parser.add_argument("--object-model", choices=("estimated", "known"), default="estimated",
                        help="--contact: the object model's mode (default estimated)")
    parser.add_argument("--tick-cost", action="store_true",
                        help="instead of the runs: one arm's tick in this process, back to "
                             "back and after sleeping (tick_cost), as case 'tick_cost'")
    parser.add_argument("--case", help="the case's key (one tick and one sched only)")
    parser.add_argument("--emulate", action="store_true",
                        help="the driver emulates drake-franka-driver (no low-pass); the "
                             "case says what it did with the commands (key emulated_<sched>_<tick>"
                             ")")
    args = parser.parse_args(argv)
    if not (0 < args.t_end < math.inf):
        parser.error(f"--t-end must be a finite number > 0, got {args.t_end}")
    if not (0 <= args.horizon <= 1):
        parser.error(f"--horizon must be in [0, 1] s, got {args.horizon}")
    if not (0 < args.margin < 1):
        parser.error(f"--margin must be in (0, 1) s, got {args.margin}")
    if not all(1 <= p <= 99 for p in args.priorities):
        parser.error(f"--priorities must be in 1-99, got {args.priorities}")
    if args.case is not None and len(args.tick) * len(args.sched) != 1:
        parser.error("--case names one case: give one --tick and one --sched with it")
    if "fifo" in args.sched and not fifo_allowed():
        parser.error("--sched fifo: chrt -f is not granted here (root or CAP_SYS_NICE)")
    from importlib.metadata import version

    if args.tick_cost:
        case = tick_cost(args.scenario, (None, args.horizon or 0.003))
        case.update(drake=version("drake"), cpu=_cpu_name(), cpus=os.cpu_count(),
                    date=time.strftime("%Y-%m-%d", time.gmtime()),
                    load_before=LoadSampler.read(),
                    command="python -m bench.paced_split " + " ".join(sys.argv[1:])
                    if argv is None else "")
        write_case(Path(args.results), args.case or "tick_cost", case)
        print(json.dumps(case["cases"], default=float))
        return 0
    if args.out is None:
        parser.error("--out: required (the folder for the runs)")
    if args.contact is not None:
        if len(args.tick) * len(args.sched) != 1:
            parser.error("--contact: give one --tick and one --sched")
        case = contact_case(args.contact, Path(args.out), t_end=args.t_end, tick=args.tick[0],
                            sched=args.sched[0], horizon=args.horizon, margin=args.margin,
                            priority=dict(zip(("hub", "serve", "driver"), args.priorities)),
                            serve_cpus=args.serve_cpus, driver_cpu=args.driver_cpu,
                            object_mode=args.object_model)
        case.update(drake=version("drake"), cpu=_cpu_name(), cpus=os.cpu_count(),
                    date=time.strftime("%Y-%m-%d", time.gmtime()),
                    command="python -m bench.paced_split " + " ".join(sys.argv[1:])
                    if argv is None else "")
        write_case(Path(args.results), args.case or f"contact_{args.contact}"
                   + ("" if args.object_model == "estimated" else f"_{args.object_model}"), case)
        print(json.dumps(case.get("comparison"), default=float))
        return 0
    out = Path(args.out)
    scenario = compensated_scenario(args.scenario, args.horizon, out / "scenario.yaml")
    for sched in args.sched:
        for tick in args.tick:
            key = args.case or ("emulated_" if args.emulate else "") + f"{sched}_{tick}"
            case = run_case(scenario, out / key, t_end=args.t_end, tick=tick, sched=sched,
                            margin=args.margin, compute_bar=args.compute_bar,
                            priority=dict(zip(("hub", "serve", "driver"), args.priorities)),
                            serve_cpus=args.serve_cpus, driver_cpu=args.driver_cpu,
                            emulate=args.emulate)
            case.update(horizon_s=args.horizon, drake=version("drake"), cpu=_cpu_name(),
                        cpus=os.cpu_count(), date=time.strftime("%Y-%m-%d", time.gmtime()),
                        command=("python -m bench.paced_split " + " ".join(sys.argv[1:])
                                 if argv is None else ""))
            write_case(Path(args.results), key, case)
            print(key, json.dumps({"bars": case["bars"], "emulation": case.get("emulation"),
                                   "robots": {
                r: {k: v for k, v in a.items() if k.endswith(("p50_s", "p99_s"))
                    or k in ("status", "missed_deadlines")}
                for r, a in case["robots"].items()}}, default=float), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
