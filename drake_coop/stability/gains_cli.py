"""``drake-coop gains SCENARIO --out DIR [--force] [--quiet]``: each robot's gains derived from
its controller model at the task's postures and checked with the one-period map
(:mod:`drake_coop.stability.gains`).

``DIR`` receives, whole or not at all (staged in a hidden sibling and renamed into place,
:class:`~drake_coop.results.run_folder.RunFolder`): ``scenario.yaml`` (the scenario with the
derived gains), ``gains.csv`` (one row per robot: every gain, the inertias ``J_j`` and
``h p_f``), ``stability.csv`` (ρ at each operating point, at the gains and with the ``K_R``
margin) and ``run.json`` (all of it, the rules' constants, the task's checks of
:mod:`drake_coop.stability.task_check` and the outcome). Exit codes: 0 the gains pass the
checks, 1 no gains passed them after the back-offs, or the task is refused (the torque
limits along the path, the grasp's buckling under the squeeze; the outputs are written, a
result, and the last line names the check, the posture and what to change) or the derivation failed (one line, nothing written), 2 bad input (one line, before
any computation), 130 Ctrl-C, 143 SIGTERM.
"""

from __future__ import annotations

import csv
import io
import json
import sys
import time
from pathlib import Path

__all__ = ["add_gains_parser", "cmd_gains", "load_for_gains"]


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


def _outputs(scenario, report, wall: float) -> dict[str, str]:
    """The output files' texts."""
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
    }
    meta.update(_task_meta(report))
    return {"scenario.yaml": dump_scenario(out_scenario),
            "gains.csv": _csv_text(list(gain_rows[0]), gain_rows),
            "stability.csv": _csv_text(["point", "K_R_factor", "rho", "stable"], rho_rows),
            "run.json": json.dumps(meta, indent=2, default=float) + "\n"}


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

    Returns
    -------
    Scenario
        The scenario.

    Raises
    ------
    ScenarioError
        As :func:`~drake_coop.scenario.loading.load_scenario`: one line naming the field.
    """
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.scenario.resources import find_scenario

    return load_scenario(find_scenario(name_or_path), before_validation=_size_gains)


def cmd_gains(args) -> int:
    """Derive, check, write (see the module docstring for the exit codes).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Returns
    -------
    int
        The exit code.
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
        texts = _outputs(scenario, report, time.perf_counter() - start)
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
