"""What the delay predictor's free-motion margin comes from, on the one joint (robot 2's slow
joint, the paper's gains; :mod:`drake_coop.stability.one_joint`): ρ with the predictor as
built (``p`` = 3 ms, the velocity observer fed ``p/h`` of the model's acceleration), without
that feed, and without the predictor, on the 1 ms plant and on the continuous arm, for the
delays 0–8 ms; and the continuous extrapolations' errors against the exact continuous joint.

    python studies/delay_compensation/predictor_terms.py docs/results/delay_predictor_terms.json

``λ̂(k−1)`` in the predicted acceleration is zero in free motion, so it cannot move the free
ρ; held, ρ is the force integral's mode, which the predictor does not touch.
"""

from __future__ import annotations

import json
import sys

import numpy as np

from drake_coop.stability.continuous import continuous_rho, continuous_spectrum
from drake_coop.stability.one_joint import one_joint_predicted_phi

J, D, LAMBDA, K_D, K_R, H = 0.478, 1.0, 26.0, 40.0, 100.0, 0.009
HORIZON = 0.003
DELAYS_MS = list(range(9))


def _eig(delay: float, horizon: float | None, dt: float | None, feed: str = "horizon",
         scale: float = 1.0) -> np.ndarray:
    return np.linalg.eigvals(one_joint_predicted_phi(J, D, LAMBDA, K_D, K_R, H, delay, horizon,
                                                     dt=dt, model_scale=scale, feed=feed))


def terms() -> dict:
    """The document written: ρ per variant, plant and delay (keys ``d<ms>``), and the
    extrapolation errors."""
    out: dict = {"joint": {"J_kg_m2": J, "D_N_m_s": D}, "gains": {
        "Lambda": LAMBDA, "k_d": K_D, "K_R": K_R}, "h_s": H, "horizon_s": HORIZON}
    for name, horizon, feed in (("predictor", HORIZON, "horizon"),
                                ("predictor_without_feed", HORIZON, "none"),
                                ("off", None, "horizon")):
        for plant, dt in (("plant_1ms", 1e-3), ("continuous", None)):
            out.setdefault(name, {})[plant] = {
                f"d{d}": float(np.max(np.abs(_eig(d * 1e-3, horizon, dt, feed))))
                for d in DELAYS_MS}
    errors = {}
    for scale, label in ((1.0, "exact"), (0.7, "light_0.7"), (1.3, "heavy_1.3")):
        largest, per_mode = [], []
        for d in DELAYS_MS:
            coarse, fine = _eig(d * 1e-3, HORIZON, 1e-3, scale=scale), \
                _eig(d * 1e-3, HORIZON, 5e-4, scale=scale)
            exact = float(np.max(np.abs(_eig(d * 1e-3, HORIZON, None, scale=scale))))
            largest.append(continuous_rho(np.max(np.abs(coarse)), np.max(np.abs(fine))) - exact)
            per_mode.append(float(np.max(np.abs(continuous_spectrum(coarse, fine)))) - exact)
        errors[label] = {"largest_modulus": largest, "per_mode": per_mode}
    out["extrapolation_error_with_predictor"] = errors
    return out


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: predictor_terms.py OUT.json")
    with open(sys.argv[1], "w", encoding="utf-8") as handle:
        json.dump(terms(), handle, indent=1)
        handle.write("\n")
