"""Why the online identification lost under the reference table's Coulomb friction: the
block replayed on the momentum observer's runs of the table's Coulomb column.

``python bench/online_coulomb.py --draws 3 --out docs/results/online_coulomb.json`` runs the
momentum observer's case of each draw of the Coulomb column (the table's own scenario: the
truth plant's friction ``U(0, 1)`` N·m a joint, smoothed as ``tanh(q̇ / 0.01)``; the
controller's model has none), then feeds each robot's logged ``q``, ``q̇̂``, ``τ`` and
reference through :class:`~drake_coop.identification.online.OnlineIdentification` (the
estimate then runs open loop, on the same motion for every variant):

* ``no_friction_prior``: ``coulomb_prior = 0``, the block's default (the friction's prior
  standard deviation ``r|f_c0| = 0``);
* ``friction_prior``: ``coulomb_prior = 0.5`` N·m (the batch identification's floor);
* ``plant_smoothing``: as ``friction_prior``, with the regressor's friction column smoothed as the
  simulated plant's (``v_c = 0.01`` rad/s instead of the identification's 0.02): the share of
  what is left that is the friction's shape, which no controller knows.

Per draw and robot it records the drawn friction, the identified friction, the largest link
mass error (kg) and the circle's RMS of ``λ̂ − λ`` (N) of each variant, and the momentum
observer's own (its model has no friction).

``--merge DIR --out docs/results/reference_table_online_prior.json`` puts the online row's
exact, ±30 % and Coulomb cells of a finished ``drake-coop reference-table --rows online
--columns exact,model_30,coulomb --draws 20 --out DIR`` into a copy of the table's results
file (from its finished cases: a cell of fewer draws says so by its ``n``), the table's own
cells kept under ``replaced``. The committed file's cells were run with the block's
``coulomb_prior`` at 0.5 N·m (its default when they ran; the command line has no switch for
it, the table's online row runs the default 0).
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

VARIANTS = {"no_friction_prior": (0.0, 0.02), "friction_prior": (0.5, 0.02),
            "plant_smoothing": (0.5, 0.01)}


def one_draw(draw: int) -> dict:
    """The momentum observer's case of ``draw`` and the replays of every variant."""
    from drake_coop.control.reference_layout import ReferenceLayout
    from drake_coop.experiment.simulate import simulate
    from drake_coop.identification.online import OnlineIdentification, replay
    from drake_coop.identification.regressor import Regressor, load_structure, true_parameters
    from drake_coop.plant.arms import Arm
    from drake_coop.plant.model_error import controller_arm_model
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.studies.reference_table import expand_table

    case = expand_table(load_scenario(), ["momentum"], ["coulomb"], draw + 1)[draw]
    scenario = load_scenario(data=case.scenario_yaml)
    result = simulate(scenario, t_end=8.0)
    out: dict = {"draw": draw, "status": result.meta["status"], "robots": {}}
    for robot in scenario.robots:
        log = result.logs[robot.name]
        arm = Arm(robot, scenario.task)
        model = controller_arm_model(arm, robot.model_error)
        structure = load_structure(arm.urdf_path, arm.base_frame,
                                   sensor_joint=robot.sensor_joint)
        theta0 = true_parameters(structure, model.plant)
        layout = ReferenceLayout(n=structure.n, m=1)
        circle = log["t"] >= scenario.task.t_circle_start
        truth = np.asarray(robot.model_error.coulomb_friction)
        rms = lambda lam: float(np.sqrt(np.mean((lam[circle] - log["lambda_meas"][circle]) ** 2)))
        entry = {"friction": truth.tolist(), "momentum_estimate": rms(log["lambda_hat"])}
        links = slice(0, 10 * len(structure.links), 10)
        for name, (prior, v_c) in VARIANTS.items():
            block = OnlineIdentification(Regressor(structure, v_c), theta0, model.J_phi, layout,
                                         scenario.control_period, robot.gains.momentum_gain,
                                         coulomb_prior=prior)
            theta, lam = replay(block, log)
            entry[name] = {"friction": theta[structure.joint_slice("coulomb")].tolist(),
                           "mass_error": float(np.max(np.abs(theta[links] - theta0[links]))),
                           "estimate": rms(lam[:, 0])}
        out["robots"][robot.name] = entry
    return out


def summary(draws: list[dict]) -> dict:
    """Medians over draws of the worst robot's circle estimate error, per variant."""
    keys = ["momentum_estimate", *VARIANTS]
    worst = {k: [max(r[k] if k == "momentum_estimate" else r[k]["estimate"]
                     for r in d["robots"].values()) for d in draws] for k in keys}
    return {"estimate_worst": worst,
            "estimate_worst_median": {k: float(np.median(v)) for k, v in worst.items()},
            "mass_error_max": {k: float(max(r[k]["mass_error"] for d in draws
                                            for r in d["robots"].values())) for k in VARIANTS}}


#: The online row's cells run again with the friction prior (``--merge``).
MERGED = ("exact", "model_30", "coulomb")


def merge(folder: Path, table_file: Path, draws: int = 20, before: Path | None = None) -> dict:
    """Replace the online row's :data:`MERGED` cells of ``table_file`` (the reference table's
    results) by the cells of the cases finished in ``folder`` (``drake-coop reference-table
    --rows online --columns exact,model_30,coulomb --draws 20 --out folder``; a cell of fewer
    finished draws says so by its ``n``), keeping each replaced cell under
    ``replaced.online_<column>_before_friction_prior`` and the run's CPU under ``runs``; with
    ``before`` (the store of the earlier block's run), each column's squeeze error paired by
    draw under ``paired.online_<column>``."""
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.studies.reference_table import cell_statistics, expand_table, per_draw
    from drake_coop.studies.store import ResultStore

    records = ResultStore(folder).load()
    table = json.loads(table_file.read_text())
    replaced = table.setdefault("replaced", {})
    cases = expand_table(load_scenario(), ["online"], list(MERGED), draws)
    for col in MERGED:
        done = [records[c.hash] for c in cases
                if c.params["column"] == col and c.hash in records]
        if not done:
            continue
        replaced.setdefault(f"online_{col}_before_friction_prior", table["cells"]["online"][col])
        table["cells"]["online"][col] = cell_statistics(done)
        if before is not None:
            earlier = ResultStore(before).load()
            pairs = [(per_draw(earlier[c.hash])["squeeze"], per_draw(records[c.hash])["squeeze"])
                     for c in cases if c.params["column"] == col and c.hash in records
                     and c.hash in earlier]
            old, new = (np.array(v) for v in zip(*pairs))
            table.setdefault("paired", {})[f"online_{col}"] = {
                "n": len(pairs), "before": old.tolist(), "after": new.tolist(),
                "worse": int(np.sum(new > old)), "largest_increase": float(np.max(new - old)),
                "largest_after": float(np.max(new)), "median_ratio": float(np.median(new / old))}
    distinct = {c.hash for c in cases if c.hash in records}
    table["runs"].append({"log": "online row, friction prior (exact, model_30, coulomb)",
                          "last_progress": f"{len(distinct)} distinct cases finished",
                          "cpu_s": float(sum(records[h].get("cpu_time_s", 0.0)
                                             for h in distinct))})
    table_file.write_text(json.dumps(table, indent=1) + "\n")
    return {col: table["cells"]["online"][col]["squeeze"]["median"] for col in MERGED}


def main() -> None:
    """Run the draws and write the results file (or merge a rerun of the online row)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--draws", type=int, default=3, help="draws of the Coulomb column")
    parser.add_argument("--workers", type=int, default=2, help="parallel processes")
    parser.add_argument("--out", required=True, help="the results file (JSON)")
    parser.add_argument("--merge", default=None, metavar="DIR",
                        help="put the online row's exact, ±30 %% and Coulomb cells of DIR's "
                             "finished cases (20 draws) into --out (the table's results file)")
    parser.add_argument("--before", default=None, metavar="DIR",
                        help="--merge: the earlier block's store, to pair the draws with")
    args = parser.parse_args()
    if args.merge:
        print(json.dumps(merge(Path(args.merge), Path(args.out),
                               before=Path(args.before) if args.before else None)))
        return
    with ProcessPoolExecutor(args.workers) as pool:
        draws = list(pool.map(one_draw, range(args.draws)))
    Path(args.out).write_text(json.dumps({"draws": draws, **summary(draws)}, indent=1) + "\n")
    print(json.dumps(summary(draws)["estimate_worst_median"]))


if __name__ == "__main__":
    main()
