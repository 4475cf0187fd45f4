"""Error metrics of Figures 2–6: RMS and max per robot, per phase and overall.

``metrics[robot][phase][error] = {"rms": ..., "max": ..., "unit": ...}`` with the phases of
``meta["phases"]`` (``free``, ``lift``, ``circle``, ``put_down``, ``return``) and ``all``, and
errors

* ``x_tilde``, ``y_tilde``, ``z_tilde`` — Cartesian tracking errors ``x − x_d`` (Fig. 2), m;
* ``force_error`` — ``λ − λ_d``, measured minus desired squeeze (Fig. 3), N;
* ``estimate_error`` — ``λ − λ̂``, measured minus estimated (Fig. 4), N;
* ``aux_force_error`` — ``λ̂ − λ_d`` (Fig. 5), N;
* ``z1`` … ``zn`` — observation errors ``q − q̂`` of the robot's n joints (Fig. 6), rad;
* ``velocity_error`` — ``max_j |q̇_j − q̇̂_j|``, the worst joint's error of the controller's
  velocity estimate (``d/dt q̂`` of the observer, or the alternative source's), rad/s; only
  for logs that hold ``qdot`` and ``qdot_hat`` (runs with the sensing models).

For a robot with m >= 2 constraints the three force errors are m-vectors per sample; their
metric is taken on the Euclidean norm of the vector at each sample,
``e(t_k) = ‖λ(t_k) − λ_d(t_k)‖₂`` (so ``max`` is the largest norm and ``rms`` is
``sqrt(mean_k Σ_j e_j(t_k)²)``). For one constraint (the paper) the norm is ``|λ − λ_d|``, and
RMS and max of ``|e|`` are those of ``e``: the paper's numbers are unchanged.

A phase ``[name, a, b]`` holds the samples with ``a <= t < b`` (the last phase also ``t = b``);
``all`` holds every sample. Besides the errors, ``metrics[robot][phase]`` has ``n_samples``
(samples in the phase) and ``n_nonfinite`` (samples where at least one error is NaN or
infinite, as at the end of a diverged run). Each error's RMS and max use its finite samples
only; an error with none is left out, and so is a phase with no samples (a run stopped before
it).

In ``contact`` mode each robot's phases also hold the object's metrics
(:mod:`drake_coop.results.object_metrics`): ``friction_use``, ``object_position_error``,
``object_angle_error``, ``object_turn``, ``object_tilt`` (the rotation about the grasp line
and the rest), ``slip`` (``rms``/``max``/``unit``) and the counts ``slips`` and
``drops`` (``{"count": k, "unit": "events"}``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from drake_coop.results.io import atomic_write_text
from drake_coop.results.object_metrics import object_metrics

__all__ = ["compute_metrics", "error_signals", "phase_masks", "write_metrics"]


def error_signals(log: dict[str, np.ndarray]) -> dict[str, tuple[np.ndarray, str]]:
    """The errors of Figures 2–6 of one robot's log, with their units.

    Parameters
    ----------
    log : dict
        One robot's log (schema of :mod:`drake_coop.results.logs`).

    Returns
    -------
    dict
        ``name -> (samples (N,), unit)`` for the errors listed in the module docstring.
    """
    e = np.asarray(log["x"], dtype=float) - np.asarray(log["x_d"], dtype=float)
    z = np.asarray(log["q"], dtype=float) - np.asarray(log["q_hat"], dtype=float)
    lam = np.asarray(log["lambda_meas"], dtype=float)
    lam_hat = np.asarray(log["lambda_hat"], dtype=float)
    lam_d = np.asarray(log["lambda_d"], dtype=float)
    signals = {
        "x_tilde": (e[:, 0], "m"), "y_tilde": (e[:, 1], "m"), "z_tilde": (e[:, 2], "m"),
        "force_error": (_per_sample(lam - lam_d), "N"),
        "estimate_error": (_per_sample(lam - lam_hat), "N"),
        "aux_force_error": (_per_sample(lam_hat - lam_d), "N"),
    }
    signals.update({f"z{j + 1}": (z[:, j], "rad") for j in range(z.shape[1])})
    if "qdot" in log and "qdot_hat" in log:
        dv = np.asarray(log["qdot"], dtype=float) - np.asarray(log["qdot_hat"], dtype=float)
        signals["velocity_error"] = (np.abs(dv).max(axis=1), "rad/s")
    return signals


def _per_sample(e: np.ndarray) -> np.ndarray:
    """A force error per sample: ``e`` itself for one constraint (shape (N,)), the Euclidean
    norm ``‖e_k‖₂`` of each row for m >= 2 (shape (N, m)), computed as
    ``p_k sqrt(Σ_j (e_kj / p_k)²)`` with ``p_k = max_j |e_kj|`` so that squaring cannot
    overflow; a row holding NaN or ±inf gives NaN (a non-finite sample)."""
    if e.ndim == 1:
        return e
    peak = np.max(np.abs(e), axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        scaled = np.where(peak[:, None] > 0, e / np.where(peak > 0, peak, 1.0)[:, None], 0.0)
        norm = peak * np.sqrt(np.sum(scaled ** 2, axis=1))
    return np.where(np.isfinite(peak), norm, np.nan)


def phase_masks(t: np.ndarray, phases: list) -> dict[str, np.ndarray]:
    """Boolean masks of the samples of each phase, and ``all``.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times.
    phases : list
        ``[name, t_start, t_end]`` in order; intervals are half-open except the last.

    Returns
    -------
    dict
        ``name -> mask (N,)``, then ``"all"``.
    """
    t = np.asarray(t, dtype=float)
    masks = {}
    for i, (name, a, b) in enumerate(phases):
        upper = t <= b if i == len(phases) - 1 else t < b
        masks[str(name)] = (t >= a) & upper
    masks["all"] = np.ones(t.shape, dtype=bool)
    return masks


def _rms_max(x: np.ndarray) -> tuple[float, float]:
    """RMS and max |x| of finite samples, scaled so that squaring cannot overflow."""
    peak = float(np.max(np.abs(x)))
    if peak == 0.0:
        return 0.0, 0.0
    return peak * float(np.sqrt(np.mean((x / peak) ** 2))), peak


def compute_metrics(logs: dict[str, dict[str, np.ndarray]], meta: dict) -> dict:
    """RMS and max-abs of every error of Figures 2–6, per robot and per phase.

    Parameters
    ----------
    logs : dict
        ``logs[robot][array]`` (schema of :mod:`drake_coop.results.logs`).
    meta : dict
        Run metadata; ``meta["phases"]`` is used.

    Returns
    -------
    dict
        ``metrics[robot][phase][error] = {"rms": float, "max": float, "unit": str}`` plus
        ``metrics[robot][phase]["n_samples"]`` and ``["n_nonfinite"]`` (see the module
        docstring). Every float is finite.
    """
    result = {}
    for robot, log in logs.items():
        signals = error_signals(log)
        finite = np.column_stack([np.isfinite(x) for x, _ in signals.values()])
        per_phase = {}
        for phase, mask in phase_masks(log["t"], meta["phases"]).items():
            if not mask.any():
                continue
            entry: dict = {}
            for (name, (x, unit)), ok in zip(signals.items(), finite.T):
                values = x[mask & ok]
                if values.size:
                    rms, peak = _rms_max(values)
                    entry[name] = {"rms": rms, "max": peak, "unit": unit}
            entry["n_samples"] = int(mask.sum())
            entry["n_nonfinite"] = int((mask & ~finite.all(axis=1)).sum())
            per_phase[phase] = entry
        result[robot] = per_phase
    for robot, phases in object_metrics(logs, meta, phase_masks(
            next(iter(logs.values()))["t"], meta["phases"])).items():
        for phase, entry in phases.items():
            if phase in result[robot]:
                result[robot][phase].update(entry)
    return result


def write_metrics(out_dir: str | Path, metrics: dict) -> Path:
    """Write ``metrics.json`` (indent 2, floats as JSON numbers) atomically.

    Parameters
    ----------
    out_dir : str or Path
        Run directory.
    metrics : dict
        As returned by :func:`compute_metrics`.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    ValueError
        If ``metrics`` holds a NaN or infinity (not valid JSON); nothing is written.
    """
    text = json.dumps(metrics, indent=2, allow_nan=False)
    return atomic_write_text(Path(out_dir) / "metrics.json", text + "\n")
