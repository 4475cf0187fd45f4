"""Study 5's model-mismatch draws with every force source, identified models included.

``python bench/identified_sources.py --draws 12 --out DIR`` takes the first ``--draws``
samples of ``studies/model_mismatch.yaml`` (the same draws as study 5: seed 2026, ±30 %
masses, inertias and damping of each controller model, unknown Coulomb friction up to
1 N·m per joint; the study's ``t_end`` and plant step: 65 s and the scenario's 1 ms since the
studies run the whole circle, 35 s and 3 ms when the results shipped in
``docs/figures/studies/identified_sources*`` were made) and runs each draw with six force sources,
both robots switched together, so that every comparison is paired:

* ``observer`` / ``momentum`` with the draw's nominal (wrong) controller model;
* ``observer+id`` / ``momentum+id`` with the model that ``drake-coop identify`` finds for
  this draw's arms (10 s of excitation per arm; the identification sees the draw's Coulomb
  friction, which stays in the simulated plant);
* ``sensor`` (the wrist F/T sensor model) and ``none`` with the nominal model.

``--published`` takes the draws instead from the published study 5 results
(``docs/figures/studies/model_mismatch_results.csv``: the first ``--draws`` samples, their
mass, inertia and damping scales and their Coulomb friction per joint, on the paper's
scenario with the study's plant step and ``t_end``). The two differ: today's expansion of the
study file draws no Coulomb friction (the base scenario's ``coulomb_friction`` lists are
empty, so ``robots.*.model_error.coulomb_friction.*`` matches nothing), and from the second
sample on its other draws differ too (the random stream no longer interleaves the Coulomb
draws), while the published run did draw Coulomb friction.

Each identification and each run is a fresh process (two at a time). Every finished run is
appended to ``DIR/runs.jsonl`` (so an interrupted study keeps what it ran);
``--summarize`` rereads it and writes ``DIR/identified_sources.csv`` (one row per draw and
source: the circle phase's RMS of λ − λ_d, worst robot) and ``identified_sources.png``, and
prints the table of median / 90 % / max per source.
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
SOURCES = ("observer", "observer+id", "momentum", "momentum+id", "sensor", "none")


def identify_draw(scenario_yaml: str, folder: str, duration: float,
                  estimator: str = "map_sdp") -> str:
    """Identify both robots of one draw; the identified scenario's YAML (absolute URDFs)."""
    from drake_coop.identification.report import identified_scenario, identify_robot
    from drake_coop.scenario.loading import dump_scenario, load_scenario

    scenario = load_scenario(data=scenario_yaml)
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    idents = {}
    for i in range(len(scenario.robots)):
        ident = identify_robot(scenario, i, duration, estimator=estimator)
        (out / f"{ident.name}_identified.urdf").write_text(ident.urdf_text)
        idents[i] = ident
    ided = identified_scenario(scenario, idents)
    for robot in ided.robots:
        robot.controller_model = str((out / robot.controller_model).resolve())
    errors = {ident.name: dict(ident.validation, **parameter_errors(ident))
              for ident in idents.values()}
    (out / "validation.json").write_text(json.dumps(errors, indent=1))
    return dump_scenario(ided)


def parameter_errors(ident) -> dict:
    """The forearm composite's first-moment error (%), the largest Coulomb (N·m) and viscous
    (%) friction errors, and the identifiable parameters' error: the RMS over the validation
    trajectory's torque is ``torque_error_rms_identified``."""
    s, th, tr = ident.structure, ident.estimate.theta, ident.theta_true
    k = 10 * (len(s.links) - 1) + 3                   # last composite's h_z
    c, v = s.joint_slice("coulomb"), s.joint_slice("viscous")
    return {"first_moment_error_pct": float(100.0 * (th[k] / tr[k] - 1.0)),
            "coulomb_error_max": float(max(abs(th[c] - tr[c]))),
            "viscous_error_max_pct": float(100.0 * max(abs(th[v] / tr[v] - 1.0))),
            "coulomb_identified": th[c].tolist(), "coulomb_true": tr[c].tolist()}


def identify_and_run(scenario_yaml: str, folder: str, duration: float, estimator: str,
                     t_end: float, run: bool) -> dict:
    """One budget case: identify both arms of a draw with ``estimator`` from ``duration`` s of
    excitation, then (``run``) run the draw with the identified models and observer (22)."""
    import time

    from drake_coop.studies.sweep import run_one

    t0 = time.process_time()
    ided = identify_draw(scenario_yaml, folder, duration, estimator)
    rec = {"identify_cpu_s": time.process_time() - t0,
           "robots": json.loads((Path(folder) / "validation.json").read_text())}
    if run:
        r = run_one(variant(ided, "observer"), t_end)
        rec["status"] = r["meta"]["status"]
        rec["squeeze_error"] = (squeeze_error(r["metrics"]) if rec["status"] == "ok"
                                else float("nan"))
    return rec


def run_with_coulomb(scenario_yaml: str, coulomb: dict, t_end: float) -> dict:
    """Run a scenario whose controller models compensate Coulomb friction ``coulomb[name]``
    (:class:`~drake_coop.control.arm_model.ArmModel`'s ``coulomb``, smoothed as
    ``tanh(q̇ / 0.02)`` like the identification's column: in (13), (22) and the momentum
    observer). The experiment diagram has no scenario field for it yet: this wraps its
    ``controller_arm_model`` in this worker process."""
    import functools

    import drake_coop.experiment.diagram as diagram
    from drake_coop.studies.sweep import run_one

    original = diagram.controller_arm_model

    @functools.wraps(original)
    def with_coulomb(arm, error=None):
        model = original(arm, error)
        model.coulomb = np.asarray(coulomb[arm.name], float)
        model.coulomb_velocity = 0.02
        return model

    diagram.controller_arm_model = with_coulomb
    r = run_one(scenario_yaml, t_end)
    return {"status": r["meta"]["status"],
            "squeeze_error": (squeeze_error(r["metrics"]) if r["meta"]["status"] == "ok"
                              else float("nan"))}


def friction(args) -> None:
    """``--friction``: rerun the identified runs of ``budgets.jsonl`` (``--estimators``,
    ``--durations``) with the identified Coulomb friction compensated; appended to
    ``DIR/friction.jsonl`` and printed against the same runs without compensation."""
    from drake_coop.scenario.loading import dump_scenario, load_scenario

    out = Path(args.out)
    recs = [json.loads(x) for x in (out / "budgets.jsonl").read_text().splitlines()]
    recs = [r for r in recs if r["estimator"] in args.estimators
            and r["duration"] in args.durations and "squeeze_error" in r
            and all("coulomb_identified" in v for v in r["robots"].values())][: args.draws]
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=ctx,
                             max_tasks_per_child=1) as pool:
        jobs = []
        for r in recs:
            folder = out / f"draw{r['draw']:03d}_{r['estimator']}_{r['duration']:g}s"
            cases = {k: y for k, y, _ in published_cases(r["draw"] + 1)}
            ided = load_scenario(data=with_plant_step(cases[r["draw"]], PUBLISHED_TIME_STEP))
            for robot in ided.robots:
                robot.controller_model = str((folder / f"{robot.name}_identified.urdf").resolve())
                robot.model_error.mass_scale = robot.model_error.inertia_scale = 1.0
                robot.model_error.damping_scale = 1.0
                robot.force_source = "observer"
            coulomb = {name: v["coulomb_identified"] for name, v in r["robots"].items()}
            jobs.append((r, pool.submit(run_with_coulomb, dump_scenario(ided), coulomb,
                                        PUBLISHED_T_END)))
        for r, job in jobs:
            rec = {"draw": r["draw"], "estimator": r["estimator"], "duration": r["duration"],
                   "squeeze_error_uncompensated": r["squeeze_error"], **job.result()}
            with (out / "friction.jsonl").open("a") as f:
                f.write(json.dumps(rec) + "\n")
            print(rec, flush=True)
    rows = [json.loads(x) for x in (out / "friction.jsonl").read_text().splitlines()]
    with (out / "identification_friction.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["draw", "estimator", "excitation_s", "squeeze_error_uncompensated",
                    "squeeze_error_coulomb_compensated"])
        for r in rows:
            w.writerow([r["draw"], r["estimator"], f"{r['duration']:g}",
                        f"{r['squeeze_error_uncompensated']:.4f}",
                        f"{r['squeeze_error']:.4f}"])


def budgets(args) -> None:
    """The data-budget comparison of the estimators on the published draws (``--budgets``).

    Per draw, estimator and excitation length: the validation torque error and first-moment
    error of each arm and, for the lengths in ``--run-durations``, the squeeze error of the
    run with the identified models (observer (22)). Appended to ``DIR/budgets.jsonl``;
    ``DIR/identification_budgets.csv`` rewritten from it at the end."""
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    log = out / "budgets.jsonl"
    done = set()
    if log.exists():
        for line in log.read_text().splitlines():
            r = json.loads(line)
            done.add((r["draw"], r["estimator"], r["duration"]))
    cases = [(k, with_plant_step(base, PUBLISHED_TIME_STEP), params)
             for k, base, params in published_cases(args.draws)]
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=ctx,
                             max_tasks_per_child=1) as pool:
        jobs = {}
        for d in args.durations:
            for k, base, params in cases:
                for est in args.estimators:
                    if (k, est, d) in done:
                        continue
                    jobs[(k, est, d)] = pool.submit(
                        identify_and_run, base, str(out / f"draw{k:03d}_{est}_{d:g}s"), d, est,
                        PUBLISHED_T_END, d in args.run_durations)
        for (k, est, d), job in jobs.items():
            rec = {"draw": k, "estimator": est, "duration": d, **job.result()}
            with log.open("a") as f:
                f.write(json.dumps(rec) + "\n")
            print(k, est, d, rec.get("squeeze_error"),
                  {r: round(v["torque_error_rms_identified"], 4)
                   for r, v in rec["robots"].items()}, flush=True)
    write_budget_table(out)


def write_budget_table(out: Path) -> None:
    """``identification_budgets.csv`` (one row per draw, estimator and length) and the
    summary per estimator and length (median over the draws) printed as Markdown."""
    recs = [json.loads(x) for x in (out / "budgets.jsonl").read_text().splitlines()]
    recs.sort(key=lambda r: (r["duration"], r["estimator"], r["draw"]))
    robots = sorted(recs[0]["robots"])
    cols = ["torque_error_rms_identified", "torque_error_rms_nominal", "first_moment_error_pct",
            "coulomb_error_max", "viscous_error_max_pct"]
    with (out / "identification_budgets.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["draw", "estimator", "excitation_s", "squeeze_error", "identify_cpu_s"]
                   + [f"{r}.{c}" for r in robots for c in cols])
        for r in recs:
            w.writerow([r["draw"], r["estimator"], f"{r['duration']:g}",
                        f"{r.get('squeeze_error', float('nan')):.4f}",
                        f"{r['identify_cpu_s']:.1f}"]
                       + [f"{r['robots'][x][c]:.5g}" for x in robots for c in cols])
    print("| excitation (s) | estimator | draws | model torque error, worst arm, median (N·m) "
          "| first-moment error, worst arm, median (%) | squeeze error median / max (N) |")
    print("| --- | --- | --- | --- | --- | --- |")
    for d in sorted({r["duration"] for r in recs}):
        for est in sorted({r["estimator"] for r in recs}):
            rr = [r for r in recs if r["duration"] == d and r["estimator"] == est]
            if not rr:
                continue
            te = [max(v["torque_error_rms_identified"] for v in r["robots"].values()) for r in rr]
            fm = [max(abs(v["first_moment_error_pct"]) for v in r["robots"].values()) for r in rr]
            sq = [r["squeeze_error"] for r in rr if "squeeze_error" in r]
            sq_text = (f"{np.nanmedian(sq):.3f} / {np.nanmax(sq):.3f}" if sq else "not run")
            print(f"| {d:g} | {est} | {len(rr)} | {np.median(te):.4f} | {np.median(fm):.2f} "
                  f"| {sq_text} |")


#: ``t_end`` (s) and plant step (s) of the runs that made ``identified_sources_published.csv``
#: (the 0.50 N median of the identified models): the budgets use the same.
PUBLISHED_T_END = 35.0
PUBLISHED_TIME_STEP = 0.003


def with_plant_step(scenario_yaml: str, time_step: float) -> str:
    from drake_coop.scenario.loading import dump_scenario, load_scenario

    s = load_scenario(data=scenario_yaml)
    s.plant.time_step = time_step
    return dump_scenario(s)


def published_cases(n: int) -> list[tuple[int, str, dict]]:
    """``(sample, scenario_yaml, params)`` of the first ``n`` published study 5 samples."""
    from drake_coop.scenario.loading import dump_scenario, load_scenario

    out = []
    with (ROOT / "docs" / "figures" / "studies" / "model_mismatch_results.csv").open() as f:
        rows = list(csv.DictReader(f))[:n]
    for row in rows:
        s = load_scenario(ROOT / "scenarios" / "paper.yaml")
        if row.get("plant.time_step"):           # swept in the 3 ms study, else the scenario's
            s.plant.time_step = float(row["plant.time_step"])
        params = {}
        for i, robot in enumerate(s.robots):
            e = robot.model_error
            for name in ("mass_scale", "inertia_scale", "damping_scale"):
                key = f"robots.{i}.model_error.{name}"
                setattr(e, name, float(row[key]))
                params[key] = float(row[key])
            e.coulomb_friction = [float(row[f"robots.{i}.model_error.coulomb_friction.{j}"])
                                  for j in range(3)]
            params[f"robots.{i}.model_error.coulomb_friction"] = e.coulomb_friction
        params["published_worst_force_error_rms"] = float(row["worst.force_error.rms"])
        out.append((int(row["sample"]), dump_scenario(s), params))
    return out


def variant(scenario_yaml: str, source: str) -> str:
    from drake_coop.scenario.loading import dump_scenario, load_scenario

    s = load_scenario(data=scenario_yaml)
    for robot in s.robots:
        robot.force_source = source.split("+")[0]
    return dump_scenario(s)


def squeeze_error(metrics: dict) -> float:
    """The worst robot's circle-phase RMS of λ − λ_d (N)."""
    return max(m["circle"]["force_error"]["rms"] for m in metrics.values() if "circle" in m)


def run(args) -> None:
    from drake_coop.studies.expand import expand
    from drake_coop.studies.spec import load_study
    from drake_coop.studies.sweep import run_one

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    study = load_study(ROOT / "studies" / "model_mismatch.yaml")
    cases = (published_cases(args.draws) if args.published else
             [(c.index, c.scenario_yaml, c.params) for c in expand(study)[: args.draws]])
    done = set()
    log = out / "runs.jsonl"
    if log.exists():
        for line in log.read_text().splitlines():
            r = json.loads(line)
            done.add((r["draw"], r["source"]))
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=args.workers, mp_context=ctx,
                             max_tasks_per_child=1) as pool:
        for k, base, params in cases:
            if all((k, s) in done for s in SOURCES):
                continue
            ided = pool.submit(identify_draw, base, str(out / f"draw{k:03d}"),
                               args.duration).result()
            jobs = {s: pool.submit(run_one, variant(ided if s.endswith("+id") else base, s),
                                   study.t_end) for s in SOURCES if (k, s) not in done}
            for s, job in jobs.items():
                r = job.result()
                rec = {"draw": k, "source": s, "status": r["meta"]["status"],
                       "squeeze_error": (squeeze_error(r["metrics"])
                                         if r["meta"]["status"] == "ok" else float("nan")),
                       "params": params}
                with log.open("a") as f:
                    f.write(json.dumps(rec) + "\n")
                print(k, s, rec["status"], f"{rec['squeeze_error']:.3f}", flush=True)


def summarize(args) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(args.out)
    recs = [json.loads(x) for x in (out / "runs.jsonl").read_text().splitlines()]
    draws = sorted({r["draw"] for r in recs
                    if all(any(q["draw"] == r["draw"] and q["source"] == s for q in recs)
                           for s in SOURCES)})
    table = {s: np.array([next(q["squeeze_error"] for q in recs
                               if q["draw"] == d and q["source"] == s) for d in draws])
             for s in SOURCES}
    with (out / "identified_sources.csv").open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["draw", *SOURCES])
        for i, d in enumerate(draws):
            w.writerow([d, *(f"{table[s][i]:.4f}" for s in SOURCES)])
    print(f"{len(draws)} paired draws; circle-phase RMS of λ − λ_d, worst robot (N)")
    print("| force source | median | 90 % | max |")
    print("| --- | --- | --- | --- |")
    for s in SOURCES:
        v = table[s]
        print(f"| {s} | {np.nanmedian(v):.2f} | {np.nanpercentile(v, 90):.2f} | "
              f"{np.nanmax(v):.2f} |")
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.boxplot([table[s] for s in SOURCES], whis=(0, 100))
    ax.set_xticks(range(1, len(SOURCES) + 1), SOURCES)
    ax.set_yscale("log")
    ax.set_ylabel("RMS of λ − λ_d, circle [N]")
    ax.set_title(f"±30 % model error, {len(draws)} paired draws of study 5"
                 + (" (published, Coulomb friction)" if args.published else ""))
    fig.tight_layout()
    fig.savefig(out / "identified_sources.png", dpi=80)
    plt.close(fig)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", required=True)
    p.add_argument("--draws", type=int, default=12)
    p.add_argument("--duration", type=float, default=10.0, help="excitation length (s)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--published", action="store_true",
                   help="the published study 5 draws (with their Coulomb friction)")
    p.add_argument("--summarize", action="store_true")
    p.add_argument("--budgets", action="store_true",
                   help="compare the estimators over excitation lengths (published draws)")
    p.add_argument("--friction", action="store_true",
                   help="rerun --budgets' identified runs with Coulomb compensation")
    p.add_argument("--estimators", nargs="+", default=["map_sdp", "didim"])
    p.add_argument("--durations", type=float, nargs="+", default=[2.0, 5.0, 10.0, 60.0])
    p.add_argument("--run-durations", type=float, nargs="*", default=[2.0, 5.0, 10.0],
                   help="excitation lengths whose identified models are also run")
    args = p.parse_args()
    if args.friction:
        friction(args)
    elif args.budgets:
        budgets(args)
    elif args.summarize:
        summarize(args)
    else:
        run(args)


if __name__ == "__main__":
    main()
