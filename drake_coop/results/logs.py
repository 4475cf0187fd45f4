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
``tau``         (N, 3)     applied joint torques, after the actuators' saturation (N·m)
==============  =========  ==================================================================

Optional arrays (runs since issue 7; older logs lack them and still load and plot):

=================  =========  ===============================================================
array              shape      meaning
=================  =========  ===============================================================
``qdot``           (N, 3)     true joint velocities q̇ (rad/s)
``qdot_hat``       (N, 3)     the controller's velocity estimate: d/dt q̂ (15) of the
                              observer, the true q̇ (``measured``) or the filtered difference
                              (``difference``) (rad/s)
``lambda_sensor``  (N,)       the F/T sensor model's squeeze λ_s (N)
``tau_cmd``        (N, 3)     torques commanded by the controller (13), before saturation (N·m)
=================  =========  ===============================================================

Files in the run directory:

* ``<robot>.npz`` — every array of the robot's log under its name (``np.savez``, no pickle;
  arrays beyond the schema are kept too). This is what :func:`load_logs` reads.
* ``<robot>.csv`` — the schema's arrays, one row per sample, comma separated, one header line::

      t,q1,q2,q3,q_hat1,q_hat2,q_hat3,q_d1,q_d2,q_d3,x,y,z,x_d,y_d,z_d,Fx,Fy,Fz,
      lambda_meas,lambda_hat,lambda_d,tau1,tau2,tau3

  (a single line in the file), followed by the optional arrays' columns when the log has all
  of them: ``qdot1..3,qdot_hat1..3,lambda_sensor,tau_cmd1..3``. Vector columns are numbered from 1 (joints) or named by axis
  (positions ``x, y, z``, desired ``x_d, y_d, z_d``, forces ``Fx, Fy, Fz``). Every value is
  written with ``repr(float)``, the shortest text that reads back to the same double, so
  ``np.loadtxt(path, delimiter=",", skiprows=1)`` returns the logged values bit for bit
  (``nan`` and ``inf`` included).
* ``run.json`` — the metadata: status, message, phases ``[name, t_start, t_end]``, robots,
  timing and the scenario as YAML.

Each file is written atomically (:mod:`drake_coop.results.io`).
"""

from __future__ import annotations

import io
import json
import zipfile
from pathlib import Path

import numpy as np

from drake_coop.results.io import atomic_path, atomic_write_text
from drake_coop.scenario.bounds import one_line, show

__all__ = ["COLUMNS", "OPTIONAL_COLUMNS", "csv_header", "load_logs", "save_logs", "write_meta"]

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

#: Optional arrays (sensing, issue 7) and their CSV column names; written when all present.
OPTIONAL_COLUMNS: dict[str, list[str]] = {
    "qdot": ["qdot1", "qdot2", "qdot3"],
    "qdot_hat": ["qdot_hat1", "qdot_hat2", "qdot_hat3"],
    "lambda_sensor": ["lambda_sensor"],
    "tau_cmd": ["tau_cmd1", "tau_cmd2", "tau_cmd3"],
}


def _csv_columns(log: dict[str, np.ndarray] | None) -> dict[str, list[str]]:
    """The schema's columns, plus the optional ones when ``log`` has all of them."""
    if log is not None and all(k in log for k in OPTIONAL_COLUMNS):
        return {**COLUMNS, **OPTIONAL_COLUMNS}
    return COLUMNS


def csv_header(log: dict[str, np.ndarray] | None = None) -> str:
    """The CSV header line (without newline): the column names of :data:`COLUMNS`, in order,
    then those of :data:`OPTIONAL_COLUMNS` when ``log`` has all of them."""
    return ",".join(c for names in _csv_columns(log).values() for c in names)


def _check_log(where: str, log: dict[str, np.ndarray]) -> None:
    """Raise ValueError (naming ``where``) unless ``log`` follows the schema."""
    missing = [k for k in COLUMNS if k not in log]
    if missing:
        raise ValueError(f"{where} lacks arrays {missing}")
    n = np.shape(log["t"])[0] if np.ndim(log["t"]) == 1 else None
    if n is None:
        raise ValueError(f"{where}: 't' must have shape (N,), has {np.shape(log['t'])}")
    for key, names in {**COLUMNS, **OPTIONAL_COLUMNS}.items():
        expected = (n,) if len(names) == 1 else (n, len(names))
        if key in log and np.shape(log[key]) != expected:
            raise ValueError(f"{where}: '{key}' has shape {np.shape(log[key])}, "
                             f"expected {expected}")


def _json_default(value):
    """Numpy scalars and arrays as plain JSON numbers and lists."""
    if isinstance(value, (np.generic, np.ndarray)):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def _csv_text(log: dict[str, np.ndarray]) -> str:
    n = log["t"].shape[0]
    columns = _csv_columns(log)
    table = np.hstack([np.asarray(log[k], dtype=float).reshape(n, -1) for k in columns])
    buffer = io.StringIO()
    buffer.write(csv_header(log) + "\n")
    for row in table.tolist():
        buffer.write(",".join(map(repr, row)) + "\n")
    return buffer.getvalue()


def _meta_text(meta: dict) -> str:
    return json.dumps(meta, indent=2, default=_json_default)


def write_meta(out_dir: str | Path, meta: dict) -> Path:
    """(Re)write ``run.json`` alone, atomically (e.g. to mark outputs cut short)."""
    return atomic_write_text(Path(out_dir) / "run.json", _meta_text(meta))


def save_logs(out_dir: str | Path, logs: dict[str, dict[str, np.ndarray]], meta: dict
              ) -> list[Path]:
    """Write ``<robot>.npz``, ``<robot>.csv`` and ``run.json`` to ``out_dir``, atomically.

    Parameters
    ----------
    out_dir : str or Path
        Run directory; created if needed.
    logs : dict
        ``logs[robot][array]`` in the schema of this module.
    meta : dict
        Run metadata (JSON-serialisable; numpy scalars and arrays are converted).

    Returns
    -------
    list of Path
        The files written: per robot its ``.npz`` and ``.csv``, then ``run.json``.

    Raises
    ------
    ValueError
        If a log lacks an array of the schema, an array has the wrong shape, or an array
        would need pickling (object dtype).
    """
    out = Path(out_dir)
    arrays = {robot: {k: np.asarray(v) for k, v in log.items()} for robot, log in logs.items()}
    for robot, log in arrays.items():
        _check_log(f"log of {robot}", log)
        objects = [k for k, v in log.items() if v.dtype.hasobject]
        if objects:
            raise ValueError(f"log of {robot}: arrays {objects} hold Python objects")
    meta_text = _meta_text(meta)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for robot, log in arrays.items():
        with atomic_path(out / f"{robot}.npz") as tmp:
            with open(tmp, "wb") as f:
                np.savez(f, **log)
        written.append(out / f"{robot}.npz")
        written.append(atomic_write_text(out / f"{robot}.csv", _csv_text(log)))
    written.append(atomic_write_text(out / "run.json", meta_text))
    return written


#: Bounds of what :func:`load_logs` reads: ``run.json`` (bytes), robots, arrays per ``.npz``
#: and their uncompressed size (the longest run, 200 000 ticks, needs ~45 MB per robot).
MAX_META_BYTES = 16_000_000
MAX_ROBOTS = 8
MAX_MEMBERS = 64
MAX_NPZ_BYTES = 128_000_000


def _inside(out: Path, name: str, what: str) -> Path:
    """``out / name`` if it is a regular file directly inside ``out`` (no symlink out)."""
    path = out / name
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found" + (
            ": not a drake-coop run directory" if name == "run.json" else ""))
    if path.is_symlink() or path.resolve().parent != out.resolve():
        raise ValueError(f"{path}: {what} must be a regular file inside the run folder")
    return path


def _load_meta(out: Path) -> dict:
    path = _inside(out, "run.json", "run.json")
    if path.stat().st_size > MAX_META_BYTES:
        raise ValueError(f"{path} is larger than {MAX_META_BYTES} bytes")
    try:
        meta = json.loads(path.read_bytes().decode("utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path} is not valid JSON: {one_line(exc, 120)}") from None
    except RecursionError:
        raise ValueError(f"{path} is nested too deeply to be a run's metadata") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{path} must hold a JSON object, holds {type(meta).__name__}")
    robots = meta.get("robots")
    if not (isinstance(robots, list) and 0 < len(robots) <= MAX_ROBOTS
            and all(isinstance(r, str) and r.isidentifier() and len(r) <= 40 for r in robots)
            and len(set(robots)) == len(robots)):
        raise ValueError(f"{path}: 'robots' must be a list of 1 to {MAX_ROBOTS} distinct "
                         f"identifiers (robot names), is {show(robots)}")
    return meta


def _check_npz_sizes(path: Path) -> None:
    """Refuse an archive whose members would unpack beyond :data:`MAX_NPZ_BYTES` (declared
    sizes from the zip directory, read before anything is unpacked)."""
    try:
        with zipfile.ZipFile(path) as archive:
            infos = archive.infolist()
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise ValueError(f"{path} is not a valid log: {one_line(exc, 120)}") from None
    if len(infos) > MAX_MEMBERS:
        raise ValueError(f"{path} holds {len(infos)} arrays, at most {MAX_MEMBERS}")
    total = sum(i.file_size for i in infos)
    if total > MAX_NPZ_BYTES:
        raise ValueError(f"{path} would unpack to {total / 1e6:.0f} MB, at most "
                         f"{MAX_NPZ_BYTES / 1e6:.0f} MB")


def _check_phases(path: Path, meta: dict) -> None:
    phases = meta.get("phases")
    if not (isinstance(phases, list) and all(
            isinstance(p, list) and len(p) == 3 and isinstance(p[0], str)
            and all(isinstance(v, (int, float)) for v in p[1:]) for p in phases)):
        raise ValueError(f"{path}: 'phases' must be a list of [name, t_start, t_end], "
                         f"is {show(phases)}")


def load_logs(out_dir: str | Path) -> tuple[dict[str, dict[str, np.ndarray]], dict]:
    """Read the logs and metadata written by :func:`save_logs` (from the ``.npz`` files).

    Parameters
    ----------
    out_dir : str or Path
        Run directory.

    Returns
    -------
    logs : dict
        ``logs[robot][array]``, every array stored in the robot's ``.npz``.
    meta : dict
        The content of ``run.json``.

    Raises
    ------
    FileNotFoundError
        If ``run.json`` or a robot's ``.npz`` is missing (the file is named).
    ValueError
        If a file is malformed (the file is named): robot names that are not identifiers
        (only files directly inside ``out_dir`` are read, no symlinks), a ``run.json`` too
        large or too deeply nested, an ``.npz`` that would unpack beyond
        :data:`MAX_NPZ_BYTES`, arrays of the wrong shape.
    """
    out = Path(out_dir)
    meta = _load_meta(out)
    logs = {}
    for robot in meta["robots"]:
        path = _inside(out, f"{robot}.npz", f"{robot}.npz")
        _check_npz_sizes(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                logs[robot] = {k: data[k] for k in data.files}
        except Exception as exc:  # zipfile, format and pickle errors
            raise ValueError(f"{path} is not a valid log: {one_line(exc, 120)}") from None
        _check_log(str(path), logs[robot])
    _check_phases(out / "run.json", meta)
    return logs, meta
