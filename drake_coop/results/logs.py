"""Run logs on disk: one ``.npz`` and one ``.csv`` per robot, plus ``run.json``.

Per robot, one row per control sample (period h):

==============  =========  ==================================================================
array           shape      meaning
==============  =========  ==================================================================
``t``           (N,)       time of the sample (s)
``q``           (N, 3)     measured joint positions (rad)
``q_hat``       (N, 3)     velocity-observer estimate q̂ (15) (rad)
``q_d``         (N, 3)     desired joint positions (rad)
``x``           (N, 3)     end-effector position, palm frame (m)
``x_d``         (N, 3)     desired end-effector position (28) (m)
``F_meas``      (N, 3)     measured force of the object on the end effector, palm frame (N)
``lambda_meas`` (N,)       measured squeeze ``n_i · F_meas`` (N)
``lambda_hat``  (N,)       force-observer estimate λ̂ (22) (N)
``lambda_d``    (N,)       desired squeeze (29) (N)
``tau``         (N, 3)     joint torques (N·m)
==============  =========  ==================================================================

CSV columns: ``t, q1..q3, q_hat1..q_hat3, q_d1..q_d3, x, y, z, x_d, y_d, z_d, Fx, Fy, Fz,
lambda_meas, lambda_hat, lambda_d, tau1..tau3`` with every float written with ``repr``
precision (the CSV round-trips bit for bit). ``run.json`` holds the metadata: status, message,
phases ``[name, t_start, t_end]``, robots, timing and the scenario as YAML.
"""

from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from drake_coop.results.io import atomic_path, atomic_write_text

#: Arrays of a robot's log and their CSV column names.
COLUMNS: dict[str, list[str]] = {
    "t": ["t"],
    "q": ["q1", "q2", "q3"],
    "q_hat": ["q_hat1", "q_hat2", "q_hat3"],
    "q_d": ["q_d1", "q_d2", "q_d3"],
    "x": ["x", "y", "z"],
    "x_d": ["x_d", "y_d", "z_d"],
    "F_meas": ["Fx", "Fy", "Fz"],
    "lambda_meas": ["lambda_meas"],
    "lambda_hat": ["lambda_hat"],
    "lambda_d": ["lambda_d"],
    "tau": ["tau1", "tau2", "tau3"],
}


def _table(log: dict[str, np.ndarray]) -> np.ndarray:
    n = log["t"].size
    return np.hstack([np.asarray(log[k], dtype=float).reshape(n, -1) for k in COLUMNS])


def save_logs(out_dir: str | Path, logs: dict[str, dict[str, np.ndarray]], meta: dict
              ) -> list[Path]:
    """Write ``<robot>.npz``, ``<robot>.csv`` and ``run.json`` to ``out_dir``, atomically.

    Returns
    -------
    list of Path
        The files written.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for robot, log in logs.items():
        missing = [k for k in COLUMNS if k not in log]
        if missing:
            raise ValueError(f"log of {robot} lacks {missing}")
        with atomic_path(out / f"{robot}.npz") as tmp:
            with open(tmp, "wb") as f:
                np.savez(f, **{k: np.asarray(log[k]) for k in COLUMNS})
        written.append(out / f"{robot}.npz")
        buffer = io.StringIO()
        buffer.write(",".join(c for k in COLUMNS for c in COLUMNS[k]) + "\n")
        for row in _table(log):
            buffer.write(",".join(repr(float(v)) for v in row) + "\n")
        written.append(atomic_write_text(out / f"{robot}.csv", buffer.getvalue()))
    written.append(atomic_write_text(out / "run.json", json.dumps(meta, indent=2)))
    return written


def load_logs(out_dir: str | Path) -> tuple[dict[str, dict[str, np.ndarray]], dict]:
    """Read the logs and metadata written by :func:`save_logs`.

    Raises
    ------
    FileNotFoundError
        If ``run.json`` or a robot's ``.npz`` is missing.
    ValueError
        If a file is malformed.
    """
    out = Path(out_dir)
    meta_path = out / "run.json"
    if not meta_path.is_file():
        raise FileNotFoundError(f"{meta_path} not found: not a drake-coop run directory")
    try:
        meta = json.loads(meta_path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{meta_path} is not valid JSON: {exc}") from None
    logs = {}
    for robot in meta.get("robots", []):
        path = out / f"{robot}.npz"
        if not path.is_file():
            raise FileNotFoundError(f"{path} not found")
        try:
            with np.load(path, allow_pickle=False) as data:
                logs[robot] = {k: data[k] for k in data.files}
        except Exception as exc:  # zipfile/format errors
            raise ValueError(f"{path} is not a valid log: {exc}") from None
        missing = [k for k in COLUMNS if k not in logs[robot]]
        if missing:
            raise ValueError(f"{path} lacks arrays {missing}")
    return logs, meta
