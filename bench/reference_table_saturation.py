"""Torque saturation at the lift: what each force source's estimate and squeeze error do
during and after it, on paired draws (the reference table's short segment, 8 s).

``python bench/reference_table_saturation.py --out docs/results/reference_table_saturation.json
[--draws 20] [--sweep]`` (resumable: each finished draw is kept in ``OUT.draws.jsonl``, and a
run added to the bench later is run for the stored draws only).

The saturation: robot 1's elbow limited at ``11.5 × U(0.98, 1.02)`` N·m per draw (its peak
on the lift is 11.7 N·m, on the approach 11.8: saturated on the approach and the lift, not
after; a lower limit ends the grasp). Per draw, one run each, exact model:

* ``momentum`` — the momentum observer integrating the commanded torque;
* ``residual`` — the applied-torque residual: the momentum observer integrating the clipped
  torque (:mod:`drake_coop.studies.reference_variants`);
* ``sensor`` — the loop closed on the F/T sensor (σ = 0.3 N, seed = the draw): the floor no
  estimator can beat, since its estimate is the measurement;
* ``sensor_free`` — the same sensor without the limit (the draw's noise), and once
  ``momentum_free``: the momentum observer without the limit (deterministic);
* ``momentum_aw``, ``residual_aw``, ``sensor_aw`` — the first three with the anti-windup of
  the force integral (6) on robot 1 (``anti_windup: conditional``,
  :mod:`drake_coop.control.anti_windup`; robot 2 has no limit and never clips);
* ``momentum_bc``, ``residual_bc``, ``sensor_bc`` — the same with back-calculation
  (``anti_windup: back_calculation``) at the tracking rate ``K_aw = k_F`` (the classic choice
  of a tracking time constant equal to the integral's, ``1/k_F``: the unapplied torque enters
  (6) as a force error, ``(J_φᵀ)⁺ (sat(τ) − τ)`` newtons).

``--sweep`` adds the diagnosis (``sweep`` in the results file): on draws 0 and 3, the
residual with (6), with conditional integration and with back-calculation at
``K_aw`` ∈ ``SWEEP_GAINS``, and the unsaturated run; per run also the signed mean of
``λ − λ_d`` over the circle (``squeeze_circle_mean``), the RMS of ``|τ_cmd − τ|`` over
robot 1's saturated ticks after the grasp (``excess_saturated``, N·m; also in the draws'
runs added since) and the RMS joint tracking error
``|q − q_d|`` there (``q_error_circle``, rad), at the grasp (``q_error_grasp``, rad: what the
saturated approach left) and robot 1's largest ``|λ − λ_d|`` in the first 0.2 s held
(``squeeze_grasp_max``, N; both in the runs added since); and the least-squares line
``squeeze_circle_mean = a · DF_circle_signed + b`` over those that finished (``fit``: ``a``
against the law's ``k_F``, ``DF_star = −b/a``, the ΔF̃ at which the circle's squeeze error
vanishes, and the largest distance of a run from the line; ``failed``: the runs that lost
the grasp, kept with their message). ``DF_lift_end_signed`` and ``DF_circle_signed``: the
first constraint's ``ΔF̃`` with its sign (the other ``DF_*`` are sizes).

Numbers per run, from the logs (worst robot unless said): ``squeeze_circle`` and
``estimate_circle`` — the RMS of ``λ − λ_d`` and ``λ̂ − λ`` over the circle 5–8 s;
``squeeze_lift`` and ``estimate_lift`` — over the lift 3–5 s; ``estimate_saturated`` —
robot 1's RMS of ``λ̂ − λ`` over its saturated ticks (``τ ≠ τ_cmd``), from the grasp on
(before it ``λ = 0``: ``estimate_approach``, robot 1's over its saturated ticks before the
grasp); ``saturated_ticks``; ``DF_lift_end``, ``DF_lift_max``, ``DF_circle`` — robot 1's
force integral ``ΔF̃`` (6) at the lift's end, its largest magnitude over the lift and its
mean over the circle, rebuilt from the logged ``λ̂ − λ_d`` by (6)'s closed form (held from
the grasp on; with conditional anti-windup not integrated at the ticks whose logged
commanded torque exceeds the limit, where the applied one differs from it; with
back-calculation its term added at those ticks, from the logged ``q``, ``τ`` and the arm's
model). The summary: per number, the
median over the draws of each run and of the paired ratios ``<run> / momentum_free``, with
their range, and for the circle's squeeze ratio the median's 95 % bootstrap interval
(:func:`~drake_coop.studies.reference_table.bootstrap_interval`); the paired ratios
``<run>_aw / <run>`` and ``<run>_bc / <run>``, and ``residual_bc / momentum``;
``unsaturated_lift_draws``, the draws whose limit clips only on the
approach, before the grasp. Strict JSON: a number undefined in a run (an RMS over no tick) is
null. Process CPU seconds are recorded.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from drake_coop.control.anti_windup import back_calculation
from drake_coop.experiment.simulate import simulate
from drake_coop.plant.arms import Arm, arm_model
from drake_coop.scenario.loading import load_scenario
from drake_coop.studies.reference_table import _source, bootstrap_interval, compress
from drake_coop.studies.reference_variants import variant_built

ELBOW = 11.5
CIRCLE, LIFT = (5.0, 8.0), (3.0, 5.0)
T_END = 8.0
RUNS = ("momentum", "residual", "sensor", "momentum_aw", "residual_aw", "sensor_aw",
        "sensor_free", "momentum_bc", "residual_bc", "sensor_bc")
#: The saturated runs, each with the paper's (6), conditional integration (``_aw``) and
#: back-calculation (``_bc``).
PAIRED = ("momentum", "residual", "sensor")
#: The anti-windup of each run suffix.
SCHEMES = {"_aw": "conditional", "_bc": "back_calculation"}
#: The diagnosis' draws and back-calculation gains ``K_aw`` (1/s; 111.1 = 1/h).
SWEEP_DRAWS = (0, 3)
SWEEP_GAINS = (0.03, 0.05, 0.07, 0.1, 1.0, 10.0, 1.0 / 0.009)


def _rms(x: np.ndarray) -> float | None:
    return float(np.sqrt(np.mean(x ** 2))) if x.size else None


#: The unsaturated momentum observer's robot-1 estimate error per logged tick: ``(t, |λ̂ − λ|)``
#: (its run is deterministic: run once a process).
_FREE: dict = {}


def measure(row: str, noise: float | None, limit: float | None, variant: str | None,
            draw: int, keep: bool = False, anti_windup: bool | str = False,
            gain: float | None = None, scenario: str | None = None, joint: int = 2,
            peaks: bool = False) -> dict:
    """One run's numbers (the module's docstring); ``keep``: also robot 1's estimate error
    per tick (``_FREE``); ``saturated_times``: robot 1's saturated ticks after the grasp (not
    written); ``anti_windup``: robot 1 with ``anti_windup: conditional`` (True) or the
    scheme named; ``gain``: back-calculation's ``K_aw`` (None: the law's ``k_F``);
    ``scenario``: a scenario file (None: the paper's); ``joint``: robot 1's joint the
    ``limit`` (N·m) applies to, every other joint at 100 N·m (above every shipped arm's
    peak on the segment); ``peaks``: also ``lift_peaks``, robot 1's largest ``|τ|`` per
    joint over the lift (N·m)."""
    s = compress(load_scenario(scenario) if scenario else load_scenario())
    _source(row, noise)(s, draw)
    if limit is not None:
        limits = [100.0] * len(s.robots[0].gains.K_R)
        limits[joint] = limit
        s.robots[0].actuators.torque_limits = limits
    scheme = "conditional" if anti_windup is True else (anti_windup or None)
    s.robots[0].anti_windup = scheme
    if scheme == "back_calculation":
        gain = s.robots[0].gains.k_F if gain is None else gain
        s.robots[0].anti_windup_gain = gain
    with variant_built(s, variant):
        result = simulate(s, t_end=T_END)
    out = {"status": result.meta["status"], "message": result.meta["message"]}
    if not result.ok:
        return out
    numbers: dict = {k: [] for k in ("squeeze_circle", "estimate_circle", "squeeze_lift",
                                     "estimate_lift")}
    for name, log in result.logs.items():
        t = log["t"]
        squeeze = log["lambda_meas"] - log["lambda_d"]
        estimate = log["lambda_hat"] - log["lambda_meas"]
        for key, (t0, t1) in (("circle", CIRCLE), ("lift", LIFT)):
            w = (t >= t0 - 1e-9) & (t < t1 - 1e-9)
            numbers[f"squeeze_{key}"].append(_rms(squeeze[w]))
            numbers[f"estimate_{key}"].append(_rms(estimate[w]))
            out[f"squeeze_{key}_{name}"] = numbers[f"squeeze_{key}"][-1]
            out[f"estimate_{key}_{name}"] = numbers[f"estimate_{key}"][-1]
        if name == "robot1":
            sat = np.any(np.abs(log["tau_cmd"] - log["tau"]) > 1e-12, axis=1)
            grasped = t >= s.task.t_grasp - 1e-9
            out["saturated_ticks"] = int(sat.sum())
            circle = (t >= CIRCLE[0] - 1e-9) & (t < CIRCLE[1] - 1e-9)
            out["squeeze_circle_mean"] = float(np.mean(squeeze[circle]))
            out["q_error_circle"] = _rms(np.linalg.norm(log["q"] - log["q_d"], axis=1)[circle])
            out["estimate_saturated"] = _rms(estimate[sat & grasped])
            out["excess_saturated"] = _rms(np.linalg.norm(log["tau_cmd"] - log["tau"],
                                                          axis=1)[sat & grasped])
            out["estimate_approach"] = _rms(estimate[sat & ~grasped])
            out["saturated_times"] = t[sat & grasped]
            # At the grasp: the joint error the approach left, and the constraint force's
            # largest excess over its reference in the first 0.2 s held.
            at = np.searchsorted(t, s.task.t_grasp - 1e-9)
            out["q_error_grasp"] = float(np.linalg.norm(log["q"][at] - log["q_d"][at]))
            first = grasped & (t < s.task.t_grasp + 0.2 - 1e-9)
            out["squeeze_grasp_max"] = float(np.abs(squeeze[first]).max())
            if peaks:
                lift = (t >= LIFT[0] - 1e-9) & (t < LIFT[1] - 1e-9)
                out["lift_peaks"] = np.abs(log["tau"][lift]).max(axis=0).tolist()
            after = grasped & (t > (t[sat].max() if sat.any() else np.inf))
            lift_after = after & (t < LIFT[1] - 1e-9)
            out["estimate_lift_after_saturation"] = _rms(estimate[lift_after])
            # The observer's own lag: (15)'s momentum balance in the observer's forward-Euler
            # tick gives λ̂(k+1) ≈ λ̂(k) + K_O h (λ(k) − λ̂(k)); this low-pass of the simulated
            # λ is what an observer integrating the right torque estimates.
            alpha = s.robots[0].gains.momentum_gain * (t[1] - t[0])
            lam = np.asarray(log["lambda_meas"], float).reshape(t.size, -1)
            lp = np.zeros_like(lam)
            for k in range(1, t.size):
                lp[k] = lp[k - 1] + alpha * (lam[k - 1] - lp[k - 1]) if grasped[k - 1] else 0.0
            off = np.asarray(log["lambda_hat"], float).reshape(t.size, -1) - lp
            free_lift = grasped & (t < LIFT[1] - 1e-9)
            out["lowpass_saturated"] = _rms(off[sat & grasped])
            out["lowpass_lift"] = _rms(off[free_lift & ~sat])
            # ΔF̃ (6) rebuilt from the logged λ̂ − λ_d (held from the grasp on).
            error = np.asarray(log["lambda_hat"] - log["lambda_d"], float).reshape(t.size, -1)
            DF = np.zeros_like(error)
            frozen = sat if scheme == "conditional" else np.zeros_like(sat)
            h = t[1] - t[0]
            if scheme == "back_calculation":
                model = arm_model(Arm(s.robots[0], s.task))
                limits = np.asarray(s.robots[0].actuators.torque_limits, float)
                for k in np.flatnonzero(sat & grasped):
                    term = back_calculation(log["tau_cmd"][k], limits, model.J_phi(log["q"][k]),
                                            s.robots[0].gains.k_F, gain)
                    error[k] = error[k] + (0.0 if term is None else term)
            for k in range(1, t.size):
                DF[k] = (DF[k - 1] + (0.0 if frozen[k - 1] else h * error[k - 1])
                         if grasped[k - 1] else 0.0)
            size = np.linalg.norm(DF, axis=1)
            lift = grasped & (t < LIFT[1] - 1e-9)
            out["DF_lift_end"] = float(size[np.searchsorted(t, LIFT[1] - 1e-9)])
            out["DF_lift_max"] = float(size[lift].max())
            out["DF_circle"] = float(size[(t >= CIRCLE[0] - 1e-9)].mean())
            # The first constraint's ΔF̃ with its sign (the sizes above have none).
            out["DF_lift_end_signed"] = float(DF[np.searchsorted(t, LIFT[1] - 1e-9), 0])
            out["DF_circle_signed"] = float(DF[(t >= CIRCLE[0] - 1e-9), 0].mean())
            if keep:
                _FREE.update(t=t, error=np.abs(estimate).reshape(t.size, -1).max(axis=1))
    out.update({k: max(v) for k, v in numbers.items()})
    return out


def _free_over(times: np.ndarray) -> float:
    """The unsaturated run's robot-1 RMS estimate error over the given tick times."""
    if "t" not in _FREE:
        measure("momentum", None, None, None, 0, keep=True)
    idx = np.searchsorted(_FREE["t"], np.asarray(times) - 1e-9)
    return _rms(_FREE["error"][idx])


def _add_runs(out: dict, draw: int, limit: float) -> None:
    """The draw's saturated runs ``out`` does not have yet (every scheme)."""
    for tail in ("",) + tuple(SCHEMES):
        scheme = SCHEMES.get(tail, False)
        for run, (row, noise, variant) in (("momentum", ("momentum", None, None)),
                                           ("residual", ("momentum", None, "applied_torque")),
                                           ("sensor", ("sensor", 0.3, None))):
            if run + tail not in out:
                out[run + tail] = measure(row, noise, limit, variant, draw,
                                          anti_windup=scheme)
                out[run + tail].pop("saturated_times", None)


def sweep() -> dict:
    """The diagnosis (module docstring): the residual on ``SWEEP_DRAWS`` with every scheme
    and back-calculation gain, the unsaturated run, and the line through their circle
    squeeze errors against ``ΔF̃``."""
    runs = [{"draw": None, "scheme": None, "gain": None,
             **measure("momentum", None, None, None, 0)}]
    for draw in SWEEP_DRAWS:
        limit = ELBOW * float(np.random.default_rng([1, draw]).uniform(0.98, 1.02))
        for scheme, gain in ((None, None), ("conditional", None),
                             *(("back_calculation", g) for g in SWEEP_GAINS)):
            runs.append({"draw": draw, "scheme": scheme, "gain": gain,
                         **measure("momentum", None, limit, "applied_torque", draw,
                                   anti_windup=scheme or False, gain=gain)})
    for run in runs:
        run.pop("saturated_times", None)
    ok = [r for r in runs if r["status"] == "ok"]
    x = np.array([r["DF_circle_signed"] for r in ok])
    y = np.array([r["squeeze_circle_mean"] for r in ok])
    a, b = np.polyfit(x, y, 1)
    k_F = load_scenario().robots[0].gains.k_F
    return {"runs": runs, "failed": len(runs) - len(ok),
            "fit": {"a": float(a), "b": float(b), "k_F": k_F, "a_over_k_F": float(a / k_F),
                    "DF_star": float(-b / a), "n": len(ok),
                    "residual_max": float(np.abs(y - (a * x + b)).max())}}


def run_draw(draw: int, seed: int = 1) -> dict:
    """The paired runs of one draw; ``free_over_saturated``: the unsaturated momentum
    observer's robot-1 estimate error over the ticks the draw's residual run saturated."""
    limit = ELBOW * float(np.random.default_rng([seed, draw]).uniform(0.98, 1.02))
    out = {"draw": draw, "elbow_limit": limit}
    _add_runs(out, draw, limit)
    out["sensor_free"] = measure("sensor", 0.3, None, None, draw)
    times = out["residual"].get("saturated_times")
    out["free_over_saturated"] = _free_over(times) if times is not None else None
    for run in RUNS:
        out[run].pop("saturated_times", None)
    return out


KEYS = ("squeeze_circle", "estimate_circle", "squeeze_lift", "estimate_lift",
        "estimate_saturated", "estimate_approach", "saturated_ticks",
        "estimate_lift_after_saturation", "squeeze_lift_robot1", "squeeze_lift_robot2",
        "estimate_lift_robot1", "estimate_lift_robot2", "squeeze_circle_robot1",
        "squeeze_circle_robot2", "lowpass_saturated", "lowpass_lift", "DF_lift_end",
        "DF_lift_max", "DF_circle")


def summarize(draws: list[dict], free: dict) -> dict:
    """Medians and ranges over the draws; the paired ratios against the unsaturated run."""
    def stats(values):
        v = np.array([x for x in values if x is not None and np.isfinite(x)])
        if not v.size:
            return None
        return {"median": float(np.median(v)), "min": float(v.min()), "max": float(v.max()),
                "n": int(v.size)}

    out: dict = {"n": len(draws)}
    for run in RUNS:
        ok = [d[run] for d in draws if d[run]["status"] == "ok"]
        out[run] = {"completed": len(ok), **{k: stats([r.get(k) for r in ok]) for k in KEYS}}
    for run in PAIRED + tuple(f"{r}{tail}" for tail in SCHEMES for r in PAIRED):
        free_run = free if not run.startswith("sensor") else None
        out[f"{run}_over_free"] = {
            k: stats([d[run][k] / (free_run or d["sensor_free"])[k] for d in draws
                      if d[run]["status"] == "ok" and d["sensor_free"]["status"] == "ok"])
            for k in ("squeeze_circle", "estimate_circle", "squeeze_lift", "estimate_lift")}
        ratios = np.array([d[run]["squeeze_circle"] / (free_run or d["sensor_free"])[
            "squeeze_circle"] for d in draws
            if d[run]["status"] == "ok" and d["sensor_free"]["status"] == "ok"])
        median, low, high = bootstrap_interval(ratios, 0.5)
        out[f"{run}_over_free"]["squeeze_circle_interval"] = (
            {"median": median, "low": low, "high": high} if ratios.size else None)
    for run in PAIRED:
        for tail in SCHEMES:
            out[f"{run}{tail}_over_{run}"] = {
                k: stats([d[f"{run}{tail}"][k] / d[run][k] for d in draws
                          if d[run]["status"] == d[f"{run}{tail}"]["status"] == "ok"])
                for k in ("squeeze_circle", "squeeze_lift", "estimate_circle", "DF_lift_end")}
    out["residual_over_momentum"] = {
        k: stats([d["residual"][k] / d["momentum"][k] for d in draws
                  if d["residual"]["status"] == d["momentum"]["status"] == "ok"
                  and d["residual"].get(k) is not None and d["momentum"].get(k)])
        for k in ("squeeze_circle", "estimate_circle", "squeeze_lift", "estimate_lift",
                  "estimate_saturated")}
    # Back-calculation at K_aw = k_F on the residual against the commanded-torque observer
    # with (6), whose integral the term reproduces up to the observer's lag (the module
    # docstring of drake_coop.control.anti_windup).
    out["residual_bc_over_momentum"] = {
        k: stats([d["residual_bc"][k] / d["momentum"][k] for d in draws
                  if d["residual_bc"]["status"] == d["momentum"]["status"] == "ok"])
        for k in ("squeeze_circle", "DF_lift_end")}
    for run in PAIRED:
        out[f"{run}_saturated_over_free_same_ticks"] = stats(
            [d[run]["estimate_saturated"] / d["free_over_saturated"] for d in draws
             if d[run]["status"] == "ok" and d["free_over_saturated"]
             and d[run]["estimate_saturated"] is not None])
    out["free_over_saturated"] = stats([d["free_over_saturated"] for d in draws])
    # Draws whose limit clips only on the approach (no saturated tick after the grasp).
    out["unsaturated_lift_draws"] = sum(1 for d in draws if d["residual"]["status"] == "ok"
                                        and d["residual"].get("estimate_saturated") is None)
    out["sensor_over_sensor_free_squeeze_lift"] = stats(
        [d["sensor"]["squeeze_lift"] / d["sensor_free"]["squeeze_lift"] for d in draws
         if d["sensor"]["status"] == d["sensor_free"]["status"] == "ok"])
    return out


def main() -> None:
    """Run (or resume) the draws and write the summary."""
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--out", required=True)
    p.add_argument("--draws", type=int, default=20)
    p.add_argument("--sweep", action="store_true",
                   help="also the diagnosis on draws 0 and 3 (module docstring)")
    args = p.parse_args()
    path = Path(args.out)
    lines = path.with_suffix(".draws.jsonl")
    done = ([json.loads(x) for x in lines.read_text().splitlines() if x.strip()]
            if lines.exists() else [])
    start = time.process_time()
    free = next((d["momentum_free"] for d in done if "momentum_free" in d), None)
    if free is None:
        free = measure("momentum", None, None, None, 0, keep=True)
        free.pop("saturated_times", None)
        done.append({"momentum_free": free})
        with lines.open("a") as f:
            f.write(json.dumps(done[-1]) + "\n")
    have = {d["draw"]: d for d in done if "draw" in d}
    for draw in range(args.draws):
        if draw in have:
            if all(run in have[draw] for run in RUNS):
                continue
            _add_runs(have[draw], draw, have[draw]["elbow_limit"])   # a run added later
            lines.write_text("".join(json.dumps(d) + "\n" for d in done))
        else:
            done.append(run_draw(draw))
            with lines.open("a") as f:
                f.write(json.dumps(done[-1]) + "\n")
        print(f"draw {draw}", flush=True)
    draws = sorted((d for d in done if "draw" in d), key=lambda d: d["draw"])[:args.draws]
    previous = json.loads(path.read_text()) if path.exists() else {}
    diagnosis = sweep() if args.sweep else previous.get("sweep")
    cpu = time.process_time() - start
    result = {"elbow_nominal": ELBOW, "circle": list(CIRCLE), "lift": list(LIFT),
              "momentum_free": free, "summary": summarize(draws, free), "draws": draws,
              "cpu_s": (previous.get("cpu_s") or 0.0) + cpu,
              "runs": 1 + len(RUNS) * len(draws), "sweep": diagnosis}
    result.update({k: previous[k] for k in ("cpu_note", "cpu_rerun") if k in previous})
    path.write_text(json.dumps(result, indent=1, allow_nan=False) + "\n")
    print(json.dumps(result["summary"], indent=1))


if __name__ == "__main__":
    main()
