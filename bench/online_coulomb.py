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

``--cells DIR --before TABLE --out docs/results/reference_table_online_prior.json`` writes
the cells of the table's optional row ``online_prior`` (the online block with
``coulomb_prior`` = 0.5 N·m) from a finished ``drake-coop reference-table --rows online_prior
--columns exact,model_30,coulomb --draws 20 --out DIR``, each column's squeeze error paired
by draw with the online row's (the block's default) in the table's folder ``TABLE``.
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


#: The columns of the optional row ``online_prior`` this file's ``--cells`` reads.
PRIOR_COLUMNS = ("exact", "model_30", "coulomb")


def prior_cells(folder: Path, before: Path, out: Path, draws: int = 20) -> dict:
    """The optional row ``online_prior``'s cells (the online block with ``coulomb_prior`` =
    0.5 N·m) of the finished cases in ``folder`` (``drake-coop reference-table --rows
    online_prior --columns exact,model_30,coulomb --draws 20 --out folder``; a cell of fewer
    finished draws says so by its ``n``), each column's squeeze error paired by draw with
    the online row's case of the same draw in ``before`` (the table's folder: the block's
    default, ``coulomb_prior`` = 0), written to ``out`` with the CPU of the distinct cases."""
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.studies.reference_table import cell_statistics, expand_table, per_draw
    from drake_coop.studies.store import ResultStore

    records, earlier = ResultStore(folder).load(), ResultStore(before).load()
    cols = list(PRIOR_COLUMNS)
    cases = {row: expand_table(load_scenario(), [row], cols, draws)
             for row in ("online_prior", "online")}
    cells, paired = {}, {}
    for col in cols:
        mine = [(a, b) for a, b in zip(cases["online_prior"], cases["online"])
                if a.params["column"] == col and a.hash in records]
        if not mine:
            continue
        cells[col] = cell_statistics([records[a.hash] for a, _ in mine])
        pairs = [(per_draw(earlier[b.hash])["squeeze"], per_draw(records[a.hash])["squeeze"])
                 for a, b in mine if b.hash in earlier]
        if pairs:
            old, new = (np.array(v) for v in zip(*pairs))
            paired[col] = {"n": len(pairs), "before": old.tolist(), "after": new.tolist(),
                           "worse": int(np.sum(new > old)),
                           "largest_increase": float(np.max(new - old)),
                           "largest_after": float(np.max(new)),
                           "median_ratio": float(np.median(new / old))}
    distinct = {a.hash for a in cases["online_prior"] if a.hash in records}
    table = {"command": "drake-coop reference-table --rows online_prior --columns "
                        f"{','.join(cols)} --draws {draws}",
             "rows": ["online_prior"], "columns": cols, "cells": {"online_prior": cells},
             "draws": draws, "cases": len(cases["online_prior"]),
             "distinct_cases": len({a.hash for a in cases["online_prior"]}),
             "distinct_finished": len(distinct),
             "cpu_s": float(sum(records[h].get("cpu_time_s", 0.0) for h in distinct)),
             "paired": paired}
    out.write_text(json.dumps(table, indent=1) + "\n")
    return {col: cell["squeeze"]["median"] for col, cell in cells.items()}


def main() -> None:
    """Run the draws and write the results file (or the online_prior row's cells, ``--cells``)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--draws", type=int, default=3, help="draws of the Coulomb column")
    parser.add_argument("--workers", type=int, default=2, help="parallel processes")
    parser.add_argument("--out", required=True, help="the results file (JSON)")
    parser.add_argument("--cells", default=None, metavar="DIR",
                        help="write the online_prior row's exact, ±30 %% and Coulomb cells of "
                             "DIR's finished cases (20 draws) to --out instead")
    parser.add_argument("--before", default=None, metavar="DIR",
                        help="--cells: the table's folder, its online row paired by draw")
    args = parser.parse_args()
    if args.cells:
        if not args.before:
            parser.error("--before: needed with --cells (the table's folder)")
        print(json.dumps(prior_cells(Path(args.cells), Path(args.before), Path(args.out))))
        return
    with ProcessPoolExecutor(args.workers) as pool:
        draws = list(pool.map(one_draw, range(args.draws)))
    Path(args.out).write_text(json.dumps({"draws": draws, **summary(draws)}, indent=1) + "\n")
    print(json.dumps(summary(draws)["estimate_worst_median"]))


if __name__ == "__main__":
    main()
