"""The identification page's rank table: for every arm of the shipped scenarios, the
regressor's base parameters (its numerical rank, ``condition_number``), its column count,
the column-scaled condition number of the identifiable part and the largest relative gap of
the unscaled regressor's singular values at that rank; and the A465's round-off column.

    python studies/identification/rank_table.py docs/results/identification_rank_table.json

The regressor is taken as ``tests/identification/test_regressor.py`` takes it: 30 n random
states (q, q̇, q̈ uniform in ±1, ±2, ±4, seed 0), a 0.5 kg payload. The lab arms need the
``robots`` extra (skipped without it).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from drake_coop.identification.regressor import Regressor, condition_number, load_structure
from drake_coop.plant.arms import shipped_arm_models


def regressor(urdf: str, base: str, sensor) -> tuple[int, np.ndarray]:
    """``(n, Y)`` on 30 n random states with a 0.5 kg payload."""
    s = load_structure(urdf, base, payload_mass=0.5, sensor_joint=sensor)
    rng = np.random.default_rng(0)
    q, v, a = (rng.uniform(-lim, lim, (30 * s.n, s.n)) for lim in (1.0, 2.0, 4.0))
    return s.n, Regressor(s).matrix(q, v, a)


def row(n: int, Y: np.ndarray) -> dict:
    """The table's columns for one arm."""
    cond, rank = condition_number(Y)
    sv = np.linalg.svd(Y, compute_uv=False)
    sv = np.maximum(sv, np.finfo(float).eps * sv[0])
    return {"joints": n, "base_parameters": int(rank), "parameters": int(Y.shape[1]),
            "condition_number": float(cond), "gap_at_rank": float(sv[rank - 1] / sv[rank])}


def main(argv: list[str]) -> int:
    """Write the document to ``argv[0]``."""
    out: dict = {"arms": {}}
    for model, where in sorted(shipped_arm_models().items()):
        n, Y = regressor(*where)
        out["arms"][model.rsplit("/", 1)[-1].replace(".", "_")] = row(n, Y)
        if model == "crs_a465":
            norms = np.linalg.norm(Y, axis=0)
            tiny = (norms > 0) & (norms < 1e-10 * norms.max())
            out["crs_a465_round_off_column"] = {
                "norm": float(norms[tiny].max()),
                "other_columns_min": float(norms[(norms > 0) & ~tiny].min()),
                "other_columns_max": float(norms.max())}
    Path(argv[0]).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
