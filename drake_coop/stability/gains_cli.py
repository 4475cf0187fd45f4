"""``drake-coop gains SCENARIO --out DIR [--force] [--quiet]``: each robot's gains derived from
its controller model at the task's postures and checked with the one-period map
(:mod:`drake_coop.stability.gains`).

``DIR`` receives, whole or not at all (staged in a hidden sibling and renamed into place,
:class:`~drake_coop.results.run_folder.RunFolder`): ``scenario.yaml`` (the scenario with the
derived gains), ``gains.csv`` (one row per robot: every gain, the inertias ``J_j`` and
``h p_f``), ``stability.csv`` (ρ at each operating point, at the gains and with the ``K_R``
margin) and ``run.json`` (all of it, the rules' constants, the task's checks of
:mod:`drake_coop.stability.task_check`, the outcome, and the delay margin with the derived
gains without and with delay compensation, or the line saying why there is none:
:func:`gains_margins`). Exit codes: 0 the gains pass the checks, 1 no gains passed them after
the back-offs, or the task is refused (the torque limits along the path, the grasp's own
dynamics in ``contact`` mode; the outputs are written, a result, and the last line names the check, the
posture and what to change) or the derivation failed (one line, nothing written), 2 bad input
(one line, before
any computation), 130 Ctrl-C, 143 SIGTERM.
"""

from __future__ import annotations

import csv
import io
import json
import sys
import time
from pathlib import Path

__all__ = ["add_gains_parser", "cmd_gains", "gains_margins", "load_for_gains"]


def add_gains_parser(sub) -> None:
    """Register ``gains`` on the ``drake-coop`` subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``drake-coop`` subparsers.
    """
    p = sub.add_parser("gains", help="derive each robot's gains from its model and check them "
                                     "with the stability map")
    p.add_argument("scenario", help="scenario YAML or shipped scenario name")
    p.add_argument("--out", required=True, help="output folder (new, empty, or a previous "
                                                "output of drake-coop)")
    p.add_argument("--force", action="store_true", help="replace a previous output in --out")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=cmd_gains)


def _csv_text(columns: list[str], rows: list[dict]) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buf.getvalue()


def _outputs(scenario, report, wall: float, margins: dict | None = None) -> dict[str, str]:
    """The output files' texts (``margins``: :func:`gains_margins`'s entry)."""
    from drake_coop.scenario.loading import dump_scenario
    from drake_coop.stability import gains as rules

    out_scenario = rules.gains_for_scenario(scenario, report.robots)
    gain_rows = []
    for d in report.robots:
        g = d.gains
        gain_rows.append({"robot": d.name, "n": len(g.K_R),
                          "K_R": " ".join(f"{k:.6g}" for k in g.K_R),
                          "Lambda": g.Lambda, "k_d": g.k_d, "k_F": g.k_F, "xi": g.xi,
                          "zeta": g.zeta, "beta": g.beta, "momentum_gain": g.momentum_gain,
                          "inertia_J": " ".join(f"{j:.6g}" for j in d.inertia),
                          "kappa": d.kappa, "observer_h_pf": d.observer_h_pf,
                          "postures": d.postures})
    rho_rows = [{"point": k.replace("_margin", ""),
                 "K_R_factor": rules.GAIN_MARGIN if k.endswith("_margin") else 1.0,
                 "rho": v, "stable": v < 1.0} for k, v in report.rho.items()]
    meta = {
        "status": "ok" if report.stable else "unstable",
        "message": ("gains derived and checked: rho < 1 at the free and held points, also "
                    f"with K_R x {rules.GAIN_MARGIN}") if report.stable else
                   "no derived gains passed the stability check",
        "command": "gains", "rho": report.rho, "attempts": report.attempts,
        "checked_on_object_mode": report.checked_on, "failed_attempts": report.messages,
        "rules": {"kappa_target": rules.KAPPA, "sigma_h_pf": rules.SIGMA,
                  "force_loop_gain": rules.FORCE_LOOP_GAIN, "posture_step_s": rules.POSTURE_STEP,
                  "gain_margin": rules.GAIN_MARGIN, "backoff": rules.BACKOFF},
        "robots": gain_rows, "wall_time_s": wall,
        "delay_margin": margins,
    }
    meta.update(_task_meta(report))
    return {"scenario.yaml": dump_scenario(out_scenario),
            "gains.csv": _csv_text(list(gain_rows[0]), gain_rows),
            "stability.csv": _csv_text(["point", "K_R_factor", "rho", "stable"], rho_rows),
            "run.json": json.dumps(meta, indent=2, default=float) + "\n"}


def gains_margins(scenario, report) -> dict:
    """The delay margin of the scenario with the derived gains, without and with delay
    compensation (:func:`~drake_coop.stability.margin.delay_margins`), as ``run.json``'s
    ``delay_margin`` entry; when there is none, its ``line`` says why.

    Parameters
    ----------
    scenario : Scenario
        The input scenario.
    report : GainsReport
        :func:`~drake_coop.stability.gains.derive_and_check`'s report.

    Returns
    -------
    dict
        ``without``, ``with``, ``as_configured``, ``robots``, ``line``.
    """
    from drake_coop.stability import gains as rules
    from drake_coop.stability.margin import delay_margins

    if not report.stable:
        return {"line": "no delay margin: no derived gains passed the stability check"}
    try:
        return delay_margins(rules.gains_for_scenario(scenario, report.robots)).as_dict()
    except Exception as exc:            # the map's own failures are rows: anything else
        return {"line": "no delay margin: the stability map could not be built: "
                        f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"}


def _signals_blocked():
    """SIGINT and SIGTERM held back while the outputs are written and renamed into place
    (delivered right after: the folder is then whole, and the command ends as interrupted)."""
    import contextlib
    import signal

    @contextlib.contextmanager
    def blocked():
        signals = {signal.SIGINT, signal.SIGTERM}
        try:
            previous = signal.pthread_sigmask(signal.SIG_BLOCK, signals)
        except (ValueError, OSError):        # not the main thread: nothing to hold back
            yield
            return
        try:
            yield
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, previous)

    return blocked()


def _size_gains(scenario) -> None:
    """Each robot's ``K_R`` sized to its arm's joints: a scenario without gains has the
    schema's 3-entry default, a placeholder may have any length; the derivation replaces the
    values, so a wrong-length list becomes the schema's default value on every joint."""
    from drake_coop.control.params import Gains
    from drake_coop.scenario.model_check import check_models

    default = Gains().K_R[0]
    for robot, n in zip(scenario.robots, check_models(scenario)):
        if len(robot.gains.K_R) != n:
            robot.gains.K_R = [default] * n


def load_for_gains(name_or_path):
    """The scenario ``drake-coop gains`` derives gains for: loaded and validated as ``run``
    loads it, except that each robot's ``K_R`` may be absent or of any length (deriving it is
    the command's job).

    Parameters
    ----------
    name_or_path : str or Path
        A scenario file or a shipped scenario's name.

    Raises
    ------
    ScenarioError
        As :func:`~drake_coop.scenario.loading.load_scenario`: one line naming the field.
    """
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.resources import find_scenario

    return load_scenario(find_scenario(name_or_path), before_validation=_size_gains)


#: A derived ``K_R,j`` below this fraction of the arm's largest is explained in the output.
LIGHT_FRACTION = 0.05


def light_joint_notes(scenario, report) -> list[str]:
    """Why a joint got a gain far below the arm's others: one line per such joint.

    ``K_R,j = κ J_j / h`` follows the least inertia joint ``j`` sees. A wrist that moves only
    its light links gets a small one, and more so when the model has no rotor inertia for
    it: Drake reads a URDF's ``<mechanicalReduction>`` but ignores it (a geared joint's rotor
    reflects its inertia times the reduction squared), so unless the URDF gives
    ``drake:rotor_inertia`` and ``drake:gear_ratio`` the wrist is modelled without its motor.

    Parameters
    ----------
    scenario : Scenario
        The scenario the gains were derived for.
    report : object
        :func:`~drake_coop.stability.gains.derive_and_check`'s report (``robots``: each
        robot's ``name``, ``gains.K_R`` and ``inertia``).

    Returns
    -------
    list of str
        e.g. ``jaco2_1: K_R[6] (j2s6s200_joint_6) = 0.063 N·m·s/rad = κ J/h with J =
        0.000564 kg·m², the least inertia the joint sees: the model has no rotor inertia for
        it (its URDF's mechanicalReduction 160 is ignored by Drake) ...``.
    """
    import xml.etree.ElementTree as ET

    import numpy as np

    from drake_coop.scenario.resources import model_urdf_path

    lines = []
    for i, (robot, d) in enumerate(zip(scenario.robots, report.robots)):
        K = np.asarray(d.gains.K_R, dtype=float)
        light = [j for j in range(K.size) if K[j] < LIGHT_FRACTION * K.max()]
        if not light:
            continue
        path = model_urdf_path(robot, f"robots[{i}].model")
        names, rotor = _actuated_joints(path, robot.base_frame, K.size)
        root = ET.parse(path).getroot()
        reduction = {}
        for transmission in root.findall("transmission"):
            text = transmission.findtext(".//mechanicalReduction")
            for joint in transmission.findall("joint"):
                if text is not None:
                    reduction[joint.get("name")] = text.strip()
        for j in light:
            why = (f"its rotor inertia is {rotor[j]:.3g} kg·m²" if rotor[j] > 0 else
                   "the model has no rotor inertia for it")
            if rotor[j] == 0 and names[j] in reduction:
                why += (f" (its URDF's mechanicalReduction {reduction[names[j]]} is ignored by "
                        "Drake: a geared joint's motor adds its inertia times the reduction "
                        "squared)")
            lines.append(f"{d.name}: K_R[{j + 1}] ({names[j]}) = {K[j]:.2g} N·m·s/rad = κ J/h "
                         f"with J = {d.inertia[j]:.3g} kg·m², the least inertia the joint sees: "
                         f"{why}; give drake:rotor_inertia and drake:gear_ratio in the URDF "
                         "for a geared joint, or check this gain on the real arm")
    return lines


def _actuated_joints(path, base_frame: str, n: int) -> tuple[list[str], list[float]]:
    """The arm's joints in velocity order and each one's rotor inertia (0 without actuator)."""
    import logging

    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    logger = logging.getLogger("drake")
    previous = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        plant = MultibodyPlant(0.0)
        Parser(plant).AddModels(str(path))
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(base_frame))
        plant.Finalize()
    finally:
        logger.setLevel(previous)
    names, rotor = [""] * n, [0.0] * n
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        if joint.num_velocities() == 1 and joint.velocity_start() < n:
            names[joint.velocity_start()] = joint.name()
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        k = actuator.joint().velocity_start()
        if k < n:
            rotor[k] = float(actuator.default_rotor_inertia()
                             * actuator.default_gear_ratio() ** 2)
    return names, rotor


def cmd_gains(args) -> int:
    """Derive, check, write (see the module docstring for the exit codes).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The process's exit code, as the module's docstring lists them.
    """
    from drake_coop.console import error as _error
    from drake_coop.results.run_folder import OutputFolderError, RunFolder
    from drake_coop.scenario.schema import ScenarioError

    try:
        scenario = load_for_gains(args.scenario)
    except (ScenarioError, OSError, ValueError) as exc:
        return _error(str(exc))
    folder = RunFolder(args.out)
    try:
        staging = folder.prepare(ticks=0, robots=len(scenario.robots), replace=args.force)
    except OutputFolderError as exc:
        return _error(str(exc))
    try:
        from drake_coop.stability.gains import derive_and_check

        start = time.perf_counter()

        def progress(message: str) -> None:
            if not args.quiet:
                print(f"[{time.perf_counter() - start:6.1f} s] {message}", file=sys.stderr,
                      flush=True)

        try:
            report = derive_and_check(scenario, progress=progress)
        except ScenarioError as exc:          # what the map refuses: bad input
            folder.discard()
            return _error(str(exc))
        except Exception as exc:              # the derivation or the map failed: no output
            folder.discard()
            print(f"drake-coop: gains failed: {type(exc).__name__}: "
                  f"{' '.join(str(exc).split())[:300]}", file=sys.stderr)
            return 1
        progress("the delay margin with the derived gains, without and with compensation")
        margins = gains_margins(scenario, report)
        texts = _outputs(scenario, report, time.perf_counter() - start, margins)
        with _signals_blocked():
            for name, text in texts.items():
                (staging / name).write_text(text, encoding="utf-8")
            folder.commit()
    except BaseException:
        folder.discard()
        raise
    if not args.quiet:
        for d in report.robots:
            print(f"{d.name}: K_R {[round(k, 1) for k in d.gains.K_R]}, Lambda "
                  f"{d.gains.Lambda:.3g}, k_d {d.gains.k_d:.3g}, xi {d.gains.xi:.3g}",
                  file=sys.stderr)
        print(margins["line"], file=sys.stderr)
        for line in light_joint_notes(scenario, report):
            print(line, file=sys.stderr)
        print(f"rho: {', '.join(f'{k} {v:.6g}' for k, v in report.rho.items())}; "
              f"wrote {args.out}", file=sys.stderr)
    if report.refusal:
        print(_refusal_line(report), file=sys.stderr)
    return 0 if report.stable else 1


def _task_meta(report) -> dict:
    """``run.json``'s task part: every task check (:mod:`drake_coop.stability.task_check`)
    and the refusal; the status ``refused`` when a task check failed."""
    task = getattr(report, "task", None)
    out: dict = {"refusal": getattr(report, "refusal", "")}
    if task is None:
        return out
    out["task_checks"] = [{"name": c.name, "passes": c.passes, "message": c.message,
                           "values": c.values} for c in task.checks]
    if not task.passes:
        out["status"] = "refused"
        out["message"] = task.refusal
    return out


def _refusal_line(report) -> str:
    """The one line a refused derivation ends with."""
    return f"drake-coop: gains: refused: {report.refusal}"
