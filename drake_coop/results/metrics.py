"""Error metrics of Figures 2–6: RMS and max per robot, per phase and overall.

``metrics[robot][phase][error] = {"rms": ..., "max": ..., "unit": ...}`` with phases ``free``,
``lift``, ``circle``, ``put_down``, ``return`` and ``all``, and errors

* ``x_tilde``, ``y_tilde``, ``z_tilde`` — Cartesian tracking errors ``x − x_d`` (Fig. 2), m;
* ``force_error`` — ``λ − λ_d``, measured minus desired squeeze (Fig. 3), N;
* ``estimate_error`` — ``λ − λ̂``, measured minus estimated (Fig. 4), N;
* ``aux_force_error`` — ``λ̂ − λ_d`` (Fig. 5), N;
* ``z1``, ``z2``, ``z3`` — observation errors ``q − q̂`` (Fig. 6), rad.

Non-finite samples (a diverged run) are left out and counted in ``n_nonfinite``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from drake_coop.results.io import atomic_write_text


def error_signals(log: dict[str, np.ndarray]) -> dict[str, tuple[np.ndarray, str]]:
    """The errors of Figures 2–6 of one robot's log, with their units."""
    e = log["x"] - log["x_d"]
    z = log["q"] - log["q_hat"]
    return {
        "x_tilde": (e[:, 0], "m"), "y_tilde": (e[:, 1], "m"), "z_tilde": (e[:, 2], "m"),
        "force_error": (log["lambda_meas"] - log["lambda_d"], "N"),
        "estimate_error": (log["lambda_meas"] - log["lambda_hat"], "N"),
        "aux_force_error": (log["lambda_hat"] - log["lambda_d"], "N"),
        "z1": (z[:, 0], "rad"), "z2": (z[:, 1], "rad"), "z3": (z[:, 2], "rad"),
    }


def _phase_masks(t: np.ndarray, phases: list) -> dict[str, np.ndarray]:
    masks = {}
    for i, (name, a, b) in enumerate(phases):
        last = i == len(phases) - 1
        masks[name] = (t >= a) & ((t <= b) if last else (t < b))
    masks["all"] = np.ones_like(t, dtype=bool)
    return masks


def compute_metrics(logs: dict[str, dict[str, np.ndarray]], meta: dict) -> dict:
    """RMS and max-abs of every error of Figures 2–6, per robot and per phase."""
    result = {}
    for robot, log in logs.items():
        signals = error_signals(log)
        per_phase = {}
        for phase, mask in _phase_masks(np.asarray(log["t"]), meta["phases"]).items():
            if not mask.any():
                continue
            entry = {}
            nonfinite = 0
            for name, (x, unit) in signals.items():
                x = np.asarray(x)[mask]
                ok = np.isfinite(x)
                nonfinite = max(nonfinite, int((~ok).sum()))
                x = x[ok]
                if x.size == 0:
                    continue
                entry[name] = {"rms": float(np.sqrt(np.mean(x * x))),
                               "max": float(np.max(np.abs(x))), "unit": unit}
            entry["n_samples"] = int(mask.sum())
            entry["n_nonfinite"] = nonfinite
            per_phase[phase] = entry
        result[robot] = per_phase
    return result


def write_metrics(out_dir: str | Path, metrics: dict) -> Path:
    """Write ``metrics.json`` atomically."""
    return atomic_write_text(Path(out_dir) / "metrics.json", json.dumps(metrics, indent=2))
