"""Results store of a study directory, and the summary columns of ``results.csv``.

Layout of ``DIR``::

    cases/<hash>.json   one file per finished case, written atomically when it finishes
    results.csv         one row per case: index, hash, swept parameters, status, summary metrics
    study.json          the study (grid, Monte Carlo, metrics, guides), engine, counts, cases

    cases/<hash>.died   a case whose process died (killed, out of memory): not a result

A case file holds the full metrics (every robot, phase and error of ``metrics.json``), the
scenario YAML, status (``ok``, ``diverged`` or ``error``: what the case's run said) and
message, and ``code``: the stamp of the code that computed it
(:mod:`drake_coop.studies.code_stamp`). Resuming skips every case whose hash has a valid file
of the running code's stamp (one of other code is refused, run again or kept, as the command
is told: :func:`~drake_coop.studies.code_stamp.reusable_records`); a case that was interrupted,
or whose process died, is never written as a result (a ``.died`` note says so, and the case is
run again on the next resume). A case file that cannot be read or misses a field is skipped
with a warning (:attr:`ResultStore.skipped`) and its case runs again. Its metrics must have
the shapes :mod:`drake_coop.results.metrics` writes: ``{"rms", "max"}`` numbers for an error,
plain numbers for the sample counts, and for the held object's counts and times those that
:data:`~drake_coop.results.object_metrics.EVENT_METRICS` declares (``{"count": k}``, an
integer >= 0; ``{"time": s}``, a number or null). ``results.csv`` and
``study.json`` are rewritten (atomically) after every finished case; their parameter columns
are :attr:`~drake_coop.studies.expand.Case.values`, read from each case's resolved scenario.

Summary columns (of the study's ``phase``): ``<robot>.<error>.<rms|max>`` for the errors of
:mod:`drake_coop.results.metrics`, plus ``position_error`` (RMS of ``|x − x_d|``, i.e.
``sqrt(rms_x² + rms_y² + rms_z²)``; max = the largest single-axis max) and ``observation_error``
(the same over the joints' ``z1 … zn``), ``velocity_error`` when the run logs it (the sensing alternatives),
the held object's errors in ``contact`` mode (``friction_use``, ``object_position_error``,
``object_angle_error``, ``object_turn``, ``object_tilt``, ``slip``, ``mass_estimate_error``) and
its counts and times
(``slips.count``, ``drops.count``, ``mass_convergence_time.time``), and
``worst.<error>.<stat>``, the largest over the robots.
"""

from __future__ import annotations

import csv
import errno
import io
import json
import math
from dataclasses import asdict
from pathlib import Path

from drake_coop.results.io import atomic_write_text
from drake_coop.results.object_metrics import EVENT_METRICS
from drake_coop.studies.code_stamp import code_stamp, count_stale
from drake_coop.studies.expand import Case
from drake_coop.studies.spec import Study

__all__ = ["ERRORS", "FINISHED", "ResultStore", "check_metric_names", "summary_columns"]

#: Statuses of a finished case (a result); any other (``interrupted``, ``died``) is not stored.
FINISHED = ("ok", "diverged", "failed", "error")
#: Largest case file read (bytes): a case's metrics are a few kB, its scenario ~3 kB.
MAX_CASE_BYTES = 4_000_000

#: Observation errors ``q − q̂`` of joints 1 … 12 (an arm has at most 12 joints).
JOINT_ERRORS = tuple(f"z{k}" for k in range(1, 13))
ERRORS = ("x_tilde", "y_tilde", "z_tilde", "position_error", "force_error", "estimate_error",
          "aux_force_error", *JOINT_ERRORS, "observation_error", "velocity_error",
          "friction_use", "object_position_error", "object_angle_error", "object_turn",
          "object_tilt", "slip",
          "mass_estimate_error")
#: The held object's counts and times (``contact`` mode,
#: :data:`drake_coop.results.object_metrics.EVENT_METRICS`): ``<robot>.<name>.<stat>``.
EVENTS = {name: key for name, (key, _) in EVENT_METRICS.items()}
_GROUPS = {"position_error": ("x_tilde", "y_tilde", "z_tilde"),
           "observation_error": JOINT_ERRORS}
STATS = ("rms", "max")


def _robot_summary(phase_metrics: dict) -> dict[str, float]:
    out: dict[str, float] = {}
    for error in ERRORS:
        if error in _GROUPS:
            parts = [phase_metrics.get(e) for e in _GROUPS[error]]
            if error == "observation_error":        # the joints the arm has
                parts = [p for p in parts if p is not None] or [None]
            if all(parts):
                out[f"{error}.rms"] = math.sqrt(sum(p["rms"] ** 2 for p in parts))
                out[f"{error}.max"] = max(p["max"] for p in parts)
        elif error in phase_metrics:
            out[f"{error}.rms"] = phase_metrics[error]["rms"]
            out[f"{error}.max"] = phase_metrics[error]["max"]
    for name, stat in EVENTS.items():
        if name in phase_metrics and phase_metrics[name][stat] is not None:
            out[f"{name}.{stat}"] = float(phase_metrics[name][stat])
    return out


def summary_columns(metrics: dict, phase: str) -> dict[str, float]:
    """The summary metrics of one case for ``phase`` (missing when the run never reached it).

    Parameters
    ----------
    metrics : dict
        ``metrics[robot][phase]``.
    phase : str
        The phase.
    """
    out: dict[str, float] = {}
    worst: dict[str, float] = {}
    for robot, phases in metrics.items():
        if phase not in phases:
            continue
        for name, value in _robot_summary(phases[phase]).items():
            out[f"{robot}.{name}"] = value
            worst[name] = max(worst.get(name, value), value)
    out.update({f"worst.{k}": v for k, v in worst.items()})
    return out


def metric_names(robots: list[str]) -> list[str]:
    """Every summary column name for the given robot names.

    Parameters
    ----------
    robots : list of str
        The robots' names.
    """
    return [f"{r}.{e}.{s}" for r in [*robots, "worst"] for e in ERRORS for s in STATS] + [
        f"{r}.{e}.{s}" for r in [*robots, "worst"] for e, s in EVENTS.items()]


def check_metric_names(names: list[str], robots: list[str]) -> str | None:
    """The first unknown metric name as an error message, or None.

    Parameters
    ----------
    names : list of str
        The names.
    robots : list of str
        The robots' names.

    Returns
    -------
    str or None
        The message, or None.
    """
    known = metric_names(robots)
    for name in names:
        if name not in known:
            return (f"metrics: unknown column {name!r}; use <robot|worst>.<error>.<rms|max> "
                    f"with robot in {', '.join(robots)} and error in {', '.join(ERRORS)}")
    return None


class ResultStore:
    """The case files of a study directory (see the module docstring).

    Parameters
    ----------
    out : str or Path
        The study's folder.
    stamp : str or None
        The stamp every saved record carries (``code``); None: the running code's
        (:func:`~drake_coop.studies.code_stamp.code_stamp`, computed when first needed).
    """

    def __init__(self, out: str | Path, stamp: str | None = None):
        self.out = Path(out)
        self.cases_dir = self.out / "cases"
        self._stamp = stamp

    @property
    def stamp(self) -> str:
        """The code stamp of the records this store saves.

        Returns
        -------
        str
            The stamp.
        """
        if self._stamp is None:
            self._stamp = code_stamp()
        return self._stamp

    def load(self) -> dict[str, dict]:
        """The finished case records by hash.

        A file that cannot be read, is not UTF-8 JSON, or misses a field of a record is
        skipped (its case runs again); :attr:`skipped` lists them as one-line warnings.

        Raises
        ------
        IsADirectoryError
            A case's file is a folder: its result could not be saved there, so the study is
            refused before running it (not recomputed and then lost).
        """
        records: dict[str, dict] = {}
        self.skipped: list[str] = []
        if not self.cases_dir.is_dir():
            return records
        for path in sorted(self.cases_dir.glob("*.json")):
            if path.is_dir() and not path.is_symlink():
                raise IsADirectoryError(errno.EISDIR, f"cases/{path.name} is a folder where "
                                        "a case's result file goes; remove it")
            problem = None
            try:
                if path.is_symlink() or not path.is_file():
                    problem = "not a regular file"
                elif path.stat().st_size > MAX_CASE_BYTES:
                    problem = f"larger than {MAX_CASE_BYTES} bytes"
                else:
                    record = json.loads(path.read_bytes().decode("utf-8"))
                    problem = _record_problem(record, path.stem)
            except (OSError, ValueError, RecursionError) as exc:
                problem = " ".join(str(getattr(exc, "strerror", None) or exc).split())[:120]
            if problem:
                self.skipped.append(f"{path.name}: {problem}; its case runs again")
            else:
                records[path.stem] = record
        return records

    def died(self) -> dict[str, str]:
        """The cases whose process died in an earlier run: hash -> message.
        """
        notes = {}
        if self.cases_dir.is_dir():
            for path in sorted(self.cases_dir.glob("*.died")):
                try:
                    notes[path.stem] = " ".join(path.read_bytes()[:400].decode(
                        "utf-8", "replace").split())
                except OSError:
                    notes[path.stem] = "its process died"
        return notes

    def save(self, case: Case, result: dict, t_end: float | None) -> dict:
        """Write one finished case's record atomically and return it (and drop its
        ``.died`` note, if any).

        Parameters
        ----------
        case : Case
            The case.
        result : dict
            Its result (a finished status).
        t_end : float or None
            The study's ``t_end``, s.

        Returns
        -------
        dict
            The record.
        """
        if result["status"] not in FINISHED:
            raise ValueError(f"case {case.index}: status {result['status']!r} is not a result")
        record = {"hash": case.hash, "index": case.index, "params": case.params,
                  "values": case.values, "t_end": t_end, **result, "code": self.stamp,
                  "scenario_yaml": case.scenario_yaml}
        text = json.dumps(record, indent=1, allow_nan=False)
        atomic_write_text(self.cases_dir / f"{case.hash}.json", text + "\n")
        (self.cases_dir / f"{case.hash}.died").unlink(missing_ok=True)
        return record

    def mark_died(self, case: Case, message: str) -> None:
        """Note that ``case``'s process died (not a result: the case runs again).

        Parameters
        ----------
        case : Case
            The case.
        message : str
            Why it died.
        """
        atomic_write_text(self.cases_dir / f"{case.hash}.died", message + "\n")

    def write_tables(self, study: Study, cases: list[Case], records: dict[str, dict],
                     engine: str, died: dict[str, str] | None = None) -> None:
        """Rewrite ``results.csv`` and ``study.json`` (atomically) from the records so far
        (a case without a record is ``pending``, or ``died`` when ``died`` names it);
        ``study.json`` holds the running code's stamp (``code``) and how many of its cases'
        records other code wrote (``stale_kept``: kept by a resume with ``--stale keep``).

        Parameters
        ----------
        study : Study
            The study.
        cases : list of Case
            Its cases.
        records : dict of str to dict
            Hash → record.
        engine : str
            ``local`` or ``ray``.
        died : dict of str to str or None
            Hash → message of the died cases.
        """
        died = died or {}
        param_keys: list[str] = []
        for case in cases:
            param_keys += [k for k in case.values if k not in param_keys]
        rows, metric_keys = [], []
        for case in cases:
            record = records.get(case.hash)
            summary = summary_columns(record["metrics"], study.phase) if record else {}
            metric_keys += [k for k in summary if k not in metric_keys]
            rows.append((case, record, summary))
        head = ["index", "hash", *param_keys, "status", "t_reached", "wall_time_s"]
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow([*head, *metric_keys, "message"])
        for case, record, summary in rows:
            record = record or _missing(case, died)
            writer.writerow([case.index, case.hash, *[_cell(case.values.get(k))
                                                      for k in param_keys],
                             record["status"], _cell(record.get("t_reached")),
                             _cell(record.get("wall_time_s")),
                             *[_cell(summary.get(k)) for k in metric_keys],
                             record["message"]])
        atomic_write_text(self.out / "results.csv", buffer.getvalue())
        counts: dict[str, int] = {}
        for case, record, _ in rows:
            status = (record or _missing(case, died))["status"]
            counts[status] = counts.get(status, 0) + 1
        doc = {
            "name": study.name, "description": study.description, "t_end": study.t_end,
            "phase": study.phase, "grid": study.grid,
            "monte_carlo": asdict(study.monte_carlo) if study.monte_carlo else None,
            "metrics": study.metrics, "guides": [asdict(g) for g in study.guides],
            "engine": engine, "n_cases": len(cases), "counts": counts, "code": self.stamp,
            "stale_kept": count_stale(records, (c.hash for c in cases), self.stamp),
            "cases": [{"index": c.index, "hash": c.hash, "params": c.params,
                       "values": c.values, "status": (r or _missing(c, died))["status"],
                       "message": (r or _missing(c, died))["message"], "summary": s}
                      for c, r, s in rows],
        }
        atomic_write_text(self.out / "study.json",
                          json.dumps(doc, indent=1, allow_nan=False) + "\n")


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, list):
        return " ".join(_cell(v) for v in value)
    if isinstance(value, dict):
        return " ".join(f"{k}={_cell(v)}" for k, v in value.items())
    return str(value)


def _missing(case: Case, died: dict[str, str]) -> dict:
    if case.hash in died:
        return {"status": "died", "message": died[case.hash]}
    return {"status": "pending", "message": ""}


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _entry_problem(name: str, entry) -> str | None:
    """What makes one entry of a phase's metrics unusable, or None: the shapes
    :mod:`drake_coop.results.metrics` writes (``{"rms", "max"}``, and the sample counts
    ``n_samples`` / ``n_nonfinite`` as plain integers) and those of
    :data:`~drake_coop.results.object_metrics.EVENT_METRICS` (a count, a time or null)."""
    if not isinstance(entry, dict):
        return None if _is_number(entry) else "must be a number or a mapping"
    if name in EVENT_METRICS:
        key, nullable = EVENT_METRICS[name]
        value = entry.get(key)
        if value is None and nullable:
            return None
        if key == "count":
            ok = isinstance(value, int) and not isinstance(value, bool) and value >= 0
            return None if ok else f"needs {key!r}, an integer >= 0"
        if _is_number(value) and math.isfinite(value):
            return None
        return f"needs {key!r}, a number" + (" or null" if nullable else "")
    if all(_is_number(entry.get(s)) and math.isfinite(entry[s]) for s in STATS):
        return None
    return f"needs {' and '.join(repr(s) for s in STATS)}, numbers"


def _record_problem(record, stem: str) -> str | None:
    """What makes a loaded case file unusable, or None."""
    if not isinstance(record, dict):
        return "not a JSON object"
    if record.get("hash") != stem:
        return "its hash is not its file name"
    if record.get("status") not in FINISHED:
        return f"status must be one of {', '.join(FINISHED)}"
    for key, ok in (("message", lambda v: isinstance(v, str)),
                    ("t_reached", _is_number), ("wall_time_s", _is_number),
                    ("metrics", lambda v: isinstance(v, dict)),
                    ("params", lambda v: isinstance(v, dict))):
        if key not in record or not ok(record[key]):
            return f"field {key!r} is missing or of the wrong type"
    for robot, phases in record["metrics"].items():
        where = f"metrics of {str(robot)[:40]!r}"
        if not isinstance(phases, dict):
            return f"{where} are malformed"
        for phase, entries in phases.items():
            if not isinstance(entries, dict):
                return f"{where} are malformed (phase {str(phase)[:40]!r})"
            for name, entry in entries.items():
                problem = _entry_problem(str(name), entry)
                if problem:
                    return f"{where} are malformed ({str(phase)[:40]}.{str(name)[:40]}: " \
                           f"{problem})"
    return None
