"""The momentum observer when the torque command saturates at the lift: commanded or applied τ.

``python bench/momentum_saturation.py --out DIR [--quantile 0.9] [--t-end 35]`` runs
``scenarios/paper.yaml`` with ``force_source: momentum`` on both robots (plant step 3 ms):

1. without torque limits: each robot's peak ``|τ_cmd|`` per joint in the lift phase and
   outside it;
2. with each joint's torque limit at the ``--quantile`` of its ``|τ_cmd|`` over the lift
   (0.9: the command exceeds it on 10 % of the lift's ticks without limits; a limit at a
   fraction of the peak saturates the whole lift, where the torque is nearly constant, and
   both runs diverge — measured at 0.8 and 0.9 of the peak), but at least 2 % above
   its peak outside the lift (``--outside circle``: above the circle's peak only, so the
   free phase may saturate too), twice: the momentum observer
   integrating the *commanded* torque (what today's experiment diagram builds) and the
   torque actually *applied*, ``clip(τ, −τ_max, τ_max)``
   (:class:`~drake_coop.control.momentum.MomentumObserver` with ``torque_limits``; the
   experiment diagram does not pass it yet, so this script passes it to
   :func:`~drake_coop.control.block.AddCooperativeController` by wrapping that function in
   its own worker process).

Per run: the RMS of λ − λ_d in the lift and circle phases (worst robot), the share of lift
ticks with a saturated joint. Writes ``DIR/momentum_saturation.csv`` and prints a table.
"""

from __future__ import annotations

import argparse
import csv
import json
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TIME_STEP = 0.003


def base_yaml() -> str:
    from drake_coop.scenario.loading import dump_scenario, load_scenario

    s = load_scenario(ROOT / "scenarios" / "paper.yaml")
    s.plant.time_step = TIME_STEP
    for robot in s.robots:
        robot.force_source = "momentum"
    return dump_scenario(s)


def one_run(scenario_yaml: str, t_end: float, applied: bool) -> dict:
    """Run one scenario; with ``applied`` the momentum observers integrate the clipped torque."""
    import functools

    import drake_coop.experiment.diagram as diagram
    from drake_coop.experiment.simulate import simulate
    from drake_coop.results.metrics import compute_metrics, phase_masks
    from drake_coop.scenario.loading import load_scenario

    scenario = load_scenario(data=scenario_yaml)
    if applied:
        limits = {r.name: r.actuators.torque_limits for r in scenario.robots}
        original = diagram.AddCooperativeController

        @functools.wraps(original)
        def with_applied_torque(*args, **kwargs):
            return original(*args, momentum_torque_limits=limits[kwargs["name"]], **kwargs)

        diagram.AddCooperativeController = with_applied_torque
    result = simulate(scenario, t_end=t_end)
    metrics = compute_metrics(result.logs, result.meta)
    out = {"status": result.meta["status"], "message": result.meta.get("message", ""),
           "robots": {}}
    for robot in scenario.robots:
        log = result.logs[robot.name]
        masks = phase_masks(log["t"], result.meta["phases"])
        tau = np.asarray(log["tau_cmd"])
        rec = {p: (metrics[robot.name][p]["force_error"]["rms"] if p in metrics[robot.name]
                   else float("nan")) for p in ("lift", "circle")}
        rec["peak_lift"] = np.max(np.abs(tau[masks["lift"]]), axis=0).tolist()
        rec["lift_quantiles"] = {f"{x:g}": np.quantile(np.abs(tau[masks["lift"]]), x, axis=0
                                                       ).tolist()
                                 for x in (0.5, 0.8, 0.9, 0.95, 0.99)}
        rec["peak_other"] = np.max(np.abs(tau[~masks["lift"]]), axis=0).tolist()
        rec["peak_circle"] = (np.max(np.abs(tau[masks["circle"]]), axis=0).tolist()
                              if np.any(masks.get("circle", [])) else None)
        lim = robot.actuators.torque_limits
        for phase in ("free", "lift", "circle"):
            if not np.any(masks.get(phase, [])):
                rec[f"saturated_{phase}_share"] = float("nan")
                continue
            rec[f"saturated_{phase}_share"] = (
                float(np.mean(np.any(np.abs(tau[masks[phase]]) >= np.asarray(lim), axis=1)))
                if lim is not None else 0.0)
        rec["excess_lift_max"] = (float(np.max(np.abs(tau[masks["lift"]]) - np.asarray(lim)))
                                  if lim is not None else 0.0)
        out["robots"][robot.name] = rec
    return out


def main() -> None:
    from drake_coop.scenario.loading import dump_scenario, load_scenario

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", required=True)
    p.add_argument("--quantile", type=float, default=0.9,
                   help="the torque limit: this quantile of |τ| over the lift (0.5–0.99)")
    p.add_argument("--t-end", type=float, default=35.0)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--outside", choices=("all", "circle"), default="all",
                   help="the phases whose peak the limits stay above")
    p.add_argument("--reuse", action="store_true",
                   help="take the run without limits from DIR/no_limits.json")
    args = p.parse_args()
    if f"{args.quantile:g}" not in ("0.5", "0.8", "0.9", "0.95", "0.99"):
        p.error(f"--quantile must be one of 0.5, 0.8, 0.9, 0.95, 0.99, got {args.quantile:g}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    ctx = multiprocessing.get_context("spawn")
    base = base_yaml()
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=ctx,
                             max_tasks_per_child=1) as pool:
        previous = out / "no_limits.json"
        if args.reuse and previous.exists():
            free = json.loads(previous.read_text())
        else:
            free = pool.submit(one_run, base, args.t_end, False).result()
            previous.write_text(json.dumps(free))
        s = load_scenario(data=base)
        for robot in s.robots:
            r = free["robots"][robot.name]
            robot.actuators.torque_limits = [
                max(a, 1.02 * b) for a, b in zip(r["lift_quantiles"][f"{args.quantile:g}"],
                                                 r["peak_other" if args.outside == "all"
                                                   else "peak_circle"])]
        limited = dump_scenario(s)
        jobs = {k: pool.submit(one_run, limited, args.t_end, k == "applied")
                for k in ("commanded", "applied")}
        runs = {"no limits": free, **{k: j.result() for k, j in jobs.items()}}
    (out / "momentum_saturation.json").write_text(json.dumps(
        {"runs": runs, "torque_limits": {r.name: r.actuators.torque_limits for r in s.robots},
         "quantile": args.quantile, "outside": args.outside, "t_end": args.t_end, "time_step": TIME_STEP}, indent=1))
    with (out / "momentum_saturation.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["case", "robot", "lift_rms", "circle_rms", "saturated_free_share",
                    "saturated_lift_share", "saturated_circle_share", "excess_lift_max",
                    "torque_limits"])
        for case, run in runs.items():
            for name, r in run["robots"].items():
                lim = s.robots[[x.name for x in s.robots].index(name)].actuators.torque_limits
                w.writerow([case, name, f"{r['lift']:.4f}", f"{r['circle']:.4f}",
                            *(f"{r.get(f'saturated_{x}_share', 0.0):.3f}"
                              for x in ("free", "lift", "circle")),
                            f"{r.get('excess_lift_max', 0.0):.3f}",
                            "" if case == "no limits" else " ".join(f"{x:.2f}" for x in lim)])
    print("| case | status | lift RMS r1 / r2 (N) | circle RMS r1 / r2 (N) "
          "| lift ticks saturated r1 / r2 |")
    print("| --- | --- | --- | --- | --- |")
    for case, run in runs.items():
        a, b = run["robots"].values()
        print(f"| {case} | {run['status']} | {a['lift']:.3f} / {b['lift']:.3f} | "
              f"{a['circle']:.3f} / {b['circle']:.3f} | {a['saturated_lift_share']:.2f} / "
              f"{b['saturated_lift_share']:.2f} |")


if __name__ == "__main__":
    main()
