"""Two claims of the reference table measured on its short segment (8 s unless said).

``python bench/reference_table_claims.py --out docs/results/reference_table_claims.json
[--draws 6] [--parts saturation,online]``

* ``saturation`` — the applied-torque residual under torque saturation. On the short segment
  the table's saturation column does not saturate (the approach to the grasp commands as much
  as the lift; limits below it end the grasp: measured here too), so the run limits robot 1's
  elbow at ``--elbow-limit`` N·m (its lift peak is 11.7 N·m, its approach's 11.8): saturated
  on the approach and the lift, not after. Exact model, one deterministic run each: the
  momentum observer without limits, with limits (integrating the commanded torque), and the
  applied-torque residual with limits (the clipped torque). The claim: the residual's circle
  squeeze error within 10 % of the unsaturated momentum observer's. Also each joint limit of
  robot 1 at 0.98 × its lift peak (the shoulder too): whether any source survives it.
* ``online`` — the online identification after 10 s of the task against the batch
  identification. Draws of the table's ±30 % column (the same generator); per draw, to
  13 s: the online row, and the momentum observer on each arm's MAP-SDP model identified
  from 10 s of excitation (the table's ``id_map_sdp_10s`` column). The number: the RMS of
  ``λ − λ_d``, worst robot, over 10–13 s (the circle after 10 s of the task), read from the
  logs; the claim: the online row's median within 2× the batch identification's.
* ``online_exact`` — the online row and the momentum observer with the exact model, the same
  window (not in the default parts).

Process CPU seconds of each part are written with its numbers. ``--online-log LOG`` writes
the online part from the draws a stopped run printed (its CPU seconds are then not known).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from drake_coop.experiment.simulate import simulate
from drake_coop.scenario.loading import dump_scenario, load_scenario
from drake_coop.studies.reference_table import ALL_COLUMNS, _model_30, _source, compress
from drake_coop.studies.reference_variants import variant_built

WINDOW = (10.0, 13.0)


def rms(scenario, variant, t_end: float, window: tuple[float, float]) -> dict:
    """Worst-robot RMS of λ − λ_d over ``window`` and over the lift, saturated ticks."""
    with variant_built(scenario, variant):
        result = simulate(scenario, t_end=t_end)
    out = {"status": result.meta["status"], "message": result.meta["message"]}
    if not result.ok:
        return out
    squeeze, lift, saturated = [], [], 0
    t0, t1 = scenario.task.t_grasp, scenario.task.t_circle_start
    for log in result.logs.values():
        t, e = log["t"], log["lambda_meas"] - log["lambda_d"]
        w = (t >= window[0] - 1e-9) & (t < window[1] + 1e-9)
        squeeze.append(float(np.sqrt(np.mean(e[w] ** 2))))
        lift.append(float(np.sqrt(np.mean(e[(t >= t0) & (t < t1)] ** 2))))
        saturated += int(np.any(np.abs(log["tau_cmd"] - log["tau"]) > 1e-12, axis=1).sum())
    return {**out, "squeeze": max(squeeze), "squeeze_lift": max(lift),
            "saturated_ticks": saturated}


def saturation(elbow_limit: float) -> dict:
    """The three runs with robot 1's elbow limited, and the all-joints 0.98 × lift peak runs."""
    def case(row, limits):
        s = compress(load_scenario())
        _source(row)(s, 0)
        s.robots[0].actuators.torque_limits = limits
        return s

    window = (5.0, 8.0)
    limits = [100.0, 100.0, elbow_limit]
    out = {"elbow_limit": elbow_limit, "window": list(window),
           "unsaturated": rms(case("momentum", None), None, 8.0, window),
           "momentum_commanded": rms(case("momentum", limits), None, 8.0, window),
           "residual_applied": rms(case("momentum", limits), "applied_torque", 8.0, window)}
    base = out["unsaturated"]["squeeze"]
    out["residual_over_unsaturated"] = out["residual_applied"]["squeeze"] / base
    out["momentum_over_unsaturated"] = out["momentum_commanded"]["squeeze"] / base
    out["residual_lift_over_unsaturated"] = (out["residual_applied"]["squeeze_lift"]
                                             / out["unsaturated"]["squeeze_lift"])
    out["momentum_lift_over_unsaturated"] = (out["momentum_commanded"]["squeeze_lift"]
                                             / out["unsaturated"]["squeeze_lift"])
    shoulder = [0.05, 0.98 * 23.81, 0.98 * 11.69]          # 0.98 × each lift peak (robot 1)
    out["all_joints_0p98"] = {
        "limits": shoulder,
        "momentum": rms(case("momentum", shoulder), "applied_torque", 8.0, window)}
    return out


def online(draws: int, seed: int = 1) -> dict:
    """Per draw of the ±30 % column: the online row and the batch-identified momentum row."""
    from drake_coop.studies.reference_engine import identify_task

    k = list(ALL_COLUMNS).index("model_30")
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for draw in range(draws):
            s = compress(load_scenario())
            _model_30(s, np.random.default_rng([seed, k, draw]), draw)
            _source("momentum")(s, draw)
            models = identify_task(dump_scenario(s), f"{folder}/{draw}", "map_sdp", 10.0, draw)
            if "error" in models:
                rows.append({"draw": draw, "identification": models["error"]})
                continue
            batch = load_scenario(data=dump_scenario(s))
            for robot in batch.robots:
                robot.controller_model = models[robot.name]
                e = robot.model_error
                e.mass_scale = e.inertia_scale = e.damping_scale = 1.0
            rows.append({"draw": draw,
                         "scales": [[r.model_error.mass_scale, r.model_error.inertia_scale,
                                     r.model_error.damping_scale] for r in s.robots],
                         "online": rms(s, "online", WINDOW[1], WINDOW),
                         "nominal": rms(s, None, WINDOW[1], WINDOW),
                         "batch_map_sdp_10s": rms(load_scenario(data=dump_scenario(batch)),
                                                  None, WINDOW[1], WINDOW)})
            print(json.dumps(rows[-1]), flush=True)
    return summarize(rows)


def online_exact() -> dict:
    """The online row and the momentum observer with the exact model (what the online
    block's own rows cost where there is nothing to identify)."""
    s = compress(load_scenario())
    _source("momentum")(s, 0)
    return {"window": list(WINDOW), "online": rms(s, "online", WINDOW[1], WINDOW),
            "momentum": rms(s, None, WINDOW[1], WINDOW)}


def summarize(rows: list[dict]) -> dict:
    """The online part's medians over its draws (``rows``: one dict per draw)."""
    def median(key):
        v = [r[key]["squeeze"] for r in rows if key in r and "squeeze" in r[key]]
        return float(np.median(v)) if v else None

    out = {"window": list(WINDOW), "draws": rows, "n": len(rows),
           "median_online": median("online"), "median_nominal": median("nominal"),
           "median_batch": median("batch_map_sdp_10s"),
           "failed": {key: sum(1 for r in rows if key in r and "squeeze" not in r[key])
                      for key in ("online", "nominal", "batch_map_sdp_10s")}}
    if out["median_online"] is not None and out["median_batch"]:
        out["online_over_batch"] = out["median_online"] / out["median_batch"]
    out["paired"] = paired(rows)
    return out


def paired(rows: list[dict]) -> dict:
    """The online row against the batch row draw by draw: ``ratio`` (the median of the
    per-draw ratios online / batch, with its 95 % bootstrap interval, as the table's cells),
    ``within_2x`` of ``compared`` draws (both finished) at most twice the batch's error, the
    ``worst`` ratio and its ``worst_draw``."""
    from drake_coop.studies.reference_table import bootstrap_interval

    pairs = [(r["draw"], r["online"]["squeeze"] / r["batch_map_sdp_10s"]["squeeze"])
             for r in rows if "squeeze" in r.get("online", {})
             and "squeeze" in r.get("batch_map_sdp_10s", {})]
    if not pairs:
        return {"compared": 0}
    ratios = np.array([x for _, x in pairs])
    worst = int(np.argmax(ratios))
    return {"compared": len(pairs), "within_2x": int(np.sum(ratios <= 2.0)),
            "ratio": list(bootstrap_interval(ratios, 0.5)),
            "worst": float(ratios[worst]), "worst_draw": pairs[worst][0]}


def main() -> None:
    """Run the parts named and write their numbers."""
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", required=True)
    p.add_argument("--draws", type=int, default=6)
    p.add_argument("--parts", default="saturation,online")
    p.add_argument("--elbow-limit", type=float, default=11.5)
    p.add_argument("--online-log", default=None, metavar="LOG",
                   help="the online part from the draws a stopped run printed (one JSON line "
                        "a draw) instead of running it")
    args = p.parse_args()
    path = Path(args.out)
    result = json.loads(path.read_text()) if path.exists() else {}
    if args.online_log:
        lines = [line for line in open(args.online_log) if line.startswith('{"draw"')]
        result["online"] = {**summarize([json.loads(line) for line in lines]),
                            "from_log": True}
        path.write_text(json.dumps(result, indent=1) + "\n")
        return
    for part in args.parts.split(","):
        start = time.process_time()
        result[part] = (saturation(args.elbow_limit) if part == "saturation"
                        else online_exact() if part == "online_exact" else online(args.draws))
        result[part]["cpu_s"] = time.process_time() - start
        path.write_text(json.dumps(result, indent=1) + "\n")
        print(part, json.dumps({k: v for k, v in result[part].items() if k != "draws"}))


if __name__ == "__main__":
    main()
