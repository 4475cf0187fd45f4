"""Every arm ``drake-coop arms`` lists carries the object guide's box, or is refused with the
reason: one row per arm pair, resumable.

A row is a pair of one arm (``jaco2``: two Kinova Jaco2s) or the mixed pair :data:`MIXED`
(two different models on one box). Each is set up as the lab-arms guide's how-to says
(``docs/guide/lab_arms.md``, "An arm the project does not ship"): the entry ``drake-coop arms
--yaml NAME`` prints, twice, robot 2 the mirror image of robot 1 (base turned 180°, its yaw
added to ``ee_rpy_deg``), ``contact_xy`` 0.6 m and 0.74 m (a 0.11 m box), the box of
``scenarios/contact.yaml`` (the object guide's: 0.5 kg, μ 1) with ``object_model: {mode:
estimated}``, no gains. The base's place is the first of :data:`PLACEMENTS` (distance behind
the contact point, riser height) whose scenario the validation accepts (the whole path within
reach and the joint limits); an arm with none is refused with the validation's last line.
Then what a user does: the gains as ``drake-coop gains`` derives and checks them
(:func:`drake_coop.stability.gains.derive_and_check`, with the task's checks: a refusal is the
row's result), and the run to the circle's end (+1 s) measured by
:func:`bench.unseen_arms.measure_with_lift` (the code of the other lab-arm benchmarks)::

    python -m bench.every_arm --out docs/results/every_arm.json              # every row
    python -m bench.every_arm jaco2 mixed --out docs/results/every_arm.json  # some rows
    python -m bench.every_arm --table --out docs/results/every_arm.json      # the table only
    python -m bench.every_arm --buckling jaco2 --out docs/results/every_arm.json  # diagnosis
    python -m bench.every_arm --grasp-dynamics ur5 --out docs/results/every_arm.json  # check
    python -m bench.every_arm --recheck ur5 --out docs/results/every_arm.json  # verdict again
    python -m bench.every_arm --lift jaco2 --out docs/results/every_arm.json  # the lift's truth
    python -m bench.every_arm jaco2 --squeeze friction --out docs/results/every_arm.json
    python -m bench.every_arm ur3 --squeeze-scale 0.5 --out docs/results/every_arm.json

A row already in the file is skipped (``--force`` runs it again); each row is written as soon
as it ends (:func:`bench.lab_arms_object.write_case`), with its command, CPU and wall time,
drake version and CPU model. ``--table`` (also after every row) writes the guide's generated
table, ``docs/results/every_arm.md`` (included by the guide), from the file (:func:`table`). A row's verdict is
the bars of :data:`BARS` on the circle phase (the worst arm), or its refusal.
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

#: The mixed pair: robot 1 and robot 2's arms.
MIXED = ("ur5", "z1")
#: Base placements tried in order: (distance behind the contact point, riser height), m.
PLACEMENTS = [(back, riser) for back in (0.45, 0.4, 0.5, 0.35, 0.55, 0.3, 0.25, 0.2)
              for riser in (0.1, 0.2, 0.0, 0.3, 0.4, 0.5)]
#: The pads' contact points (x, m) and the box's plant (scenarios/contact.yaml's).
CONTACT_X = (0.6, 0.74)
#: The bars per row: squeeze error RMS (N, worst arm), box position error RMS (m), slips.
BARS = {"squeeze_error_rms_N": 0.3, "object_position_error_rms_m": 0.5e-3, "slips": 0}
#: The generated table.
TABLE = Path(__file__).resolve().parents[1] / "docs" / "results" / "every_arm.md"


def robot_entry(name: str, index: int, back: float, riser: float) -> str:
    """Robot ``index`` (1 on the −x side, 2 on the +x side) of arm ``name`` as the how-to
    writes it from ``drake-coop arms --yaml NAME``: placed ``back`` m behind its contact point
    on a ``riser`` m riser, facing the box (YAML text, one list item)."""
    from drake_coop.scenario.arms_cli import _yaml

    x = CONTACT_X[index - 1]
    side = -1.0 if index == 1 else 1.0
    values = {"- name:": f"- name: {name}_{index}",
              "  base_xyz:": f"  base_xyz: [{x + side * back:.4g}, 0.0, {riser:g}]",
              "  base_yaw_deg:": f"  base_yaw_deg: {0.0 if index == 1 else 180.0}",
              "  contact_xy:": f"  contact_xy: [{x:g}, 0.0]",
              "  normals:": f"  normals: [[{side:g}, 0.0, 0.0]]",
              "  home:": f"  home: [{x + side * 0.1:.4g}, 0.0, 0.6]",
              "  ee_rpy_deg: [": f"  ee_rpy_deg: [0.0, 90.0, {0.0 if index == 1 else 180.0}]"}
    lines = []
    for line in _yaml(name).splitlines():
        if line.lstrip().startswith("#"):
            continue
        line = line.split("  #")[0].rstrip()
        key = next((k for k in values if line.startswith(k)), None)
        lines.append(values[key] if key else line)
    return "\n".join(lines)


def pair_yaml(arms: tuple[str, str], places: tuple[tuple[float, float], ...]) -> str:
    """The scenario text of a pair (no gains): ``arms`` robot 1 and 2, ``places`` their
    ``(back, riser)``."""
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.resources import scenarios_dir

    plant = load_scenario(scenarios_dir() / "contact.yaml").plant
    head = (f"plant: {{object_mode: contact, object_mass: {plant.object_mass:g}, friction: "
            f"{plant.friction:g}, time_step: {plant.time_step:g}, stand_clearance: "
            f"{plant.stand_clearance:g}}}\nobject_model: {{mode: estimated}}\nrobots:\n")
    return head + "\n".join(robot_entry(a, i + 1, *p) for i, (a, p) in
                            enumerate(zip(arms, places))) + "\n"


def load_pair(arms: tuple[str, str], places: tuple, path: Path):
    """The pair's scenario (:func:`pair_yaml`) written to ``path``, loaded as ``gains``
    loads it, the file removed again (also when the load refuses: its error propagates)."""
    from drake_coop.stability.gains_cli import load_for_gains

    path.write_text(pair_yaml(arms, tuple(places)))
    try:
        return load_for_gains(str(path))
    finally:
        path.unlink(missing_ok=True)


def placement(name: str, folder: Path) -> tuple[tuple[float, float] | None, str]:
    """The first of :data:`PLACEMENTS` whose mirrored pair of ``name`` validates, or None and
    the validation's last refusal."""
    from drake_coop.scenario.schema import ScenarioError

    last = ""
    for place in PLACEMENTS:
        try:
            load_pair((name, name), (place, place), folder / f".{name}.placement.yaml")
            return place, ""
        except (ScenarioError, ValueError) as exc:
            last = str(exc)
    return None, last


def run_row(key: str, out: Path, squeeze: str | None = None,
            past_refusal: bool = False, squeeze_scale: float | None = None) -> dict:
    """One row: the placement, the gains and their checks, the run (module docstring);
    ``squeeze`` (``profile`` or ``friction``) sets ``object_model.squeeze`` (None: the
    how-to's default); ``past_refusal`` runs the derived gains even when ``gains`` refuses
    them (the refusal is kept beside the run as ``refused_by``: what the run says of it);
    ``squeeze_scale`` multiplies the task's squeeze profile (``task.force_mean`` and
    ``force_amplitude``: a case the checks were not designed on)."""
    from bench.lab_arms_object import contact_scenario
    from bench.unseen_arms import measure_with_lift
    from drake_coop.scenario.loading import dump_scenario
    from drake_coop.stability.gains import derive_and_check, gains_for_scenario
    from drake_coop.stability.gains_cli import load_for_gains

    arms = MIXED if key == "mixed" else (key, key)
    folder = out.parent
    folder.mkdir(parents=True, exist_ok=True)
    places = []
    for arm in dict.fromkeys(arms):
        place, why = placement(arm, folder)
        if place is None:
            return {"arms": list(arms), "refusal": f"{arm}: no placement within reach: {why}"}
        places.append(place)
    places = places * 2 if arms[0] == arms[1] else places
    text = pair_yaml(arms, tuple(places))
    case: dict = {"arms": list(arms), "placement": [list(p) for p in places],
                  "scenario_yaml": text}
    path = folder / f".{key}.every_arm.yaml"
    path.write_text(text)
    try:
        scenario = load_for_gains(str(path))
        if squeeze is not None:
            scenario.object_model.squeeze = squeeze
        if squeeze_scale is not None:
            scenario.task.force_mean *= squeeze_scale
            scenario.task.force_amplitude *= squeeze_scale
            case["squeeze_scale"] = squeeze_scale
        start = time.process_time()
        report = derive_and_check(scenario)
        case["gains"] = {
            "rho": report.rho, "stable": report.stable, "attempts": report.attempts,
            "cpu_seconds": round(time.process_time() - start, 1),
            "task_checks": ({c.name: {"passes": c.passes, "message": c.message,
                                      "values": c.values}
                             for c in report.task.checks} if report.task else {}),
            "robots": {d.name: {"K_R": [float(k) for k in d.gains.K_R],
                                "Lambda": d.gains.Lambda, "xi": d.gains.xi}
                       for d in report.robots}}
        if not report.stable:
            if not past_refusal:
                case["refusal"] = f"drake-coop gains: {report.refusal}"
                return case
            case["refused_by"] = f"drake-coop gains: {report.refusal}"
        path.write_text(dump_scenario(gains_for_scenario(scenario, report.robots)))
        scenario = contact_scenario(str(path), squeeze=squeeze)   # the scaled task written
    finally:
        path.unlink(missing_ok=True)
    try:
        case.update(measure_with_lift(scenario))
    except KeyError as exc:          # the run ended before the circle: no circle to measure
        if exc.args != ("circle",):
            raise
        case["lift"] = lift_truth(scenario, list(arms))
        case["status"], case["message"] = case["lift"]["status"], case["lift"]["message"]
        return case
    case["verdict"] = verdict(case)
    return case


def grasp_row(key: str, out: Path, squeeze: str | None = None) -> dict:
    """The grasp's dynamics check of ``drake-coop gains`` alone
    (:func:`~drake_coop.stability.grasp_dynamics.check_grasp_dynamics`) on a row's setup, at
    the gains derived at the first attempt (:func:`~drake_coop.stability.gains.derive_gains`;
    a row whose gains ``gains`` backed off is not checked here): what the check says of a row
    whose run is in the file, without running the rest of ``gains`` or the task again."""
    from drake_coop.stability.gains import derive_gains, gains_for_scenario
    from drake_coop.stability.grasp_dynamics import check_grasp_dynamics

    arms, scenario = _placed_pair(key, out, "grasp", squeeze)
    derived = derive_gains(scenario)
    result = check_grasp_dynamics(gains_for_scenario(scenario, derived))
    return {"arms": list(arms), "passes": result.passes, "message": result.message,
            "growth_rate_per_s": result.sigma, "amplification": result.amplification,
            "worst": result.worst, "joints": result.joints, "pads": result.pads,
            "cpu_seconds": result.cpu_seconds, "values": grasp_values(result),
            "K_R": {d.name: [float(k) for k in d.gains.K_R] for d in derived}}


def _placed_pair(key: str, out: Path, purpose: str, squeeze) -> tuple:
    """Row ``key``'s two arms at their stored placements, loaded as ``gains`` loads them
    (through ``.{key}.{purpose}.yaml`` beside ``out``), its squeeze set when given."""
    arms = MIXED if key == "mixed" else (key, key)
    places = [placement(a, out.parent)[0] for a in dict.fromkeys(arms)]
    places = places * 2 if arms[0] == arms[1] else places
    scenario = load_pair(arms, places, out.parent / f".{key}.{purpose}.yaml")
    if squeeze is not None:
        scenario.object_model.squeeze = squeeze
    return arms, scenario


def grasp_values(result) -> dict:
    """The grasp check's record in a row's ``gains.task_checks.grasp.values``."""
    return {"checked": result.checked, "growth_rate_per_s": result.sigma,
            "amplification": result.amplification, "tilt_deg": result.tilt_deg,
            "worst": result.worst, "joints": result.joints, "pads": result.pads,
            "box_turn_axis": result.box_turn_axis, "cpu_seconds": result.cpu_seconds}


#: A row's keys that hold its run (what :func:`bench.unseen_arms.measure_with_lift` adds).
RUN_KEYS = ("robots", "verdict", "status", "message", "mass_at_lift_end_kg",
            "mass_error_at_lift_end", "object_mass_kg", "friction", "time_step_s",
            "turn_sources", "cpu_seconds", "squeeze")


def recheck(key: str, data: dict, out: Path) -> dict:
    """A row of the file (``ROW`` or ``ROW@sqS``) checked again by the grasp's dynamics
    check alone at the gains ``gains`` derives (:func:`grasp_row`), its verdict rewritten from
    it and from the runs in the file: refused, with the row's run (if any) kept as its run
    past the refusal (``ROW@past``); passed, with its run, or the run past the old refusal
    (which followed the same gains) as its run. Returns the cases to write (key to case); a
    row the check now passes with no run in the file is run (:func:`run_row`)."""
    cases = data["cases"]
    case = copy.deepcopy(cases[key])
    if "gains" not in case or "grasp" not in case["gains"].get("task_checks", {}):
        return {}                     # refused before the grasp check (placement, the map)
    other = [n for n, c in case["gains"]["task_checks"].items()
             if n != "grasp" and not c["passes"]]
    if other:
        return {}
    squeeze = key.split("@sq")[1] if "@sq" in key else None
    found = grasp_row(key.split("@")[0], out, squeeze)
    grasp = case["gains"]["task_checks"]["grasp"]
    grasp.update(passes=found["passes"], message=found["message"],
                 values={**grasp.get("values", {}), **found["values"]})
    case["grasp_recheck"] = {"cpu_seconds": found["cpu_seconds"], "K_R": found["K_R"]}
    case["gains"]["stable"] = found["passes"]
    past_key = f"{key}@past"
    past = copy.deepcopy(cases.get(past_key))
    written = {key: case}
    if found["passes"]:
        case.pop("refusal", None)
        if "verdict" not in case:
            if past is None or "verdict" not in past:
                return {}             # a run is needed: the caller runs the row
            case.update({k: past[k] for k in RUN_KEYS if k in past})
            case["run_command"] = past.get("command")
        case.pop("refused_by", None)
        return written
    case["refusal"] = f"drake-coop gains: {found['message']}"
    if "verdict" in case:             # its run goes on as the run past the refusal
        past = {k: case.pop(k) for k in RUN_KEYS if k in case}
        past.update(arms=case["arms"], command=case.get("command", "") + " --past-refusal",
                    refused_by=case["refusal"])
        written[past_key] = past
    elif past is not None:
        past["refused_by"] = case["refusal"]
        written[past_key] = past
    return written


def lift_row(key: str, out: Path, squeeze: str | None = None) -> dict:
    """The row's pair (its setup and the gains ``gains`` derives, no checks) run to the
    lift's end, from the plant's truth (:func:`~drake_coop.results.object_metrics.
    object_signals`): the run's status and message, the box's largest tilt (degrees) and the
    first time it passes the tilt guard, the pads' largest friction use ``f_t / (μ f_n)`` and
    slide on the box (m) before that time: whether a grasp lost in the lift slid or turned."""
    from drake_coop.stability.gains import derive_gains, gains_for_scenario

    arms, scenario = _placed_pair(key, out, "lift", squeeze)
    return lift_truth(gains_for_scenario(scenario, derive_gains(scenario)), list(arms))


def lift_truth(scenario, arms: list) -> dict:
    """:func:`lift_row`'s run of a scenario with its gains, to the lift's end."""
    from drake_coop.experiment.simulate import simulate
    from drake_coop.results.object_metrics import object_signals

    start = time.process_time()
    result = simulate(scenario, t_end=scenario.task.t_circle_start)
    signals = object_signals(result.logs, result.meta)
    robots = list(result.logs)
    t = np.asarray(result.logs[robots[0]]["t"], dtype=float)
    tilt = np.degrees(np.nan_to_num(signals[robots[0]]["object_tilt"]))
    guard = scenario.guards.max_object_tilt_deg
    past = np.flatnonzero(tilt > guard)
    end = int(past[0]) if past.size else len(t)
    use = max(float(np.nanmax(np.append(signals[r]["friction_use"][:end], 0.0)))
              for r in robots)
    slide = max(float(np.nanmax(np.append(np.abs(signals[r]["slip"][:end]), 0.0)))
                for r in robots)
    return {"arms": list(arms), "status": result.meta["status"],
            "message": result.meta.get("message"), "t_end": float(t[-1]),
            "tilt_max_deg": float(tilt.max()), "tilt_guard_deg": guard,
            "t_tilt_guard": float(t[past[0]]) if past.size else None,
            "friction_use_max": use, "slide_max_m": slide,
            "cpu_seconds": round(time.process_time() - start, 1)}


def buckling(key: str, out: Path, t_end: float = 24.0) -> dict:
    """The grasp's buckling bound against the simulated truth on a pair (the row's setup and
    derived gains, :func:`~drake_coop.stability.gains.derive_gains`, no checks): the task's
    squeeze (``profile``) and the friction squeeze on a box of μ 2 (``friction_mu2``), each
    run to ``t_end`` s (the lift): the bound's worst ``λ_d / λ_b`` before ``t_end``, the box's
    rotation angle at the end and its largest, the pads' sideways error at the end."""
    from drake_coop.experiment.simulate import simulate
    from drake_coop.kinematics.rotations import quaternion_rotations
    from drake_coop.stability.gains import derive_gains, gains_for_scenario
    from drake_coop.stability.grasp import check_grasp_buckling

    arms = MIXED if key == "mixed" else (key, key)
    places = [placement(a, out.parent)[0] for a in arms]
    base = load_pair(arms, places, out.parent / f".{key}.buckling.yaml")
    base = gains_for_scenario(base, derive_gains(base))
    cases = {}
    for name, squeeze, mu in (("profile", "profile", None), ("friction_mu2", "friction", 2.0)):
        s = copy.deepcopy(base)
        s.object_model.squeeze = squeeze
        if mu is not None:
            s.plant.friction = mu
        bound = check_grasp_buckling(s, t_end=t_end)
        start = time.process_time()
        result = simulate(s, t_end=t_end)
        log = next(iter(result.logs.values()))
        R = quaternion_rotations(np.asarray(log["object_pose"])[:, :4])
        angle = np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1))
        err = np.asarray(log["x"]) - np.asarray(log["x_d"])
        cases[name] = {"worst_ratio": bound.worst_ratio, "ratio_t": bound.t,
                       "squeeze_N": bound.squeeze, "lambda_b_N": bound.lambda_b,
                       "min_lambda_b_N": bound.min_lambda_b,
                       "stiffness_N_per_m": bound.stiffness, "distance_m": bound.distance,
                       "box_angle_end_rad": float(angle[-1]), "box_angle_max_rad":
                       float(angle.max()), "pad_sideways_error_end_m":
                       float(np.linalg.norm(err[-1, 1:3])),
                       "squeeze_measured_end_N": float(np.ravel(log["lambda_meas"][-1])[0]),
                       "squeeze_desired_end_N": float(np.ravel(log["lambda_d"][-1])[0]),
                       "cpu_seconds": round(time.process_time() - start, 1)}
    return {"arms": list(arms), "t_end": t_end, "runs": cases}


def verdict(case: dict) -> dict:
    """The row's bars (:data:`BARS`, the worst arm) and the box's tilt, from its metrics."""
    robots = list(case["robots"].values())
    measured = {"squeeze_error_rms_N": max(r["squeeze_error_rms_N"] for r in robots),
                "object_position_error_rms_m": max(r["object_position_error_rms"]
                                                   for r in robots),
                "slips": sum(r["slips"] or 0 for r in robots)}
    out = {k: {"value": v, "bar": BARS[k], "passes": bool(v <= BARS[k])}
           for k, v in measured.items()}
    out["passes"] = all(v["passes"] for v in out.values())
    return out


def _cell(value, fmt: str, scale: float = 1.0) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    return format(value * scale, fmt)


def _remedy(data: dict, key: str) -> str:
    """For a missed row: ``(status …; squeeze: friction passes)`` when its failure and a
    passing ``KEY@sqfriction`` row are in the file."""
    notes = []
    case = data["cases"][key]
    if case.get("status") not in (None, "ok"):
        notes.append(case.get("message") or case["status"])
    other = data["cases"].get(f"{key}@sqfriction", {}).get("verdict", {})
    if "@" not in key and other.get("passes"):
        notes.append("`squeeze: friction` passes")
    return f" ({'; '.join(notes)})" if notes else ""


def table(data: dict) -> str:
    """The guide's table (Markdown) from the results file's ``cases``: per row the squeeze
    error, the box's position error, its tilt, slips, the mass estimate and the verdict, or
    the one-line refusal.

    Parameters
    ----------
    data : dict
        The results file.

    Returns
    -------
    str
        The table.
    """
    lines = ["| arms | squeeze error RMS (N) | box position error RMS (mm) | box tilt RMS (mrad) "
             "| slips | mass at the lift's end (%) | bars (0.3 N, 0.5 mm, 0 slips) |",
             "| --- | --- | --- | --- | --- | --- | --- |"]
    for key in sorted(data["cases"], key=lambda k: (k.split("@")[0] == "mixed", k)):
        if key.endswith(("@buckling", "@past", "@grasp", "@lift")) or "@scale" in key:
            continue
        case = data["cases"][key]
        arms = " + ".join(case.get("arms", [key]))
        if "@sq" in key:
            arms += f", `squeeze: {key.split('@sq')[1]}`"
        if "refusal" in case:
            reason = " ".join(case["refusal"].split()).replace("|", "/")
            past = data["cases"].get(f"{key}@past")
            if past is not None and "verdict" in past:
                reason += "; run past the refusal: " + (
                    past.get("message") if past.get("status") != "ok" else
                    f"carried ({_cell(past['verdict']['squeeze_error_rms_N']['value'], '.3f')} N,"
                    f" {_cell(past['verdict']['object_position_error_rms_m']['value'], '.2f', 1e3)}"
                    " mm): the refusal is wrong here")
            lines.append(f"| {arms} | refused: {reason} | | | | | refused |")
            continue
        robots = list(case["robots"].values())
        v = case["verdict"]
        tilt = max((r.get("object_tilt_rms") or 0.0) for r in robots)
        lines.append(
            f"| {arms} | {_cell(v['squeeze_error_rms_N']['value'], '.3f')} "
            f"| {_cell(v['object_position_error_rms_m']['value'], '.2f', 1e3)} "
            f"| {_cell(tilt, '.2f', 1e3)} | {v['slips']['value']:.0f} "
            f"| {_cell(case.get('mass_error_at_lift_end'), '+.1f', 100)} "
            f"| {'pass' if v['passes'] else 'miss' + _remedy(data, key)} |")
    return ("<!-- generated by python -m bench.every_arm --table from "
            "docs/results/every_arm.json: do not edit -->\n" + "\n".join(lines) + "\n")


def main(argv=None) -> int:
    """Run the rows (module docstring).

    Parameters
    ----------
    argv : list of str or None
        The command line (None: ``sys.argv``).

    Returns
    -------
    int
        0.
    """
    from drake_coop.scenario.lab_arms import LAB_ARMS

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rows", nargs="*", help=f"arms of drake-coop arms ({', '.join(LAB_ARMS)}) "
                                                "or mixed; none: every row")
    parser.add_argument("--out", required=True)
    parser.add_argument("--force", action="store_true", help="run rows already in the file")
    parser.add_argument("--table", action="store_true", help="only write the guide's table")
    parser.add_argument("--squeeze", choices=("profile", "friction"),
                        help="the object model's squeeze source (the row is stored as "
                             "ROW@sq<squeeze>)")
    parser.add_argument("--past-refusal", action="store_true",
                        help="run the derived gains even when gains refuses them, to test "
                             "the refusal (the row is stored as ROW@past)")
    parser.add_argument("--squeeze-scale", type=float, metavar="S",
                        help="multiply the task's squeeze profile by S (the row is stored as "
                             "ROW@scaleS; not in the guide's table)")
    parser.add_argument("--grasp-dynamics", action="store_true",
                        help="instead of the rows: only the grasp's dynamics check of gains "
                             "on each named pair (:func:`grasp_row`), under ROW[@sqS]@grasp")
    parser.add_argument("--lift", action="store_true",
                        help="instead of the rows: each named pair run to the lift's end, "
                             "its tilt, friction use and slide (:func:`lift_row`), under "
                             "ROW[@sqS]@lift")
    parser.add_argument("--recheck", action="store_true",
                        help="instead of the rows: check each named row of the file again "
                             "with the grasp's dynamics check and rewrite its verdict "
                             "(:func:`recheck`; ROW or ROW@sqS with --squeeze)")
    parser.add_argument("--buckling", action="store_true",
                        help="instead of the rows: the buckling bound against the simulated "
                             "truth on each named pair (:func:`buckling`), under ROW@buckling")
    args = parser.parse_args(argv)
    rows = args.rows or [*LAB_ARMS, "mixed"]
    for row in rows:
        if row not in LAB_ARMS and row != "mixed":
            parser.error(f"rows: {row!r} is not an arm of drake-coop arms nor mixed")
    if args.squeeze_scale is not None and not args.squeeze_scale > 0:
        parser.error(f"--squeeze-scale: must be > 0, got {args.squeeze_scale:g}")
    out = Path(args.out)
    from importlib.metadata import version

    from bench.lab_arms_object import _cpu_name, write_case

    if args.grasp_dynamics:
        for row in args.rows:
            key = row + (f"@sq{args.squeeze}" if args.squeeze else "") + "@grasp"
            done = json.loads(out.read_text())["cases"] if out.exists() else {}
            if key in done and not args.force:
                print(f"{key}: in {out}, skipped (--force runs it again)", flush=True)
                continue
            case = grasp_row(row, out, args.squeeze)
            case["command"] = (f"python -m bench.every_arm --grasp-dynamics {row} --out "
                               f"{args.out}" + (f" --squeeze {args.squeeze}"
                                                if args.squeeze else ""))
            case["drake"], case["cpu"] = version("drake"), _cpu_name()
            write_case(out, key, case)
            print(key, case["message"], flush=True)
        return 0
    if args.lift:
        for row in args.rows:
            key = row + (f"@sq{args.squeeze}" if args.squeeze else "") + "@lift"
            case = lift_row(row, out, args.squeeze)
            case["command"] = (f"python -m bench.every_arm --lift {row} --out {args.out}"
                               + (f" --squeeze {args.squeeze}" if args.squeeze else ""))
            case["drake"], case["cpu"] = version("drake"), _cpu_name()
            write_case(out, key, case)
            print(key, json.dumps(case), flush=True)
        return 0
    if args.recheck:
        for row in args.rows:
            key = row + (f"@sq{args.squeeze}" if args.squeeze else "")
            data = json.loads(out.read_text())
            if key not in data["cases"]:
                print(f"{key}: not in {out}, run it first", flush=True)
                continue
            if "grasp_recheck" in data["cases"][key] and not args.force:
                print(f"{key}: rechecked in {out}, skipped (--force checks it again)",
                      flush=True)
                continue
            written = recheck(key, data, out)
            if key not in written and "refusal" not in data["cases"][key] \
                    and "gains" in data["cases"][key]:
                print(f"{key}: nothing rechecked", flush=True)
            elif not written:
                print(f"{key}: the check now passes it and no run is in the file: run "
                      f"python -m bench.every_arm {row} --force --out {args.out}", flush=True)
            for name, case in written.items():
                if name == key:
                    case["grasp_recheck"]["command"] = (
                        f"python -m bench.every_arm --recheck {row} --out {args.out}"
                        + (f" --squeeze {args.squeeze}" if args.squeeze else ""))
                    case["grasp_recheck"]["drake"] = version("drake")
                    case["grasp_recheck"]["cpu"] = _cpu_name()
                write_case(out, name, case)
            print(key, written.get(key, {}).get("gains", {}).get("task_checks", {})
                  .get("grasp", {}).get("message"), flush=True)
        TABLE.write_text(table(json.loads(out.read_text())))
        return 0
    if args.buckling:
        for row in args.rows:
            case = buckling(row, out)
            case["command"] = f"python -m bench.every_arm --buckling {row} --out {args.out}"
            case["drake"], case["cpu"] = version("drake"), _cpu_name()
            write_case(out, f"{row}@buckling", case)
            print(row, json.dumps(case), flush=True)
        return 0
    if not args.table:
        for row in rows:
            key = (row + (f"@sq{args.squeeze}" if args.squeeze else "")
                   + (f"@scale{args.squeeze_scale:g}" if args.squeeze_scale else "")
                   + ("@past" if args.past_refusal else ""))
            done = json.loads(out.read_text())["cases"] if out.exists() else {}
            if key in done and not args.force:
                print(f"{key}: in {out}, skipped (--force runs it again)", flush=True)
                continue
            wall, cpu = time.perf_counter(), time.process_time()
            case = run_row(row, out, args.squeeze, args.past_refusal, args.squeeze_scale)
            case["cpu_seconds_row"] = round(time.process_time() - cpu, 1)
            case["wall_seconds_row"] = round(time.perf_counter() - wall, 1)
            case["command"] = (f"python -m bench.every_arm {row} --out {args.out}"
                               + (f" --squeeze {args.squeeze}" if args.squeeze else "")
                               + (f" --squeeze-scale {args.squeeze_scale:g}"
                                  if args.squeeze_scale else "")
                               + (" --past-refusal" if args.past_refusal else ""))
            case["drake"] = version("drake")
            case["cpu"] = _cpu_name()
            if args.squeeze:
                case["squeeze"] = args.squeeze
            write_case(out, key, case)
            print(key, json.dumps({k: case.get(k) for k in
                                   ("refusal", "verdict", "cpu_seconds_row",
                                    "wall_seconds_row")}), flush=True)
    if out.exists():
        TABLE.write_text(table(json.loads(out.read_text())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
