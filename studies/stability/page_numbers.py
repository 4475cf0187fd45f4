"""The stability page's numbers that are computed, not simulated: the observer's
forward-Euler period limit ``2/p_f`` per robot and ``k_d``, the one-joint closed form with
measured velocities (its crossing period and its ρ against a computation delay), the
continuous arm's delay margin interpolated from the shipped delay-compensation map, and the
clock-skew runs' largest relative change of the squeeze error, and the mean and 99th percentile
of the sampling lateness ``studies/timing.yaml`` draws (from the distributions' closed forms).

    python studies/stability/page_numbers.py docs/results/stability_page_numbers.json

Inputs: the paper's gains (``scenarios/paper.yaml``: Λ = 35 and 26 1/s, k_d = 40 1/s,
K_R = 120 and 100 N·m·s/rad), robot 2's slow joint (J = 0.478 kg·m², D = 1 N·m·s/rad, as in
``studies/delay_compensation/predictor_terms.py``), h = 9 ms on the 1 ms plant; and the CSVs
``docs/figures/stability/delay_compensation.csv`` and ``docs/figures/stability/clock_skew.csv``.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np

from drake_coop.stability.one_joint import crossing_period, observer_period_limit, one_joint_rho

ROOT = Path(__file__).resolve().parents[2]
LAMBDAS = {"robot1": 35.0, "robot2": 26.0}
J, D, K_R, H, DT = 0.478, 1.0, 100.0, 0.009, 0.001


def _rows(name: str) -> list[dict]:
    with (ROOT / "docs" / "figures" / "stability" / name).open(newline="") as handle:
        return list(csv.DictReader(handle))


def observer_limits() -> dict:
    """``2/p_f`` (s) and the two poles (1/s) per robot and ``k_d``."""
    out: dict = {}
    for robot, lam in LAMBDAS.items():
        for k_d in (40.0, 80.0, 160.0, 320.0):
            b = 2.0 * lam + k_d
            disc = np.sqrt(b * b - 4.0 * lam * k_d)
            out.setdefault(robot, {})[f"k_d{k_d:.0f}"] = {
                "period_limit_s": observer_period_limit(lam, k_d),
                "pole_slow": -0.5 * (b - disc), "pole_fast": -0.5 * (b + disc)}
    return out


def one_joint_measured() -> dict:
    """The one joint with measured velocities: ``h K_R / J``, its crossing period and ρ at
    h = 9 ms for a computation delay of 0–4 plant steps."""
    return {"h_K_R_over_J": H * K_R / J,
            "crossing_period_s": crossing_period(J, D, 26.0, 40.0, K_R, DT, "measured"),
            "rho_by_delay_steps": [one_joint_rho(J, D, 26.0, 40.0, K_R, H, DT, "measured", s)
                                   for s in range(5)]}


def continuous_margin() -> dict:
    """The delay (s) at which the continuous arm's ρ crosses 1 (free, exact model, no
    compensation), linearly interpolated between the grid's delays."""
    rows = sorted((float(r["delay_ms"]), float(r["rho_continuous"]))
                  for r in _rows("delay_compensation.csv")
                  if r["model"] == "exact" and not r["horizon_ms"] and r["point"] == "free")
    for (d0, r0), (d1, r1) in zip(rows, rows[1:]):
        if r0 < 1.0 <= r1:
            return {"margin_s": 1e-3 * (d0 + (1.0 - r0) * (d1 - d0) / (r1 - r0)),
                    "below_s": 1e-3 * d0, "above_s": 1e-3 * d1}
    return {"margin_s": None}


def skew_changes() -> dict:
    """Per object mode and compensation: the largest relative change (fraction) of each
    robot's squeeze error RMS against the run without skew or drift."""
    out: dict = {}
    rows = _rows("clock_skew.csv")
    for mode in sorted({r["object_mode"] for r in rows}):
        for horizon in sorted({r["prediction_horizon"] for r in rows}):
            group = [r for r in rows if r["object_mode"] == mode
                     and r["prediction_horizon"] == horizon]
            base = next(r for r in group if float(r["skew_s"]) == 0 and float(r["drift"]) == 0)
            key = f"{mode}_{'p%.0fms' % (1e3 * float(horizon)) if horizon else 'off'}"
            out[key] = {robot: max(abs(float(r[f"squeeze_rms_{robot}"])
                                       / float(base[f"squeeze_rms_{robot}"]) - 1.0)
                                   for r in group) for robot in ("robot1", "robot2")}
            out[key]["worst"] = max(out[key]["robot1"], out[key]["robot2"])
    return out


def jitter_lateness() -> dict:
    """Mean and 99th percentile (s) of each lateness distribution of ``studies/timing.yaml``
    (no computation delay, so the exponential is cut at ``h``)."""
    out: dict = {}
    scale = 0.0011
    cut = 1.0 - np.exp(-H / scale)                  # the exponential's mass below h
    out["exponential_1p1ms"] = {
        "mean_s": scale - H * np.exp(-H / scale) / cut,
        "p99_s": -scale * np.log(1.0 - 0.99 * cut)}
    for ms in (3, 6, 9):
        out[f"uniform_{ms}ms"] = {"mean_s": 0.5e-3 * ms, "p99_s": 0.99e-3 * ms}
    return out


def main(argv: list[str]) -> int:
    """Write the document to ``argv[0]``."""
    document = {"observer_period_limit": observer_limits(),
                "one_joint_measured": one_joint_measured(),
                "continuous_margin": continuous_margin(),
                "clock_skew_change": skew_changes(),
                "jitter_lateness": jitter_lateness()}
    Path(argv[0]).write_text(json.dumps(document, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
