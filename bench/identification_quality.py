"""Identified-model quality against excitation length and encoder resolution.

``python bench/identification_quality.py --out DIR [--durations 2 5 10 20]
[--resolutions 1 0.1] [--t-end 35]`` identifies both robots of ``scenarios/realistic.yaml``
(nominal models 10 % heavy / 10 % light) for each excitation length and each encoder
resolution (a factor on the scenario's ``counts_per_rev``: 1 = 200 000 / 144 000 counts per
joint revolution, 0.1 = ten times coarser), then runs the identified scenario to ``--t-end``.
Per case it records the model torque error on a validation trajectory (identified and
nominal, RMS over the joints, N·m), the forearm composite's first-moment error (%, the part
of the model gravity and the force observer depend on most), the largest Coulomb and viscous
friction errors, and the circle-phase RMS of λ − λ_d (worst robot, N). Writes
``DIR/identification_quality.csv`` and ``.png`` and prints a Markdown table.
"""

from __future__ import annotations

import argparse
import csv
import json
import multiprocessing
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def one_case(duration: float, resolution: float, folder: str, t_end: float) -> dict:
    from drake_coop.identification.report import identified_scenario, identify_robot
    from drake_coop.scenario.loading import dump_scenario, load_scenario
    from drake_coop.studies.sweep import run_one

    scenario = load_scenario(ROOT / "scenarios" / "realistic.yaml")
    for robot in scenario.robots:
        robot.encoders.counts_per_rev = int(round(robot.encoders.counts_per_rev * resolution))
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    idents, rec = {}, {"duration": duration, "resolution": resolution}
    for i in range(len(scenario.robots)):
        ident = identify_robot(scenario, i, duration)
        (out / f"{ident.name}_identified.urdf").write_text(ident.urdf_text)
        idents[i] = ident
        s, th, tr = ident.structure, ident.estimate.theta, ident.theta_true
        k = 10 * (len(s.links) - 1) + 3              # last composite's h_z
        rec[ident.name] = {
            "torque_error_identified": ident.validation["torque_error_rms_identified"],
            "torque_error_nominal": ident.validation["torque_error_rms_nominal"],
            "first_moment_error_pct": 100.0 * (th[k] / tr[k] - 1.0),
            "coulomb_error_max": float(max(abs(th[s.joint_slice("coulomb")]
                                               - tr[s.joint_slice("coulomb")]))),
            "viscous_error_max_pct": float(max(abs(th[s.joint_slice("viscous")]
                                                   / tr[s.joint_slice("viscous")] - 1)) * 100),
        }
    ided = identified_scenario(scenario, idents)
    for robot in ided.robots:
        robot.controller_model = str((out / robot.controller_model).resolve())
    r = run_one(dump_scenario(ided), t_end)
    rec["status"] = r["meta"]["status"]
    rec["squeeze_error"] = (max(m["circle"]["force_error"]["rms"] for m in r["metrics"].values())
                            if rec["status"] == "ok" else float("nan"))
    return rec


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", required=True)
    p.add_argument("--durations", type=float, nargs="+", default=[2.0, 5.0, 10.0, 20.0])
    p.add_argument("--resolutions", type=float, nargs="+", default=[1.0, 0.1])
    p.add_argument("--t-end", type=float, default=35.0)
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=ctx,
                             max_tasks_per_child=1) as pool:
        jobs = [pool.submit(one_case, d, r, str(out / f"d{d:g}_r{r:g}"), args.t_end)
                for r in args.resolutions for d in args.durations]
        recs = [j.result() for j in jobs]
    (out / "identification_quality.json").write_text(json.dumps(recs, indent=1))
    cols = ["duration", "resolution", "squeeze_error"]
    sub = ["torque_error_identified", "torque_error_nominal", "first_moment_error_pct",
           "coulomb_error_max", "viscous_error_max_pct"]
    with (out / "identification_quality.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols + [f"{r}.{c}" for r in ("robot1", "robot2") for c in sub])
        for rec in recs:
            w.writerow([rec[c] for c in cols]
                       + [f"{rec[r][c]:.5g}" for r in ("robot1", "robot2") for c in sub])
    print("| excitation (s) | encoder counts × | model torque error r1 / r2 (N·m) "
          "| first moment error r1 / r2 (%) | squeeze error (N) |")
    print("| --- | --- | --- | --- | --- |")
    for rec in recs:
        a, b = rec["robot1"], rec["robot2"]
        print(f"| {rec['duration']:g} | {rec['resolution']:g} | "
              f"{a['torque_error_identified']:.3f} / {b['torque_error_identified']:.3f} | "
              f"{a['first_moment_error_pct']:+.2f} / {b['first_moment_error_pct']:+.2f} | "
              f"{rec['squeeze_error']:.3f} |")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(8, 3))
    for r in args.resolutions:
        rr = [x for x in recs if x["resolution"] == r]
        d = [x["duration"] for x in rr]
        axes[0].plot(d, [x["robot1"]["torque_error_identified"] for x in rr], "o-",
                     label=f"robot 1, counts × {r:g}")
        axes[0].plot(d, [x["robot2"]["torque_error_identified"] for x in rr], "s--",
                     label=f"robot 2, counts × {r:g}")
        axes[1].plot(d, [x["squeeze_error"] for x in rr], "o-", label=f"counts × {r:g}")
    axes[0].set_ylabel("model torque error [N·m RMS]")
    axes[1].set_ylabel("RMS of λ − λ_d, circle [N]")
    for ax in axes:
        ax.set_xlabel("excitation [s]")
        ax.set_yscale("log")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "identification_quality.png", dpi=80)


if __name__ == "__main__":
    main()
