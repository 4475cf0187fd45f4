"""The object remedy on lab arms: squeeze, box path, slips, drops and mass estimate.

Runs each named scenario with ``contact.yaml``'s plant (a real box held by friction at
hydroelastic pads, 3 ms plant step) and ``object_model: {mode: estimated}`` to the circle's
end (+1 s), and writes the circle phase's metrics (and the mass estimate at the lift's end)
to a JSON file::

    python -m bench.lab_arms_object two_pandas two_ur5 contact --out docs/results/lab_arms_object.json

A name is a shipped scenario (or a YAML file); ``contact`` is the paper's arms. Each case is
written as soon as it ends, with its command, the drake version and the CPU (the file keeps
the cases of other calls). ``--mass`` (kg), ``--mu`` and ``--time-step`` (s) change the
plant's box mass, pad–box friction and plant step (the controllers' assumed μ follows the
plant's unless the scenario sets ``object_model.mu``), ``--squeeze`` the object model's
squeeze source (``profile``, the task's (29), or ``friction``); such a case is stored under
``NAME@m<mass>_mu<mu>[_dt<step>][_sq<squeeze>]`` (``.`` written ``p``, as the docs' ``{result}`` role splits
a key path on dots) unless ``--case`` names it. Per robot the circle phase's squeeze error,
the box's position error, its whole rotation, its turn about the grasp line and its tilt
(``object_turn``, ``object_tilt``: RMS of the signed turn, max of its magnitude; rad), the
friction use, the largest slip with its creep floor, slips and drops.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

#: contact.yaml's plant fields copied onto a lab-arm scenario.
CONTACT_PLANT = ("object_mode", "object_mass", "friction", "time_step", "stand_clearance")


def contact_scenario(name: str, control_point: str = "auto", *, mass: float | None = None,
                     mu: float | None = None, time_step: float | None = None,
                     squeeze: str | None = None):
    """``name`` with contact.yaml's plant (unless it is a ``contact`` scenario already) and an
    estimated object model (unless it has one); ``mass``, ``mu``, ``time_step`` (when given)
    replace the plant's box mass, friction and step, ``squeeze`` the object model's squeeze
    source (``profile`` or ``friction``)."""
    from drake_coop.scenario import validate
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.resources import scenarios_dir

    path = Path(name) if name.endswith(".yaml") else scenarios_dir() / f"{name}.yaml"
    scenario = load_scenario(path)
    if scenario.plant.object_mode != "contact":
        contact = load_scenario(scenarios_dir() / "contact.yaml")
        for field in CONTACT_PLANT:
            setattr(scenario.plant, field, getattr(contact.plant, field))
    if scenario.object_model.mode == "none":
        scenario.object_model.mode = "estimated"
    scenario.object_model.control_point = control_point
    for field, value in (("object_mass", mass), ("friction", mu), ("time_step", time_step)):
        if value is not None:
            setattr(scenario.plant, field, float(value))
    if squeeze is not None:
        scenario.object_model.squeeze = squeeze
    validate(scenario)
    return scenario


def measure(scenario) -> dict:
    """The circle phase's metrics of one run (to the circle's end + 1 s)."""
    from drake_coop.experiment.simulate import simulate
    from drake_coop.results.metrics import compute_metrics

    task = scenario.task
    start = time.process_time()
    result = simulate(scenario, t_end=task.t_circle_end + 1.0)
    cpu = time.process_time() - start
    metrics = compute_metrics(result.logs, result.meta)
    out: dict = {"status": result.meta["status"], "message": result.meta.get("message", ""),
                 "cpu_seconds": round(cpu, 1), "robots": {}}
    mass = float(scenario.plant.object_mass)
    for robot, log in result.logs.items():
        circle = metrics[robot]["circle"]
        entry = {"squeeze_error_rms_N": circle["force_error"]["rms"]}
        for key in ("object_position_error", "object_angle_error", "object_turn",
                    "object_tilt", "friction_use"):
            if key in circle:
                entry[f"{key}_rms"] = circle[key]["rms"]
                entry[f"{key}_max"] = circle[key]["max"]
        if "slip" in circle:
            entry["slip_max"] = circle["slip"]["max"]
            entry["slip_floor"] = circle["slip"].get("floor")
        entry["slips"] = circle.get("slips", {}).get("count")
        entry["drops"] = circle.get("drops", {}).get("count")
        out["robots"][robot] = entry
    t = np.asarray(next(iter(result.logs.values()))["t"])
    k = int(np.searchsorted(t, task.t_circle_start - 1e-9)) - 1
    shares = [np.asarray(log["mass_share"])[k] for log in result.logs.values()
              if "mass_share" in log]
    if shares:
        out["mass_at_lift_end_kg"] = float(np.sum(shares))
        out["mass_error_at_lift_end"] = float(np.sum(shares) / mass - 1.0)
    sources = turn_sources(result.logs, result.meta)
    if sources is not None:
        out["turn_sources"] = sources
    out["object_mass_kg"] = mass
    out["friction"] = float(scenario.plant.friction)
    out["time_step_s"] = float(scenario.plant.time_step)
    out["squeeze"] = scenario.object_model.squeeze
    return out


def turn_sources(logs: dict, meta: dict) -> dict | None:
    """What the box's turn about the grasp line follows over the circle, among what the
    controllers can compute from their encoders (the pad body's rotation, forward kinematics
    of the logged ``q``): each pad's twist about the same line since the grasp (its finite
    rotation's twist, :func:`~drake_coop.results.object_metrics.turn_and_tilt`) and each pad's
    **spin** about it, ``∫ ω·a dt`` since the grasp (``ω`` the pad's angular velocity, from
    one logged rotation to the next; ``a`` the grasp line, fixed in the box, in the world at
    each sample): the rotation a patch that does not slide in torsion gives the box. For each,
    the least-squares fit ``turn ≈ k · (the two pads' mean)``: slope ``k``, the correlation
    ``r`` and the RMS of what the fit leaves. None without the object's signals."""
    from drake_coop.kinematics.rotations import quaternion_rotations
    from drake_coop.results.object_metrics import grasp_axis, object_signals, turn_and_tilt
    from pydrake.math import RotationMatrix

    signals = object_signals(logs, meta)
    robots = list(logs)
    if not signals or any("pad_rotation" not in logs[r] for r in robots):
        return None
    t = np.asarray(logs[robots[0]]["t"])
    span = {str(name): (a, b) for name, a, b in meta["phases"]}
    if "circle" not in span:
        return None
    k0 = int(np.searchsorted(t, float(span["lift"][0]) - 1e-9))
    circle = (t >= span["circle"][0]) & (t < span["circle"][1])
    pose = np.asarray(logs[robots[0]]["object_pose"])
    a_B = grasp_axis([np.asarray(logs[r]["pad_in_object"])[k0] for r in robots],
                     0.5 * float(meta["object_size"][0]))
    R_B = quaternion_rotations(pose[:, :4])
    a_W = np.einsum("kij,j->ki", R_B, a_B)
    turn = signals[robots[0]]["object_turn"]
    twists, spins = {}, {}
    for r in robots:
        R = np.asarray(logs[r]["pad_rotation"])
        quats = np.array([RotationMatrix(Rk).ToQuaternion().wxyz() for Rk in R])
        twists[r], _ = turn_and_tilt(quats, k0, R[k0].T @ a_W[k0])
        step = np.zeros(len(R))
        for k in range(k0 + 1, len(R)):
            aa = RotationMatrix(R[k - 1].T @ R[k]).ToAngleAxis()   # body frame at k - 1
            step[k] = aa.angle() * float((R[k - 1] @ aa.axis()) @ a_W[k])
        spins[r] = np.cumsum(step)

    def fit(signal: dict) -> dict:
        x, y = np.mean([signal[r] for r in robots], axis=0)[circle], turn[circle]
        k = float(x @ y / (x @ x)) if x @ x > 0 else 0.0
        return {"slope": k, "residual_rms": float(np.sqrt(np.mean((y - k * x) ** 2))),
                "correlation": float(np.corrcoef(x, y)[0, 1]) if np.std(x) > 0 else None}

    return {"pad_twist_rms": {r: float(np.sqrt(np.mean(twists[r][circle] ** 2)))
                              for r in robots},
            "pad_twist_max": {r: float(np.max(np.abs(twists[r][circle]))) for r in robots},
            "pad_spin_rms": {r: float(np.sqrt(np.mean(spins[r][circle] ** 2))) for r in robots},
            "pad_spin_max": {r: float(np.max(np.abs(spins[r][circle]))) for r in robots},
            "twist_fit": fit(twists), "spin_fit": fit(spins)}


def case_name(name: str, mass: float | None, mu: float | None, time_step: float | None,
              squeeze: str | None = None) -> str:
    """The case's key: ``name``, with the changed box, step and squeeze when any is given."""
    parts = [f"{tag}{value:g}".replace(".", "p") for tag, value in
             (("m", mass), ("mu", mu), ("dt", time_step)) if value is not None]
    parts += [f"sq{squeeze}"] if squeeze is not None else []
    return name if not parts else f"{name}@{'_'.join(parts)}"


def _cpu_name() -> str:
    """The CPU's model name (``/proc/cpuinfo``; the platform's otherwise)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def write_case(out: Path, key: str, case: dict) -> None:
    """Add ``case`` under ``key`` to the JSON file ``out`` (created if absent), whole or not at
    all: read again and written under an exclusive lock on ``out``'s folder, so that calls
    running at once each keep the others' cases."""
    import fcntl
    import os

    out.parent.mkdir(parents=True, exist_ok=True)
    folder = os.open(out.parent, os.O_RDONLY)
    try:
        fcntl.flock(folder, fcntl.LOCK_EX)
        data = json.loads(out.read_text()) if out.exists() else {"cases": {}}
        data["cases"][key] = case
        tmp = out.with_name(f"{out.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(data, indent=1, sort_keys=True) + "\n")
        tmp.replace(out)
    finally:
        os.close(folder)         # releases the lock


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="+")
    parser.add_argument("--out", required=True)
    parser.add_argument("--control-point", default="auto")
    parser.add_argument("--mass", type=float, help="the box's mass (kg)")
    parser.add_argument("--mu", type=float, help="the pad-box friction coefficient")
    parser.add_argument("--time-step", type=float, help="the plant step (s)")
    parser.add_argument("--squeeze", choices=("profile", "friction"),
                        help="the object model's squeeze source")
    parser.add_argument("--case", help="the case's key in the file (one name only)")
    args = parser.parse_args(argv)
    if args.case is not None and len(args.names) != 1:
        parser.error("--case: names one case; give one scenario name with it")
    out = Path(args.out)
    from importlib.metadata import version

    for name in args.names:
        scenario = contact_scenario(name, args.control_point, mass=args.mass, mu=args.mu,
                                    time_step=args.time_step, squeeze=args.squeeze)
        case = measure(scenario)
        case["control_point"] = args.control_point
        case["command"] = ("python -m bench.lab_arms_object " + " ".join(sys.argv[1:])
                           if argv is None else "")
        case["drake"] = version("drake")
        case["cpu"] = _cpu_name()
        key = args.case or case_name(name, args.mass, args.mu, args.time_step, args.squeeze)
        write_case(out, key, case)
        print(name, json.dumps(case), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
