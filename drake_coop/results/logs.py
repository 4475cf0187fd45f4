"""Run logs on disk: one ``.npz`` and one ``.csv`` per robot, plus ``run.json``.

Per robot, one row per control sample (period h); ``n`` is the robot's number of joints (read
from ``q``), ``m`` its number of constraints (read from ``lambda_d``: an array of shape (N,)
is one constraint, the paper's case, and (N, m) with m >= 2 several):

===============  ================  ===========================================================
array            shape             meaning
===============  ================  ===========================================================
``t``            (N,)              time of the sample (s)
``q``            (N, n)            measured joint positions (rad)
``q_hat``        (N, n)            velocity-observer estimate q̂ (15) (rad)
``q_d``          (N, n)            desired joint positions (rad)
``x``            (N, 3)            end-effector position, palm frame (m)
``x_d``          (N, 3)            desired end-effector position (28) (m)
``F_meas``       (N, 3)            measured force of the object on the end effector, palm
                                   frame (N)
``lambda_meas``  (N,) or (N, m)    measured squeeze ``N_i F_meas`` (N)
``lambda_hat``   (N,) or (N, m)    force-observer estimate λ̂ (22) (N)
``lambda_d``     (N,) or (N, m)    desired squeeze (29) (N)
``tau``          (N, n)            applied joint torques, after the actuators' saturation (N·m)
===============  ================  ===========================================================

Optional arrays (newer runs; older logs lack them and still load and plot):

=================  ==============  ============================================================
array              shape           meaning
=================  ==============  ============================================================
``qdot``           (N, n)          true joint velocities q̇ (rad/s)
``qdot_hat``       (N, n)          the controller's velocity estimate: d/dt q̂ (15) of the
                                   observer, the true q̇ (``measured``) or the filtered
                                   difference (``difference``) (rad/s)
``lambda_sensor``  (N,) or (N, m)  the F/T sensor model's squeeze λ_s (N)
``tau_cmd``        (N, n)          torques commanded by the controller (13), before
                                   saturation (N·m)
``tau_ff``         (N, n)          the load feedforward ``J_xᵀ f_i`` added to (13)
                                   (``object_model`` known or estimated; ``.npz`` only) (N·m)
``f_load``         (N, 3)          the arm's load ``f_i = m_i (a_d − g)`` it feeds forward (N)
``mass_share``     (N,)            the arm's share ``m_i`` of the object's mass, the estimate
                                   with ``estimated`` (kg)
=================  ==============  ============================================================

Files in the run directory:

* ``<robot>.npz`` — every array of the robot's log under its name (``np.savez``, no pickle;
  arrays beyond the schema are kept too). This is what :func:`load_logs` reads.
* ``<robot>.csv`` — the schema's arrays, one row per sample, comma separated, one header line;
  for the paper's arms (n = 3, m = 1)::

      t,q1,q2,q3,q_hat1,q_hat2,q_hat3,q_d1,q_d2,q_d3,x,y,z,x_d,y_d,z_d,Fx,Fy,Fz,
      lambda_meas,lambda_hat,lambda_d,tau1,tau2,tau3

  (a single line in the file), followed by the optional arrays' columns when the log has all
  of them: ``qdot1..3,qdot_hat1..3,lambda_sensor,tau_cmd1..3``. Joint columns are numbered
  from 1 to n (``q1..qn``, ``tau1..taun``); force columns keep their name for one constraint
  (``lambda_meas``) and are numbered from 1 to m for several (``lambda_meas1..m``); Cartesian
  columns are named by axis (positions ``x, y, z``, desired ``x_d, y_d, z_d``, forces
  ``Fx, Fy, Fz``). :func:`log_columns` gives a log's columns. Every value is written with
  ``repr(float)``, the shortest text that reads back to the same double, so
  ``np.loadtxt(path, delimiter=",", skiprows=1)`` returns the logged values bit for bit
  (``nan`` and ``inf`` included).
* ``run.json`` — the metadata: status, message, phases ``[name, t_start, t_end]``, robots,
  timing and the scenario as YAML.

Each file is written atomically (:mod:`drake_coop.results.io`).
"""

from __future__ import annotations

import io
import json
import math
import zipfile
from pathlib import Path

import numpy as np

from drake_coop.results.io import atomic_path, atomic_write_text
from drake_coop.scenario.bounds import one_line, show

__all__ = ["COLUMNS", "OPTIONAL_COLUMNS", "csv_header", "load_logs", "log_columns",
           "log_sizes", "save_logs", "schema", "write_meta"]

#: Kind of each array of the schema: ``t`` (the time), ``joint`` (one column per joint),
#: ``cartesian`` (columns named below), ``force`` (one per constraint); optional ones last.
KINDS: dict[str, str] = {
    "t": "t", "q": "joint", "q_hat": "joint", "q_d": "joint", "x": "cartesian",
    "x_d": "cartesian", "F_meas": "cartesian", "lambda_meas": "force", "lambda_hat": "force",
    "lambda_d": "force", "tau": "joint",
}
OPTIONAL_KINDS: dict[str, str] = {
    "qdot": "joint", "qdot_hat": "joint", "lambda_sensor": "force", "tau_cmd": "joint",
}
#: Column names of the Cartesian arrays (by axis).
CARTESIAN_NAMES: dict[str, list[str]] = {
    "x": ["x", "y", "z"], "x_d": ["x_d", "y_d", "z_d"], "F_meas": ["Fx", "Fy", "Fz"],
}


def schema(n: int = 3, m: int = 1, optional: bool = False) -> dict[str, list[str]]:
    """Arrays of a robot's log with ``n`` joints and ``m`` constraints, and their CSV columns.

    Parameters
    ----------
    n : int
        Joints: ``q`` becomes ``q1..qn``.
    m : int
        Constraints: ``lambda_d`` stays one column for ``m = 1`` (the paper) and becomes
        ``lambda_d1..m`` for ``m >= 2``.
    optional : bool
        Return the optional arrays (:data:`OPTIONAL_COLUMNS` for n = 3, m = 1) instead.

    Returns
    -------
    dict
        ``array name -> column names``, in the CSV's order.
    """
    columns = {}
    for key, kind in (OPTIONAL_KINDS if optional else KINDS).items():
        if kind == "joint":
            columns[key] = [f"{key}{j}" for j in range(1, n + 1)]
        elif kind == "force":
            columns[key] = [key] if m == 1 else [f"{key}{k}" for k in range(1, m + 1)]
        elif kind == "cartesian":
            columns[key] = list(CARTESIAN_NAMES[key])
        else:
            columns[key] = [key]
    return columns


#: Arrays of the paper's robots' logs (n = 3 joints, m = 1 constraint) and their CSV columns.
COLUMNS: dict[str, list[str]] = schema(3, 1)

#: Optional arrays (sensing) of the paper's robots and their CSV columns; written when
#: all present.
OPTIONAL_COLUMNS: dict[str, list[str]] = schema(3, 1, optional=True)


def log_sizes(log: dict[str, np.ndarray]) -> tuple[int, int]:
    """``(n, m)`` of a log: joints from ``q`` (N, n), constraints from ``lambda_d``
    ((N,): 1, (N, m): m). Shapes are checked by :func:`_check_log`.

    Parameters
    ----------
    log : dict of str to numpy.ndarray
        One robot's log.
    """
    n = np.shape(log["q"])[1] if np.ndim(log["q"]) == 2 else 0
    m = 1 if np.ndim(log["lambda_d"]) == 1 else int(np.shape(log["lambda_d"])[-1])
    return n, m


def log_columns(log: dict[str, np.ndarray]) -> dict[str, list[str]]:
    """The CSV columns of ``log``: its schema's, plus the optional ones when it has all of
    them.

    Parameters
    ----------
    log : dict of str to numpy.ndarray
        One robot's log.

    Returns
    -------
    dict of str to list of str
        Array name → its CSV columns.
    """
    n, m = log_sizes(log)
    columns = schema(n, m)
    optional = schema(n, m, optional=True)
    if all(k in log for k in optional):
        columns.update(optional)
    return columns


def csv_header(log: dict[str, np.ndarray] | None = None) -> str:
    """The CSV header line (without newline): the columns of :func:`log_columns` of ``log``,
    or those of :data:`COLUMNS` (the paper's robots, no optional arrays) without a log.

    Parameters
    ----------
    log : dict of str to numpy.ndarray or None
        One robot's log; None for the paper's robots.
    """
    columns = COLUMNS if log is None else log_columns(log)
    return ",".join(c for names in columns.values() for c in names)


def _check_log(where: str, log: dict[str, np.ndarray]) -> None:
    """Raise ValueError (naming ``where``) unless ``log`` follows the schema: ``t`` (N,),
    ``q`` (N, n) with n >= 1, ``lambda_d`` (N,) or (N, m) with m >= 2, and every other array
    of the schema (optional ones when present) consistent with N, n and m."""
    missing = [k for k in KINDS if k not in log]
    if missing:
        raise ValueError(f"{where} lacks arrays {missing}")
    if np.ndim(log["t"]) != 1:
        raise ValueError(f"{where}: 't' must have shape (N,), has {np.shape(log['t'])}")
    N = np.shape(log["t"])[0]
    q_shape, lam_shape = np.shape(log["q"]), np.shape(log["lambda_d"])
    if len(q_shape) != 2 or q_shape[0] != N or q_shape[1] < 1:
        raise ValueError(f"{where}: 'q' has shape {q_shape}, expected (N, n) = ({N}, n) with "
                         "n >= 1 joints")
    if not (lam_shape == (N,) or (len(lam_shape) == 2 and lam_shape[0] == N
                                  and lam_shape[1] >= 2)):
        raise ValueError(f"{where}: 'lambda_d' has shape {lam_shape}, expected ({N},) for one "
                         f"constraint or ({N}, m) with m >= 2")
    n, m = log_sizes(log)
    for key, names in {**schema(n, m), **schema(n, m, optional=True)}.items():
        kind = {**KINDS, **OPTIONAL_KINDS}[key]
        expected = (N,) if kind == "t" or (kind == "force" and m == 1) else (N, len(names))
        if key in log and np.shape(log[key]) != expected:
            raise ValueError(f"{where}: '{key}' has shape {np.shape(log[key])}, "
                             f"expected {expected} (n = {n} joints, m = {m} constraints)")


def _json_default(value):
    """Numpy scalars and arrays as plain JSON numbers and lists."""
    if isinstance(value, (np.generic, np.ndarray)):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def _csv_text(log: dict[str, np.ndarray]) -> str:
    n = log["t"].shape[0]
    columns = log_columns(log)
    table = np.hstack([np.asarray(log[k], dtype=float).reshape(n, -1) for k in columns])
    buffer = io.StringIO()
    buffer.write(csv_header(log) + "\n")
    for row in table.tolist():
        buffer.write(",".join(map(repr, row)) + "\n")
    return buffer.getvalue()


def _rounded(value):
    """Floats (also inside lists and mappings) to 12 significant digits: ``run.json`` says
    ``0.009``, not the ``0.009000000000000008`` of a period aligned in floating point."""
    if isinstance(value, (np.generic, np.ndarray)):
        value = value.tolist()
    if isinstance(value, float):
        return float(f"{value:.12g}") if math.isfinite(value) else value
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_rounded(v) for v in value]
    return value


def _meta_text(meta: dict) -> str:
    return json.dumps(_rounded(meta), indent=2, default=_json_default)


def write_meta(out_dir: str | Path, meta: dict) -> Path:
    """(Re)write ``run.json`` alone, atomically (e.g. to mark outputs cut short).

    Parameters
    ----------
    out_dir : str or Path
        The run's folder.
    meta : dict
        The run's metadata.

    Returns
    -------
    Path
        The file written.
    """
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
#: and their uncompressed size (the longest run, 200 000 ticks, needs ~45 MB for a 3-joint
#: robot and ~102 MB for one with n = 6 joints and m = 3 constraints: 64 columns).
MAX_META_BYTES = 16_000_000
MAX_ROBOTS = 8
MAX_MEMBERS = 64
MAX_NPZ_BYTES = 128_000_000
#: Phases a ``run.json`` may list (a run has five; each phase costs the figures and metrics a
#: pass over the logs, so a damaged file with 400 000 of them is refused before any is read).
MAX_PHASES = 32


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
    if isinstance(phases, list) and len(phases) > MAX_PHASES:
        raise ValueError(f"{path}: 'phases' lists {len(phases)} phases, at most {MAX_PHASES}")
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
    _check_phases(out / "run.json", meta)        # before the logs are read: bounded work
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
